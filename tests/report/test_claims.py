"""[[claims]]: declared in the study file, evaluated from the posterior, bad ones refused in one line."""

import math

import numpy as np
import pytest

from bayesfric.study import STUDIES_DIR, load_study
from bayesfric.study.claims import evaluate_claims, make_claim
from bayesfric.study.config import CLAIM
from bayesfric.study.schema import parse
from tests.hostile.harness import assert_user_error
from tests.hostile.test_study_corpus import study_toml, tree  # noqa: F401  (the case-tree fixture)
from tests.report.fakes import outcome

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
    ratio, fixed, chord, param, score, best = evaluate_claims(claims, out, out.table)
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
                                out, out.table)
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
        check_claim(c, ["dahl"], [], [])
    assert np.isfinite(c.at["angle"])


def test_fully_fixed_numerator_needs_only_the_reference_fit(study, tmp_path):
    """A catalogue prediction (every parameter fixed) against a passing reference stays testable
    when the numerator law's own fit failed: its posterior is never read."""
    out = outcome(study, tmp_path, failed="coulomb")
    c = claim(kind="ratio", law="coulomb", fixed={"T_C": 4.0}, at={"velocity": "1 rad/s"},
              reference="coulomb_viscous", expect=[-0.5, -0.2])  # 4 / (5 + 2) − 1 = −0.43
    (result,) = evaluate_claims([c], out, out.table)
    assert result.verdict == "reproduced" and result.value == pytest.approx(4 / 7 - 1, rel=0.03)
