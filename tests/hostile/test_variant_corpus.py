"""Bad-input cases of law variants (issue 13): study ``[[laws]]`` options and ``fit --fix``.

Same contract as :mod:`tests.hostile.test_study_corpus` (whose base study, case tree and TOML
writer are reused): exit status 2, one line naming the file (or option) and the key, nothing
written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.hostile.harness import assert_user_error
from tests.hostile.test_study_corpus import FIT, C, Case, S, study_toml, tree  # noqa: F401  (fixture)

DAHL = ("fit", "dahl_duplex", "dahl", "--quiet")
CASES = [
    S("fixed-unknown", {"laws.0.fixed": {"nope": 1.0}}, "laws[0].fixed.nope", "no parameter or constant 'nope'"),
    S("fixed-string", {"laws.0.fixed": {"T_C": "big"}}, "laws[0].fixed.T_C", "number"),
    S("fixed-outside-support", {"laws.0.fixed": {"T_C": -1.0}}, "laws[0].fixed.T_C", "outside the support"),
    S("fixed-then-prior", {"laws.0.fixed": {"c_v": 0.1}, "laws.0.priors": {"c_v": {"dist": "HalfNormal",
                                                                                   "scale": 1.0}}},
      "laws[0].priors.c_v", "no parameter 'c_v'"),
    S("asymmetric-unknown", {"laws.0.asymmetric": ["T_s"]}, "laws[0].asymmetric", "no parameter 'T_s'"),
    S("asymmetric-number", {"laws.0.asymmetric": [1]}, "laws[0].asymmetric", "names"),
    S("asymmetric-trajectory", {"laws.0.name": "lugre", "laws.0.asymmetric": ["F_c"]}, "laws[0].asymmetric",
      "steady law"),
    S("add-unknown", {"laws.0.add": ["nope"]}, "laws[0].add", "'nope'"),
    S("add-other-response", {"laws.0.add": ["coastdown_stribeck"]}, "laws[0].add", "velocity"),
    S("offset-string", {"laws.0.offset": "yes"}, "laws[0].offset", "true or false"),
    S("label-not-plain", {"laws.0.label": "a/b"}, "laws[0].label"),
    S("same-label-twice", {"laws": [{"name": "coulomb", "label": "a"}, {"name": "coulomb_viscous", "label": "a"}]},
      "laws[1].label", "twice"),
    S("rotary-only-on-force", {"data.dataset": "{root}/tribo.csv", "laws.0.name": "thermal_mass2_viscous",
                               "compare.blocked.0.axis": "linear_velocity", "compare.blocked.0.threshold": 0.0},
      "laws[0] (thermal_mass2_viscous)", "rotary (torque) data only"),
    S("missing-input-data-terms", {"data.dataset": "{root}/tribo.csv", "laws.0.name": "lugre",
                                   "compare.blocked.0.axis": "linear_velocity", "compare.blocked.0.threshold": 0.0},
      "laws[0] (lugre)", "time (time since the start"),
    S("missing-velocity-data-terms", {"data.dataset": "{root}/tribo_x.csv", "laws.0.name": "coulomb",
                                      "compare.blocked.0.axis": "displacement", "compare.blocked.0.threshold": 0.0},
      "laws[0] (coulomb)", "linear_velocity (sliding velocity"),
    C("fix-not-pair", FIT + ("--fix", "c_v"), "--fix 'c_v'", "NAME=VALUE"),
    C("fix-not-number", FIT + ("--fix", "c_v=fast"), "--fix c_v", "not a number"),
    C("fix-nan", FIT + ("--fix", "c_v=nan"), "--fix c_v", "finite"),
    C("fix-unknown", FIT + ("--fix", "i=1.5"), "--fix i", "no parameter or constant 'i'"),
    C("fix-outside-support", DAHL + ("--fix", "i=-1"), "--fix i", "outside the support"),
    C("fix-then-prior", DAHL + ("--fix", "i=1.5", "--prior", 'i={"dist":"HalfNormal","scale":1}'), "--prior i"),
]


def _tribometer(root: Path) -> None:
    """A small translational data file (force in mN against sliding speed and displacement)."""
    x = 1e3 * 20e-6 * np.sin(np.linspace(0, 4 * np.pi, 40))  # mm
    columns = zip(x, np.gradient(x), 0.5 * np.sign(x), strict=True)
    rows = "\n".join(f"{xi:.6g},{vi:.6g},{fi:.6g}" for xi, vi, fi in columns)
    (root / "tribo.csv").write_text("x_mm,v_mm_s,F_mN\n" + rows + "\n")
    (root / "tribo.toml").write_text(
        '[dataset]\nname = "tribo"\ntitle = "t"\nprovenance = "simulated"\nsource = "test"\n'
        '[columns.x_mm]\nrole = "input"\nquantity = "displacement"\nunit = "mm"\n'
        '[columns.v_mm_s]\nrole = "input"\nquantity = "linear_velocity"\nunit = "mm/s"\n'
        '[columns.F_mN]\nrole = "response"\nquantity = "force"\nunit = "mN"\n')
    (root / "tribo_x.csv").write_text("x_mm,F_mN\n" + "\n".join(f"{xi:.6g},{0.5 * np.sign(xi):.6g}" for xi in x) + "\n")
    (root / "tribo_x.toml").write_text(
        '[dataset]\nname = "tribo_x"\ntitle = "t"\nprovenance = "simulated"\nsource = "test"\n'
        '[columns.x_mm]\nrole = "input"\nquantity = "displacement"\nunit = "mm"\n'
        '[columns.F_mN]\nrole = "response"\nquantity = "force"\nunit = "mN"\n')


def test_variant_corpus_ids_unique():
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_variant_is_one_line_and_changes_nothing(case: Case, tree: Path):  # noqa: F811
    _tribometer(tree)
    if case.changes is not None:
        (tree / case.file).write_text(study_toml(case.changes, tree))
    assert_user_error(case.argv, tree, case.mentions)
