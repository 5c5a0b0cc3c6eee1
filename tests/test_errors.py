"""One keyed error class (issue 31 item 6): every error about what a user gives is a UserError
with a ``key`` and a one-line ``problem``, re-keyed by ``within``; the CLI catches that one class."""

from __future__ import annotations

import pickle

import pytest

from bayesfric import cli
from bayesfric.datasets import DataError
from bayesfric.errors import UserError
from bayesfric.fsutil import PathError
from bayesfric.laws.errors import LawDeclarationError, VariantError
from bayesfric.laws.plugins import LawModuleError
from bayesfric.priors import PriorError
from bayesfric.quantities import UnitError
from bayesfric.sizing.points import SizingError
from bayesfric.study.claimspec import ClaimError
from bayesfric.study.schema import SchemaError
from bayesfric.study.spec import StudyError

ERRORS = {
    DataError: DataError("bench.csv: row 3: not a number"),
    PriorError: PriorError("must be > 0", "scale"),
    UnitError: UnitError("cannot parse 'Nmm'"),
    SchemaError: SchemaError(("sampler", "draws"), "must be ≥ 1"),
    ClaimError: ClaimError("law", "unknown law 'x'"),
    SizingError: SizingError("at", "no operating point"),
    VariantError: VariantError("must be a finite number", "fixed.i"),
    LawDeclarationError: LawDeclarationError("law 'x': no docstring"),
    StudyError: StudyError("s.toml: [sampler] draws: must be ≥ 1"),
    PathError: PathError("out: not a folder"),
    LawModuleError: LawModuleError("my_laws.py: does not import"),
    cli.UsageError: cli.UsageError("bayesfric: error: unknown option"),
}


@pytest.mark.parametrize("cls", list(ERRORS), ids=lambda c: c.__name__)
def test_every_input_error_is_one_keyed_class(cls):
    err = ERRORS[cls]
    assert isinstance(err, UserError) and isinstance(err, ValueError)
    assert str(err) == (f"{err.key}: {err.problem}" if err.key else err.problem)
    assert "\n" not in str(err)
    moved = err.within("laws[0]")
    assert type(moved) is cls and moved.problem == err.problem
    assert moved.key == (f"laws[0].{err.key}" if err.key else "laws[0]") and str(moved).startswith("laws[0]")
    assert str(err).startswith(err.key)  # the original is unchanged
    back = pickle.loads(pickle.dumps(err))  # a Dask worker's error reaches the client
    assert type(back) is cls and str(back) == str(err) and back.key == err.key
    assert cli.USER_ERRORS == (UserError,)


def test_keys_and_problems_by_hand():
    assert str(PriorError("must be > 0", "scale").within("priors.T_C")) == "priors.T_C.scale: must be > 0"
    assert str(SchemaError(("sampler", "draws"), "must be ≥ 1")) == "[sampler] draws: must be ≥ 1"
    assert str(SizingError("", "a trajectory law")) == "a trajectory law"
    assert str(UserError("x", "a").within("[study]", sep=" ")) == "[study] a: x"
    assert isinstance(LawDeclarationError("x"), TypeError)  # what declaration errors were before
    assert SchemaError(("sampler", "draws"), "x").within("s.toml", sep=": ").where == ("sampler", "draws")
