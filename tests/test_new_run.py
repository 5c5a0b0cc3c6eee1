"""Answers for a new run when the runs differ (bayesfric.sizing.newrun): the rule's three modes,
the widening's distribution, the basis restricted to the laws that model a flagged group, the
statement said first, the spread prior for few levels, and the between-group sd the
residual-structure check measures; (slow) the two-run case a user brought, through a study."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr
from scipy import stats

from bayesfric.compare.structure_stats import Column, StructureCheck, structure_tests
from bayesfric.hierarchy import SPREAD, SPREAD_WIDTH, hyperprior
from bayesfric.priors import Prior
from bayesfric.sizing.basis import LOO, choose_basis
from bayesfric.sizing.newrun import MAX_LOG_FACTOR, LawGroups, NewRun, rule, widen_draws


def _flag(column="run", levels=2, between=0.2, flagged=True):
    return StructureCheck(column, "group", levels, 0.3, 6.0, 1e-6 if flagged else 0.5, 0.05, flagged, "", "N*m",
                          "velocity", 0.0, 1, between)


def _laws(aware_usable=True, with_aware=True):
    pooled = LawGroups("cv", frozenset(), True, (_flag(),), 2.0)
    stribeck = LawGroups("stribeck", frozenset(), True, (_flag(between=0.4),), 2.0)
    aware = LawGroups("cv_by_run", frozenset({"run"}), aware_usable, (), 2.0)
    return [pooled, stribeck] + ([aware] if with_aware else [])


# -- the rule ---------------------------------------------------------------------------------------
def test_no_flag_no_rule():
    quiet = [LawGroups("cv", frozenset(), True, (_flag(flagged=False),), 2.0)]
    r = rule(quiet)
    assert r.mode == "" and r.statement == "" and r.names(["cv"]) == ["cv"] and not r.widened("cv")


def test_a_flagged_run_with_a_usable_group_aware_law_answers_from_it_alone():
    r = rule(_laws())
    assert r.mode == "aware" and r.aware == ("cv_by_run",) and set(r.blind) == {"cv", "stribeck"}
    assert r.names(["cv", "stribeck", "cv_by_run"]) == ["cv_by_run"]
    assert not r.widened("cv")  # the blind laws are left out, not widened
    assert r.statement.startswith("FOR A NEW 'run'") and "cv_by_run" in r.statement and "left out" in r.statement


def test_every_group_aware_law_failed_cannot_answer_for_a_new_run():
    r = rule(_laws(aware_usable=False))
    assert r.mode == "cannot" and r.failed == ("cv_by_run",) and r.aware == ()
    assert r.statement.startswith("CANNOT ANSWER FOR A NEW 'run'") and "FAILED" in r.statement
    assert r.widened("cv") and r.spreads["cv"]["run"] == pytest.approx(0.1)  # 0.2 N·m over a mean |T| of 2
    assert r.names(["cv", "stribeck"]) == ["cv", "stribeck"]


def test_no_group_aware_law_widens_the_pooled_laws_by_their_measured_spread():
    r = rule(_laws(with_aware=False))
    assert r.mode == "widened" and r.spreads == {"cv": {"run": pytest.approx(0.1)},
                                                  "stribeck": {"run": pytest.approx(0.2)}}
    assert "no law models 'run'" in r.statement and "vary_by" in r.statement


def test_a_column_only_a_minority_of_blind_laws_shows_is_their_misfit_not_a_new_run_question():
    quiet = _flag(between=0.1, flagged=False)
    minority = [LawGroups("coulomb", frozenset(), True, (_flag(),), 2.0)] + [
        LawGroups(f"law{i}", frozenset(), True, (quiet,), 2.0) for i in range(3)]
    assert rule(minority).mode == ""
    half = minority[:3]  # one of two blind laws shows it
    assert rule(half[:2]).mode == "widened"


def test_a_failed_blind_law_flags_nothing():
    failed = [LawGroups("cv", frozenset(), False, (_flag(),), 2.0)]
    assert rule(failed).mode == ""


# -- the widening -------------------------------------------------------------------------------------
def test_widening_is_one_student_t_factor_per_draw_with_levels_minus_one_degrees_of_freedom():
    mu = np.full((20000, 3), 2.0)
    w = widen_draws(mu, 0.1, 5, seed=3)
    assert np.allclose(w[:, 0], w[:, 2])  # shared by the points: a run is one factor
    t = np.log(w[:, 0] / 2.0) / (0.1 * math.sqrt(1 + 1 / 5))
    assert stats.kstest(t, stats.t(4).cdf).pvalue > 1e-3
    assert widen_draws(mu, float("nan"), 5) is mu and widen_draws(mu, 0.1, 1) is mu
    two = widen_draws(mu, 0.2, 2, seed=1)  # Cauchy: cut at a factor 1e6, never infinite
    assert np.isfinite(two).all() and np.max(np.abs(np.log(two / 2.0))) <= MAX_LOG_FACTOR + 1e-9


def test_widened_prediction_interval_covers_a_new_group_as_the_textbook_interval_does():
    """G group means, a new one: the widened band of the pooled mean holds it 90 % of the time."""
    rng = np.random.default_rng(0)
    hits = []
    for _ in range(400):
        groups = np.exp(0.2 * rng.normal(size=4))
        mean, sd = groups[:3].mean(), groups[:3].std(ddof=1)
        band = widen_draws(np.full((4000, 1), mean), sd / mean, 3, seed=int(rng.integers(1 << 30)))
        lo, hi = np.quantile(band, [0.05, 0.95])
        hits.append(lo <= groups[3] <= hi)
    assert 0.85 <= np.mean(hits) <= 0.96


# -- the basis --------------------------------------------------------------------------------------
def _basis(new_run, weights):
    grid = {"velocity": np.array([1.0])}
    data = {"velocity": np.linspace(0.1, 2, 10)}
    names = list(weights)
    return choose_basis(grid, data, (), names, {k: {LOO: v} for k, v in weights.items()}, {}, {}, new_run)


def test_the_basis_weighs_only_the_laws_that_model_the_flagged_group():
    r = rule(_laws())
    basis = _basis(r, {"cv": 0.7, "stribeck": 0.2, "cv_by_run": 0.1})
    assert basis.weights == {"cv_by_run": pytest.approx(1.0)} and basis.new_run == r.statement
    # none of them has a weight there: equal weights over them, said
    two = rule(_laws() + [LawGroups("st_by_run", frozenset({"run"}), True, (), 2.0)])
    basis = _basis(two, {"cv": 0.9, "stribeck": 0.1, "cv_by_run": 0.0, "st_by_run": 0.0})
    assert basis.weights == {"cv_by_run": 0.5, "st_by_run": 0.5} and "equal weights" in basis.note
    assert _basis(NewRun(), {"cv": 0.9, "cv_by_run": 0.1}).weights == {"cv": 0.9, "cv_by_run": 0.1}


def test_the_statement_is_the_first_thing_an_answer_says():
    from types import SimpleNamespace

    from bayesfric.sizing.tidy import first_warnings

    r = rule(_laws(aware_usable=False))
    basis = _basis(r, {"cv": 0.5, "stribeck": 0.5})
    answer = SimpleNamespace(basis=basis, distance={"velocity": np.array([0.0])})
    assert first_warnings(answer)[0].startswith("CANNOT ANSWER FOR A NEW 'run'")


# -- the spread prior and the spread measured -----------------------------------------------------------
def test_the_spread_prior_vanishes_at_zero_and_puts_90_percent_between_6_and_63_percent():
    prior = hyperprior(Prior("HalfNormal", scale=2.0), "T_C")
    assert prior.dist == "LogNormal" and prior.args["scale"] == SPREAD_WIDTH
    lo, hi = (math.exp(math.log(SPREAD) + z * SPREAD_WIDTH) for z in (-1.645, 1.645))
    assert 0.05 < lo < 0.07 and 0.55 < hi < 0.7
    real = hyperprior(Prior("Normal", loc=0.0, scale=2.0, scaled_by={"response": 1}), "offset")
    assert real.dist == "LogNormal" and real.scaled_by == {"response": 1} and real.args["loc"] == pytest.approx(
        math.log(0.5))


@pytest.mark.parametrize("offsets", [(0.0, 0.3), (0.0, 0.2, 0.5), (-0.2, 0.0, 0.1, 0.3, 0.4)])
def test_the_check_measures_the_between_group_sd_of_group_offsets(offsets):
    rng = np.random.default_rng(1)
    v = np.tile(np.linspace(0.1, 2, 40), len(offsets))
    run = np.repeat(np.arange(len(offsets)), 40)
    resid = np.asarray(offsets)[run] + 0.05 * rng.normal(size=run.size)
    (check,) = structure_tests(resid, np.full(run.size, 0.05), {"velocity": v}, [Column("run", "group", run)])
    assert check.flagged and check.between_sd == pytest.approx(np.std(offsets, ddof=1), rel=0.1)
    (numeric,) = structure_tests(resid, np.full(run.size, 0.05), {"velocity": v},
                                 [Column("temperature", "trend", run.astype(float), "temperature")])
    assert math.isnan(numeric.between_sd)


# -- a blocked fold scored for a new run (bayesfric.compare.newgroup) --------------------------------
def test_a_new_run_with_no_spread_is_the_typical_run_scored_jointly():
    """With every spread draw at zero, a new level is the typical value: each run's held-out rows
    scored jointly equal log mean_s Π_i N(y_i | T_C_s + c_v_s v_i, σ_s), computed here by hand."""
    from bayesfric.compare.newgroup import new_group_lpd
    from bayesfric.datasets.synthetic import simulate_runs
    from bayesfric.laws import get_law
    from bayesfric.model import build_program

    law = get_law("coulomb_viscous")
    ds, _ = simulate_runs(law, {"velocity": np.linspace(0.1, 2, 8)}, {"T_C": 2.0, "c_v": 1.0}, {"T_C": 0.2},
                          runs=3, sigma=0.05, seed=4)
    program = build_program(law.vary_by("run", "T_C"), ds)
    rng = np.random.default_rng(0)
    s = 50
    t_c, c_v, sigma = 2.0 + 0.05 * rng.normal(size=s), 1.0 + 0.02 * rng.normal(size=s), 0.05 + 0.005 * rng.random(s)
    samples = {"T_C": t_c, "c_v": c_v, "sigma": sigma, "T_C_sd": np.zeros(s),
               "T_C_u": np.log(np.full((s, 3), 9.0)), "T_C_run": np.full((s, 3), 9.0)}  # named levels far off
    samples = {k: v.reshape((1, s) + v.shape[1:]) for k, v in samples.items()}
    v, y = ds["velocity"].values, ds["torque"].values
    groups = np.repeat([0, 1, 2], 8)
    held = v > 1.0
    got = new_group_lpd(program, samples, held, groups, "run")
    for g in range(3):
        rows = held & (groups == g)
        ll = stats.norm.logpdf(y[rows][None, :], t_c[:, None] + c_v[:, None] * v[rows][None, :],
                               sigma[:, None]).sum(axis=1)
        assert got[g] == pytest.approx(float(np.logaddexp.reduce(ll) - np.log(s)), abs=1e-8)


def test_new_run_weights_need_three_runs_and_then_weigh_the_better_law():
    from bayesfric.compare.refit import CVResult
    from bayesfric.compare.weights import new_group_weights
    from bayesfric.inference.diagnostics import Verdict

    ok = [Verdict(True, 1.0, 900.0, 900.0, 0, 0.9, None)]

    def result(values):
        return CVResult("law", "blocked", 0.0, 0.0, np.zeros(3), np.ones(3, bool), ok, 0.0,
                        elpd_new_group=np.asarray(values, dtype=float))

    with pytest.raises(ValueError, match="cannot tell the laws apart for a new group: 2 groups"):
        new_group_weights({"a": result([-1, -2]), "b": result([-5, -6])})
    w = new_group_weights({"a": result([-1, -2, -3, -1, -2, -1]), "b": result([-9, -8, -9, -10, -9, -8])})
    assert w.weights["a"] > 0.9


# -- (slow) the two-run case a user brought, through a study --------------------------------------------
def _two_runs(folder):
    """Own data as a newcomer has it: two runs 10 % apart (Coulomb level and viscous coefficient),
    60 rows, a Stribeck + viscous truth (Armstrong-Hélouvry), SIMULATED."""
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.laws import get_law

    v = np.tile(np.linspace(0.05, 2.0, 30), 2)
    run = np.repeat(["a", "b"], 30)
    truth = {"T_C": np.where(run == "a", 2.0, 2.2), "dT_s": 1.0, "v_s": 0.2, "delta": 1.0,
             "c_v": np.where(run == "a", 1.0, 1.1)}
    ds = simulate(get_law("armstrong_helouvry"), {"velocity": v}, truth, sigma=0.05, seed=3, groups={"run": run})
    rows = ["speed,torque,run"] + [f"{a:.10g},{b:.10g},{c}" for a, b, c in
                                   zip(ds["velocity"].values, ds["torque"].values, run, strict=True)]
    (folder / "runs.csv").write_text("\n".join(rows) + "\n")
    (folder / "runs.toml").write_text(
        '[dataset]\nname = "runs"\nprovenance = "simulated"\nsource = "test"\n'
        '[columns.speed]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n'
        '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n[columns.run]\nrole = "group"\n')
    return folder / "runs.csv"


@pytest.fixture(scope="module")
def two_run_study(tmp_path_factory):
    import bayesfric

    folder = tmp_path_factory.mktemp("two_runs")
    by_run = bayesfric.law("armstrong_helouvry").vary_by("run", "T_C", "c_v")
    study = bayesfric.Study("runs", _two_runs(folder), laws=["coulomb_viscous", "armstrong_helouvry", by_run],
                            compare={"evidence": False, "blocked": [{"axis": "velocity", "threshold": 1.5}]},
                            sizing=[{"at": {"velocity": "1..3 rad/s"}}])  # the default sampler, 4 x 1000
    return bayesfric.run(study, folder / "reports"), folder, by_run.name


@pytest.mark.slow
def test_two_runs_the_group_term_law_passes_and_carries_the_new_run_answer(two_run_study):
    result, folder, by_run = two_run_study
    diag = result.tree["diagnostics"].to_dataset()
    assert bool(diag["passed"].sel(law=by_run)), str(diag["problems"].sel(law=by_run).values)
    sizing = result.sizing
    # the answer for a new run comes from the group-term law alone, and says so first
    laws = sizing[sizing.role == "law"]
    used = laws.groupby("law")["weight_used"].max()
    assert used[by_run] == pytest.approx(1.0) and used.drop(by_run).max() == 0.0
    assert sizing["warnings"].str.startswith("FOR A NEW 'run'").all()
    summary = (folder / "reports" / "runs" / "summary.md").read_text()
    first = next(line for line in summary.splitlines() if line.startswith("- "))
    assert first.startswith("- FOR A NEW 'run'")
    recommendation = next(line for line in summary.splitlines() if line.startswith("**For a NEW 'run'"))
    for_new = recommendation.split("For the tested")[0]
    assert f"use **{by_run.replace('_', chr(92) + '_')}**" in for_new  # the pooled laws are not recommended
    # two runs cannot weigh laws for a new run, and leave-one-run-out cannot rank them: both say so
    assert "cannot tell the laws apart for a new group: 2 groups" in summary
    scores = result.scores
    logo = scores[(scores.metric == "elpd_cv") & (scores.scheme == "leave-one-run-out")]
    assert not logo["reliable"].any() and logo["reason"].str.contains("each fold trained on 1").all()


@pytest.mark.slow
def test_every_group_aware_law_failed_says_cannot_answer_for_a_new_run_first(two_run_study):
    """The same study with its group-term fit failed: the summary and the sizing answer say first
    that they cannot answer for a new run."""
    from bayesfric import sizing
    from bayesfric.report.findings import summary_block
    from bayesfric.report.view import TreeView
    from bayesfric.sizing.answer import answer_question
    from bayesfric.sizing.points import make_question
    from bayesfric.sizing.tidy import first_warnings

    result, folder, by_run = two_run_study
    tree = result.tree.copy(deep=True)
    diag = tree["diagnostics"].to_dataset()
    diag["passed"] = diag["passed"].where(diag["law"] != by_run, False)
    diag["problems"] = diag["problems"].where(diag["law"] != by_run, "12 divergent transitions")
    tree["diagnostics"] = xr.DataTree(diag)
    summary = summary_block(TreeView(tree))
    assert summary.answers[0].parts[0][0].startswith("CANNOT ANSWER FOR A NEW 'run'")
    assert "CANNOT ANSWER FOR A NEW 'run'" in "".join(p for p, _ in summary.recommendation.parts)
    sources = sizing.sources(tree, folder / "reports" / "runs", fits=dict(result.fits))
    data = {"velocity": np.asarray(result.tree["fits"][by_run]["constant_data"]["velocity"].values)}
    question = make_question({"velocity": "1..3 rad/s"}, 0.99)
    answer = answer_question(question, sources, data, schemes=sizing.basis_schemes(tree), fan=False)
    assert first_warnings(answer)[0].startswith("CANNOT ANSWER FOR A NEW 'run'")
    assert answer.basis.weights.get(by_run, 0.0) == 0.0


def test_leave_one_group_out_with_two_groups_cannot_tell():
    from bayesfric.compare.refit import CVResult, _too_few
    from bayesfric.compare.weights import _why_unreliable
    from bayesfric.inference.diagnostics import Verdict

    ok = [Verdict(True, 1.0, 900.0, 900.0, 0, 0.9, None)] * 2
    r = CVResult("law", "leave-one-run-out", -2700.0, 1300.0, np.zeros(4), np.ones(4, bool), ok, 0.0,
                 elpd_fold=np.array([-100.0, -2600.0]), too_few=_too_few(2, 3))
    assert not r.reliable and "each fold trained on 1" in r.failure and _why_unreliable(r) == r.failure
    assert _too_few(3, 3) == ""
