"""[[claims]]: declared in the study file, evaluated from the posterior, bad ones refused in one line."""

import math

import numpy as np
import pytest

from bayesfric.laws import get_law
from bayesfric.study import STUDIES_DIR, load_study
from bayesfric.study.claims import evaluate_claims, make_claim
from bayesfric.study.config import CLAIM
from bayesfric.study.schema import parse
from tests.hostile.harness import assert_user_error
from tests.hostile.test_study_corpus import study_toml, tree  # noqa: F401  (the case-tree fixture)
from tests.report.fakes import outcome, tree_of

BLOCKED = "velocity 1 (train ≤ cut, score below)"


def claim(**entry):
    return make_claim(parse(CLAIM, {"text": "t", "source": "s", **entry}))


@pytest.fixture
def study(tmp_path):
    (tmp_path / "tiny.toml").write_text(
        '[study]\nname = "tiny"\n[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\n'
        'name = "coulomb_viscous"\n[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\n'
        'threshold = 1.0\nlabel = "outside"\n')
    return load_study(tmp_path / "tiny.toml")


def test_ratio_parameter_score_and_best_against_hand_computed_values(study, tmp_path):
    """Fake posterior draws around T_C = 5, c_v = 2 (sd 5 %): the ratio's median is the ratio of
    the law at the centre up to a few per cent; a fully fixed numerator is exact."""
    out = outcome(study, tmp_path)
    claims = [
        claim(kind="ratio", law="coulomb_viscous", at={"velocity": "3 rad/s"},
              reference_at={"velocity": "0.5 rad/s"}, expect=[0.8, 0.9]),  # (5 + 6) / (5 + 1) − 1 = 0.833
        claim(kind="ratio", law="coulomb_viscous", fixed={"T_C": 5.0, "c_v": 4.0}, at={"velocity": "3 rad/s"},
              reference="coulomb", expect=[1.0, 2.0]),  # 17 / 6.3 − 1 = 1.698 (coulomb: T_C = 6.3)
        claim(kind="ratio", law="coulomb_viscous", at={"velocity": "3 rad/s"}, minus={"velocity": "1 rad/s"},
              reference_at={"velocity": "1 rad/s"}, reference_minus={"velocity": "0.5 rad/s"}, expect=[3.5, 4.5]),
        claim(kind="parameter", law="coulomb_viscous", parameter="c_v", expect=[2.5, 3.0]),
        claim(kind="score", law="coulomb", metric="penalty", scheme="outside", expect=[1.0, math.inf]),
        claim(kind="best", law="coulomb", metric="elpd_cv", scheme="outside"),
    ]
    ratio, fixed, chord, param, score, best = evaluate_claims(claims, tree_of(out))
    assert ratio.verdict == "reproduced" and ratio.value == pytest.approx(11 / 6 - 1, rel=0.03)
    assert ratio.lo < ratio.value < ratio.hi
    # numerator fixed, denominator coulomb's posterior (T_C ~ 6.3 ± 5 %)
    assert fixed.value == pytest.approx(17 / 6.3 - 1, rel=0.03) and fixed.verdict == "reproduced"
    # chords: (2·2) / (2·0.5) − 1 = 3 exactly for any T_C: outside the claimed 3.5–4.5
    assert chord.value == pytest.approx(3.0, rel=0.05) and chord.verdict == "not reproduced"
    assert param.verdict == "not reproduced" and param.value == pytest.approx(2.0, rel=0.02)
    assert score.verdict == "reproduced" and score.value == 15.0
    assert best.verdict == "not reproduced" and best.winner == "coulomb_viscous"


def test_failed_fit_makes_a_claim_not_testable(study, tmp_path):
    out = outcome(study, tmp_path, failed="coulomb_viscous")
    (result,) = evaluate_claims([claim(kind="parameter", law="coulomb_viscous", parameter="c_v", expect=[1, 3])],
                                tree_of(out))
    assert result.verdict == "not testable" and "failed the diagnostics gate" in result.why
    assert math.isnan(result.value)


def test_every_seed_study_declares_claims():
    for f in sorted(STUDIES_DIR.glob("*.toml")):
        study = load_study(f)
        assert study.claims, f"{f.name} declares no claim of its seed paper"
        assert all(c.source.startswith("seed 00") for c in study.claims)


def _claims(**entry):
    return {"claims": [{"text": "t", "source": "s", "law": "coulomb_viscous", **entry}]}


RATIO = {"kind": "ratio", "at": {"velocity": "3 rad/s"}, "expect": [0.0, 1.0]}
CASES = [
    ("kind-unknown", _claims(kind="guess"), "claims[0].kind", "one of"),
    ("law-unknown", {"claims": [{"text": "t", "source": "s", "kind": "best", "law": "nope", "metric": "elpd_loo"}]},
     "claims[0].law", "unknown law"),
    ("law-not-candidate", {"claims": [{"text": "t", "source": "s", "kind": "best", "law": "stribeck",
                                       "metric": "elpd_loo"}]}, "claims[0].law", "not a candidate"),
    ("text-missing", {"claims": [{"source": "s", "kind": "best", "law": "coulomb_viscous", "metric": "elpd_loo"}]},
     "claims[0].text", "required"),
    ("ratio-without-at", _claims(kind="ratio", expect=[0, 1]), "claims[0].at", "required"),
    ("expect-reversed", _claims(**(RATIO | {"expect": [1.0, 0.0]})), "claims[0].expect", "low ≤ high"),
    ("expect-text", _claims(**(RATIO | {"expect": ["a", "b"]})), "claims[0].expect", "two numbers"),
    ("at-bad-unit", _claims(**(RATIO | {"at": {"velocity": "3 kg"}})), "claims[0].at.velocity"),
    ("at-missing-input", _claims(**(RATIO | {"at": {"temperature": "20 degC"}})), "claims[0].at", "reads velocity"),
    ("fixed-unknown", _claims(**(RATIO | {"fixed": {"nope": 1.0}})), "claims[0].fixed.nope"),
    ("parameter-unknown", _claims(kind="parameter", parameter="nope", expect=[0, 1]), "claims[0].parameter", "nope"),
    ("key-of-other-kind", _claims(kind="parameter", parameter="c_v", expect=[0, 1], at={"velocity": "1 rad/s"}),
     "claims[0].at", "does not apply"),
    ("metric-unknown", _claims(kind="best", metric="nope"), "claims[0].metric", "unknown metric"),
    ("scheme-unknown", _claims(kind="score", metric="penalty", scheme="nope", expect=[0, 1]),
     "claims[0].scheme", "'nope'"),
]


@pytest.mark.parametrize(("changes", "mentions"), [(c[1], c[2:]) for c in CASES], ids=[c[0] for c in CASES])
def test_bad_claim_is_one_line_and_changes_nothing(tree, changes, mentions):  # noqa: F811
    (tree / "s.toml").write_text(study_toml(changes, tree))
    assert_user_error(("study", "s.toml", "--out", "reports"), tree, ("s.toml", *mentions))


def test_claim_ratio_of_trajectory_law_is_refused():
    from bayesfric.study.claims import ClaimError, check_claim

    c = claim(kind="ratio", law="dahl", at={"angle": "1 deg", "preload": "100 N"}, expect=[0, 1])
    with pytest.raises(ClaimError, match="trajectory"):
        check_claim(c, {"dahl": get_law("dahl")}, [], [])
    assert np.isfinite(c.at["angle"])


def test_fully_fixed_numerator_needs_only_the_reference_fit(study, tmp_path):
    """A catalogue prediction (every parameter fixed) against a passing reference stays testable
    when the numerator law's own fit failed: its posterior is never read."""
    out = outcome(study, tmp_path, failed="coulomb")
    c = claim(kind="ratio", law="coulomb", fixed={"T_C": 4.0}, at={"velocity": "1 rad/s"},
              reference="coulomb_viscous", expect=[-0.5, -0.2])  # 4 / (5 + 2) − 1 = −0.43
    (result,) = evaluate_claims([c], tree_of(out))
    assert result.verdict == "reproduced" and result.value == pytest.approx(4 / 7 - 1, rel=0.03)


# -- basis: pipeline check or evidence ------------------------------------------------------------
def test_every_claim_on_reconstructed_seed_data_declares_its_basis():
    """The five seed data sets are RECONSTRUCTED from their papers: each claim says whether its
    number was used to build the data (a pipeline check) or not (evidence)."""
    from bayesfric.datasets import load_builtin
    from bayesfric.study.claims import basis_problem

    for f in sorted(STUDIES_DIR.glob("*.toml")):
        study = load_study(f)
        provenance = load_builtin(study.dataset).attrs["provenance"]
        assert provenance == "reconstructed", f.name
        assert not [c.text for c in study.claims if basis_problem(c, provenance)], f.name


def test_basis_is_rendered_in_the_table_csv_and_summary(study, tmp_path):
    from bayesfric.report.content import _claim_warnings, _claims, claim_records

    out = outcome(study, tmp_path)
    results = evaluate_claims([
        claim(kind="best", law="coulomb", metric="elpd_loo", basis="pipeline check"),  # not reproduced
        claim(kind="best", law="coulomb_viscous", metric="elpd_loo", basis="evidence"),
        claim(kind="best", law="coulomb_viscous", metric="elpd_loo"),  # measured/simulated data: evidence
    ], tree_of(out))
    records = claim_records(results)
    table = _claims(records)
    basis = table.header.index("basis")
    assert [row[basis] for row in table.rows] == ["pipeline check, not evidence", "evidence", "evidence"]
    assert "pipeline check, not evidence" in table.caption
    assert [(r["basis"], r["evidence"]) for r in records] == [
        ("pipeline check", False), ("evidence", True), ("evidence", True)]
    lines = [" ".join(p for p, _ in f.parts) for f in _claim_warnings(records)]
    assert any("1 pipeline check(s)" in line and "NOT reproduced" in line for line in lines)
    assert not any("claim(s) of the source paper NOT" in line for line in lines)  # no evidence claim failed


BASIS_CASES = [
    ("basis-unknown", _claims(kind="best", metric="elpd_loo", basis="tuned"), "claims[0].basis", "one of"),
    ("basis-not-text", _claims(kind="best", metric="elpd_loo", basis=True), "claims[0].basis"),
    # robot_joint is RECONSTRUCTED: an undeclared basis is refused
    ("basis-missing-on-reconstructed-data", _claims(kind="best", metric="elpd_loo"), "claims[0].basis",
     "RECONSTRUCTED", "pipeline check"),
]


@pytest.mark.parametrize(("changes", "mentions"), [(c[1], c[2:]) for c in BASIS_CASES],
                         ids=[c[0] for c in BASIS_CASES])
def test_bad_basis_is_one_line_and_changes_nothing(tree, changes, mentions):  # noqa: F811
    (tree / "s.toml").write_text(study_toml(changes, tree))
    assert_user_error(("study", "s.toml", "--out", "reports"), tree, ("s.toml", *mentions))


def test_make_claim_refuses_a_bad_basis_without_the_schema():
    from bayesfric.study.claims import ClaimError

    with pytest.raises(ClaimError, match="basis: must be one of"):
        make_claim({"text": "t", "source": "s", "kind": "best", "law": "coulomb", "metric": "elpd_loo",
                    "basis": "maybe"})


# -- one predictive path: a claim on a variant predicts with the variant ---------------------------
def _variant_fit(law, draws: dict[str, float], sd: float = 1e-3):
    """A hand-made fit of ``law`` (a variant) with the attrs a real fit stores (recipe included):
    draws N(value, sd·|value|), 2 chains × 100."""
    import arviz as az

    from bayesfric.inference.datatree import provenance
    from bayesfric.model import build_program
    from tests.report.fakes import data

    ds = data()
    rng = np.random.default_rng(1)
    post = {k: v + sd * abs(v) * rng.standard_normal((2, 100)) for k, v in draws.items()}
    post["sigma"] = 0.2 + 0.0 * rng.standard_normal((2, 100))
    fit = az.from_dict({"posterior": post})
    fit.attrs.update(provenance(build_program(law, ds), ds, "nuts", {}, 0))
    return fit


def _with(out, name: str, law, fit):
    """``out`` with the law labelled ``name`` replaced by ``law`` and its fit (its result tree's
    rows carry the new law's name, as a study run's would)."""
    import dataclasses

    out.laws = [dataclasses.replace(w, law=law, fit=fit) if w.name == name else w for w in out.laws]
    return out


def test_claim_on_an_offset_variant_predicts_with_the_offset(study, tmp_path):
    """A study entry without a label is labelled by the base law's name (``coulomb_viscous`` +
    offset, named so here as the study names it): the claim must predict with the fitted program
    (offset included), not the base law looked up by name, which would silently drop the offset:
    14/10 − 1 = 0.4, not 11/7 − 1 = 0.571."""
    from bayesfric.laws.variants import vary
    from bayesfric.study.claims import mean_draws

    law = vary(get_law("coulomb_viscous"), offset=True, name="coulomb_viscous")
    assert law.name == "coulomb_viscous" and "offset" in law.params
    fit = _variant_fit(law, {"T_C": 5.0, "c_v": 2.0, "offset": 3.0})
    out = _with(outcome(study, tmp_path), "coulomb_viscous", law, fit)
    c = make_claim(parse(CLAIM, {"text": "t", "source": "s", "kind": "ratio", "law": "coulomb_viscous",
                                 "at": {"velocity": "3 rad/s"}, "reference_at": {"velocity": "1 rad/s"},
                                 "expect": [0.35, 0.45]}), {"coulomb_viscous": law})
    (result,) = evaluate_claims([c], tree_of(out))
    assert result.value == pytest.approx(0.4, rel=1e-2) and result.verdict == "reproduced"
    assert np.median(mean_draws(fit, {"velocity": 3.0})) == pytest.approx(14.0, rel=1e-2)


def test_claim_on_a_fixed_variant_reads_its_fixed_value_and_may_override_it(study, tmp_path):
    """A labelled variant with c_v fixed at 2 (its posterior has no c_v): the claim resolves the
    label, predicts with c_v = 2, and a claim's own ``fixed`` replaces that constant."""
    from bayesfric.laws.variants import vary
    from bayesfric.study.claims import ClaimError

    law = vary(get_law("coulomb_viscous"), name="cv_fixed", fixed={"c_v": 2.0})
    fit = _variant_fit(law, {"T_C": 5.0})
    out = _with(outcome(study, tmp_path), "coulomb_viscous", law, fit)
    laws = {"cv_fixed": law, "coulomb": get_law("coulomb")}
    own = make_claim(parse(CLAIM, {"text": "t", "source": "s", "kind": "ratio", "law": "cv_fixed",
                                   "at": {"velocity": "3 rad/s"}, "reference_at": {"velocity": "1 rad/s"},
                                   "expect": [0.5, 0.6]}), laws)  # (5 + 6) / (5 + 2) − 1 = 0.571
    catalogue = make_claim(parse(CLAIM, {"text": "t", "source": "s", "kind": "ratio", "law": "cv_fixed",
                                         "fixed": {"c_v": 4.0}, "at": {"velocity": "3 rad/s"},
                                         "reference_at": {"velocity": "1 rad/s"}, "expect": [1.3, 1.5]}), laws)
    first, second = evaluate_claims([own, catalogue], tree_of(out))
    assert first.value == pytest.approx(11 / 7 - 1, rel=1e-2) and first.verdict == "reproduced"
    assert second.value == pytest.approx(17 / 7 - 1, rel=1e-2) and second.verdict == "reproduced"
    with pytest.raises(ClaimError, match="has no parameter 'c_v'"):  # fixed: not a posterior parameter
        make_claim(parse(CLAIM, {"text": "t", "source": "s", "kind": "parameter", "law": "cv_fixed",
                                 "parameter": "c_v", "expect": [0, 1]}), laws)


def test_study_claim_may_name_a_variant_by_its_label(tmp_path):
    (tmp_path / "v.toml").write_text(
        '[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb_viscous"\nlabel = "cv_off"\noffset = true\n'
        '[compare]\nevidence = false\n[[claims]]\ntext = "t"\nsource = "s"\nkind = "parameter"\nlaw = "cv_off"\n'
        'parameter = "offset"\nexpect = [0.0, 1.0]\nbasis = "evidence"\n')
    (c,) = load_study(tmp_path / "v.toml").claims
    assert (c.law, c.parameter, c.basis) == ("cv_off", "offset", "evidence")


# -- score differences ----------------------------------------------------------------------------
def test_score_difference_uses_the_paired_standard_error(study, tmp_path):
    out = outcome(study, tmp_path)
    (diff,) = evaluate_claims([claim(kind="score", law="coulomb", reference="coulomb_viscous", metric="elpd_loo",
                                     expect=[-math.inf, 0.0])], tree_of(out))
    # fakes: elpd_loo −90 and 9, pointwise values constant per law -> paired se 0
    assert diff.value == pytest.approx(-99.0) and diff.verdict == "reproduced"
    assert diff.hi - diff.lo == pytest.approx(0.0, abs=1e-9)
