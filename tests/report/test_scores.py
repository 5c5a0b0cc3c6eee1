"""The law × metric table: one row per score, reliability as a field, winners read from it."""

import math

import numpy as np
import pytest

from bayesfric.compare import EstimatorAgreement
from bayesfric.inference.diagnostics import Verdict
from bayesfric.laws import get_law
from bayesfric.study import load_study
from bayesfric.study import scores as sc
from tests.report.fakes import OK, FakeLaw, cv_result, evidence, loo_result

LABEL = "train inside, score outside"
STUDY = ('[study]\nname = "tiny"\n[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n'
         '[[laws]]\nname = "coulomb_viscous"\n[compare]\nloo = true\nevidence = false\n'
         '[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.0\n')


@pytest.fixture
def study(tmp_path):
    (tmp_path / "tiny.toml").write_text(STUDY)
    return load_study(tmp_path / "tiny.toml")


def law(tmp_path, name, loo, blocked=None, blocked_ok=True, verdict=OK, estimates=None, agree=True):
    held = np.arange(10) > 6
    cv = {LABEL: cv_result(name, LABEL, blocked, 1.0, held, reliable=blocked_ok)} if blocked is not None else {}
    agreement = None
    if estimates:
        agreement = EstimatorAgreement(estimates["bridge"], estimates["importance"], 3.0, 0.2, agree)
    return FakeLaw(law=get_law(name), fit=None, verdict=verdict, loo=loo_result(name, loo, 1.0, n=10),
                   cv=cv, penalty={LABEL: 0.5} if cv else {}, evidence=estimates or {}, agreement=agreement)


def scored(study, laws, blocked=(LABEL,)):
    """The study's score table of the fake laws' results, as the result tree builds it."""
    return sc.score_table([w.result() for w in laws], list(blocked), study.include_failed)


def test_table_is_tidy_one_row_per_law_metric_scheme(study, tmp_path):
    table = scored(study, [law(tmp_path, "coulomb", -10.0, -5.0), law(tmp_path, "coulomb_viscous", -2.0, -8.0)])
    assert list(table.columns) == sc.COLUMNS
    assert not table.duplicated(["law", "metric", "scheme"]).any()
    assert set(table["metric"]) == {"elpd_loo", "elpd_cv", "penalty"}
    row = sc.value(table, "coulomb", "elpd_cv", LABEL)
    assert (row["estimate"], row["se"], row["reliable"], row["reason"]) == (-5.0, 1.0, True, "")
    assert math.isnan(sc.value(table, "coulomb", "penalty", LABEL)["se"])  # not computed: NaN, never guessed


def test_winner_skips_unreliable_fold_and_names_it(study, tmp_path):
    """A law whose blocked fold failed the gate is not ranked; passed_over names it."""
    table = scored(study, [law(tmp_path, "coulomb", -10.0, -5.0, blocked_ok=False),
                           law(tmp_path, "coulomb_viscous", -2.0, -8.0)])
    assert sc.best(table, "elpd_loo") == "coulomb_viscous" and sc.passed_over(table, "elpd_loo") == []
    assert sc.best(table, "elpd_cv", LABEL) == "coulomb_viscous"
    assert sc.passed_over(table, "elpd_cv", LABEL) == ["coulomb"]
    assert sc.value(table, "coulomb", "elpd_cv", LABEL)["reason"] == (
        "its only fold failed the diagnostics gate (R-hat 1.2 > 1.01)")  # which fold and why
    assert sc.ranking_order(table, ["coulomb_viscous", "coulomb"], sc.Criterion("elpd_cv", LABEL, "x")) == [
        "coulomb", "coulomb_viscous"]  # the unreliable higher score keeps its place (issue 29)
    assert sc.best(table, "elpd_cv", LABEL, counted=True) == "coulomb"  # the winner if it were counted


def test_evidence_disagreement_keeps_a_law_out_of_the_evidence_ranking(study, tmp_path):
    def ev(z):
        return {"bridge": evidence(z, 0.01, "bridge"), "importance": evidence(z + 3, 0.01, "laplace-is")}

    table = scored(study, [law(tmp_path, "coulomb", -5.0, estimates=ev(-1.0), agree=False),
                           law(tmp_path, "coulomb_viscous", -5.0, estimates=ev(-4.0))], blocked=())
    assert sc.best(table, "log_evidence", "bridge") == sc.best(table, "log_evidence", "importance") == "coulomb_viscous"
    assert sc.passed_over(table, "log_evidence", "bridge") == ["coulomb"]
    assert "disagree" in sc.value(table, "coulomb", "log_evidence", "bridge")["reason"]


def test_failed_fit_is_ranked_only_with_include_failed(study, tmp_path):
    bad = Verdict(False, 1.3, 10.0, 10.0, 5, 0.1, 0.9, problems=["R-hat"])
    laws = [law(tmp_path, "coulomb", 0.0, verdict=bad), law(tmp_path, "coulomb_viscous", -2.0)]
    assert sc.best(scored(study, laws, blocked=()), "elpd_loo") == "coulomb_viscous"
    study.include_failed = True
    table = scored(study, laws, blocked=())
    assert sc.best(table, "elpd_loo") == "coulomb"
    assert "include_failed" in sc.value(table, "coulomb", "elpd_loo")["reason"]


def test_penalty_best_is_the_lowest(study, tmp_path):
    a, b = law(tmp_path, "coulomb", -1.0, -5.0), law(tmp_path, "coulomb_viscous", -1.0, -6.0)
    a.penalty[LABEL], b.penalty[LABEL] = 2.0, 0.1
    table = scored(study, [a, b])
    assert sc.best(table, "penalty", LABEL) == "coulomb_viscous"


def test_penalty_carries_its_standard_error(study, tmp_path):
    """The penalty's se is the paired differences' (LOO − blocked on the same points), not NaN."""
    from dataclasses import replace

    a = law(tmp_path, "coulomb", -1.0, -5.0)
    a = replace(a, penalty_se={LABEL: 0.12})
    table = scored(study, [a])
    assert sc.value(table, "coulomb", "penalty", LABEL)["se"] == 0.12


def test_fold_failure_names_the_folds_from_one_with_their_problems():
    from dataclasses import replace

    from tests.report.fakes import BAD

    held = np.arange(10) > 6
    cv = cv_result("coulomb", LABEL, -5.0, 1.0, held)
    other = replace(BAD, problems=["3 divergent transitions"])
    assert replace(cv, verdicts=[OK, BAD, OK, other]).failure == (
        "folds 2, 4 of 4 failed the diagnostics gate (fold 2: R-hat 1.2 > 1.01; fold 4: 3 divergent transitions)")
    assert replace(cv, verdicts=[OK, BAD]).failure == "fold 2 of 2 failed the diagnostics gate (R-hat 1.2 > 1.01)"
    assert replace(cv, verdicts=[OK, OK]).failure == "" and sc.fold_failure(cv) == ""
