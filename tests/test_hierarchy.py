"""Group terms (bayesfric.hierarchy): declaration, program sites, hand-computed levels, answers
for a new or a named level, a fit saved and read back, the study file, and (slow) recovery and
the calibration of a new run's band on SIMULATED runs."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest
from numpyro import handlers
from scipy import stats

import bayesfric
from bayesfric import hierarchy, inference
from bayesfric.compare.refit import joint_lpd
from bayesfric.datasets.synthetic import simulate_runs
from bayesfric.errors import DataError
from bayesfric.laws import get_law
from bayesfric.laws.variants import VariantError, describe
from bayesfric.model import build_program
from bayesfric.priors import Prior
from bayesfric.study.config import StudyError, study_from_raw

SPEEDS = np.linspace(0.1, 2.0, 20)
TRUTH = {"T_C": 2.0, "c_v": 1.0}


def _runs(rows: int = 20, runs: int = 6, seed: int = 1):
    return simulate_runs(get_law("coulomb_viscous"), {"velocity": np.linspace(0.1, 2.0, rows)}, TRUTH,
                         {"T_C": 0.15, "c_v": 0.15}, runs=runs, sigma=0.05, seed=seed)


# -- declaration ----------------------------------------------------------------------------------
def test_vary_by_records_a_recipe_and_says_so():
    law = get_law("coulomb_viscous").vary_by("run", "T_C").vary_by("run", "c_v")
    assert law.varying == {"T_C": "run", "c_v": "run"}
    assert law.recipe["vary_by"] == {"run": ["T_C", "c_v"]}
    assert "T_C, c_v vary by run" in describe(law)
    assert (get_law("coulomb_viscous") + "offset").vary_by("unit", "offset").varying == {"offset": "unit"}


@pytest.mark.parametrize("make, problem", [
    (lambda: get_law("coulomb_viscous").vary_by("run", "nope"), "no sampled parameter 'nope'"),
    (lambda: get_law("coulomb_viscous").vary_by("run", "T_C").vary_by("unit", "T_C"), "varies by both"),
    (lambda: get_law("dahl").vary_by("run", "F_c0").vary_by("unit", "gamma"), "one group column"),
    (lambda: get_law("coulomb_viscous").vary_by("run"), "non-empty list"),
])
def test_vary_by_refuses_what_cannot_vary(make, problem):
    with pytest.raises(VariantError, match=problem):
        make()


def test_a_program_needs_the_column_and_a_real_parameter_spreads_in_its_unit():
    ds, _ = _runs()
    with pytest.raises(DataError, match="'unit', which is not a column"):
        build_program(get_law("coulomb_viscous").vary_by("unit", "T_C"), ds)
    with pytest.raises(DataError, match="varies by 'velocity' is an input"):  # a continuous input is no group
        build_program(get_law("coulomb_viscous").vary_by("velocity", "T_C"), ds)
    law = (get_law("coulomb_viscous") + "offset").vary_by("run", "offset")
    program = build_program(law, ds)  # Normal prior: the spread's median is a quarter of its scale, data-scaled alike
    assert np.exp(program.priors["offset_sd"].args["loc"]) == pytest.approx(
        hierarchy.REAL_SPREAD * program.priors["offset"].args["scale"])
    assert program.priors["offset_sd"].scaled_by == program.priors["offset"].scaled_by
    assert hierarchy.hyperprior(Prior("HalfNormal", scale=2.0), "T_C").dist == "LogNormal"
    # a campaign scatter about a trend keeps its half-normal prior (calibrated forecasts)
    assert hierarchy.hyperprior(Prior("HalfNormal", scale=2.0), "T_C", trend=True) == Prior(
        "HalfNormal", scale=hierarchy.TREND_SPREAD)
    hours = ds.assign_coords(run=("obs", [str(int(r[1:]) * 100) for r in ds["run"].values], ds["run"].attrs))
    trend = build_program(get_law("coulomb_viscous").trend("run", "T_C"), hours)
    assert trend.priors["T_C_sd"] == Prior("HalfNormal", scale=hierarchy.TREND_SPREAD)


def test_study_file_vary_by_and_its_errors(tmp_path):
    raw = {"study": {"name": "s"}, "data": {"dataset": "robot_joint"},
           "laws": [{"name": "coulomb_viscous", "label": "cv_series", "vary_by": {"series": ["T_C"]}}]}
    study = study_from_raw(tmp_path / "s.toml", raw)
    assert study.laws[0].build().varying == {"T_C": "series"}
    assert study.grouped == "series"  # leave-one-series-out by default
    raw["laws"][0]["vary_by"] = {"series": ["nope"]}
    with pytest.raises(StudyError, match=r"laws\[0\]\.vary_by\.series: law 'coulomb_viscous' has no sampled"):
        study_from_raw(tmp_path / "s.toml", raw)
    raw["laws"][0]["vary_by"] = {"series": 3}
    with pytest.raises(StudyError, match="vary_by"):
        study_from_raw(tmp_path / "s.toml", raw)


# -- the program's sites, by hand ------------------------------------------------------------------
@pytest.mark.parametrize("rows, centred", [(20, True), (4, False)])
def test_levels_are_the_typical_value_scattered_on_the_log_scale(rows, centred):
    ds, _ = _runs(rows=rows)
    program = build_program(get_law("coulomb_viscous").vary_by("run", "T_C"), ds)
    assert program.groupings["run"].centred is centred
    level = "T_C_u" if centred else "T_C_z"
    assert set(program.density().sites) == {"T_C", "T_C_sd", level, "c_v", "sigma"}
    u = np.linspace(-1.0, 1.0, 6)
    values = {"T_C": 2.0, "T_C_sd": 0.2, "c_v": 1.0, "sigma": 0.05,
              level: np.log(2.0) + 0.2 * u if centred else u}
    tr = handlers.trace(handlers.substitute(program.model, data=values)).get_trace(**program.model_kwargs)
    expected = 2.0 * np.exp(0.2 * u)
    np.testing.assert_allclose(tr["T_C_run"]["value"], expected, rtol=1e-12)
    run = program.groupings["run"].index
    np.testing.assert_allclose(tr["response"]["fn"].loc, expected[run] + 1.0 * np.asarray(ds["velocity"]), rtol=1e-12)
    assert program.site_dims()[level] == ["run"]


def test_answers_for_a_new_level_scatter_by_the_spread_and_a_named_level_is_its_own():
    ds, _ = _runs()
    law = get_law("coulomb_viscous").vary_by("run", "T_C")
    program = build_program(law, ds).at({"velocity": np.array([0.0, 1.0])})
    assert program.groupings["run"].labels == (hierarchy.NEW_LEVEL,)
    s = 20000
    post = {"T_C": np.full(s, 2.0), "T_C_sd": np.full(s, 0.3), "c_v": np.full(s, 1.0), "sigma": np.full(s, 0.1),
            "T_C_run": np.tile([1.5, 2.5], (s, 1))}
    new = hierarchy.level_values(law, program.resolved, post, None, {"run": ("a", "b")}, np.random.default_rng(0))
    assert stats.kstest(np.log(new["T_C"] / 2.0) / 0.3, "norm").pvalue > 0.01
    named = hierarchy.level_values(law, program.resolved, post, "b", {"run": ("a", "b")}, np.random.default_rng(0))
    assert np.all(named["T_C"] == 2.5) and np.all(named["c_v"] == 1.0)
    with pytest.raises(KeyError, match="'c' is not a level of 'run'; levels: a, b"):
        hierarchy.level_values(law, program.resolved, post, "c", {"run": ("a", "b")}, np.random.default_rng(0))


def test_group_coverage_counts_rows_inside_the_central_bands_by_hand():
    from bayesfric.compare.heldout import HeldOut
    from bayesfric.compare.refit import group_coverage

    # one draw, unit noise: PIT = Φ(y − μ); rows at z = 0, 0.5, 1.0, 2.0 -> PIT 0.5, 0.69, 0.84, 0.977
    kept = HeldOut(np.arange(4), np.zeros(4, dtype=int), np.zeros((1, 4)), np.ones(4))
    shares = group_coverage(None, kept, np.array([0.0, 0.5, 1.0, 2.0]))
    assert shares == {"50": 0.5, "90": 0.75}


def test_joint_score_of_a_group_is_the_log_mean_of_the_product_by_hand():
    ds, _ = _runs(rows=3, runs=2)
    program = build_program(get_law("coulomb_viscous"), ds)
    samples = {"T_C": np.array([[1.9, 2.1]]), "c_v": np.array([[1.0, 1.1]]), "sigma": np.array([[0.1, 0.2]])}
    rows = np.asarray(ds["run"].values) == "r1"
    y, v = np.asarray(ds["torque"].values)[rows], np.asarray(ds["velocity"].values)[rows]
    draws = zip(*(samples[k][0] for k in ("T_C", "c_v", "sigma")), strict=True)
    per_draw = [stats.norm.logpdf(y, a + b * v, c).sum() for a, b, c in draws]
    assert joint_lpd(program, samples, rows) == pytest.approx(np.log(np.mean(np.exp(per_draw))), rel=1e-10)


# -- fits ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def hier_fit():
    ds, truth = _runs()
    law = get_law("coulomb_viscous").vary_by("run", "T_C", "c_v")
    return ds, truth, inference.fit(law, ds, chains=4, draws=1000, tune=1000, seed=3)


@pytest.mark.slow
def test_hierarchical_fit_recovers_each_run_and_reads_back(hier_fit, tmp_path):
    """Six SIMULATED runs (T_C, c_v spread 0.15 on the log scale, 20 rows each, noise 0.05 N·m):
    each run's 90 % interval covers its true value, and a saved fit rebuilds its program."""
    ds, truth, fit = hier_fit
    assert json.loads(fit.attrs["diagnostics"])["passed"]
    post = fit["posterior"]
    assert list(post["T_C_run"].coords["run"].values) == [f"r{i}" for i in range(6)]
    for p in ("T_C", "c_v"):
        lo, hi = (post[f"{p}_run"].quantile(q, dim=("chain", "draw")).values for q in (0.05, 0.95))
        assert np.mean((lo <= truth[p]) & (truth[p] <= hi)) >= 5 / 6, p
    path = inference.save_fit(fit, tmp_path / "fit.nc")
    _, program = bayesfric.load_fit(path)
    assert program.groupings["run"].labels == tuple(f"r{i}" for i in range(6))
    np.testing.assert_array_equal(program.groupings["run"].index, build_program(program.law, ds).groupings["run"].index)


@pytest.mark.slow
def test_sizing_answers_for_a_new_run_wider_than_for_a_named_one(hier_fit):
    from bayesfric.sizing.compute import predict

    ds, truth, fit = hier_fit
    grid = {"velocity": np.array([1.0, 3.0])}
    new, named = predict(fit, grid), predict(fit, grid, group="r2")
    width = {k: np.subtract(*np.quantile(d.mu.reshape(-1, 2), [0.95, 0.05], axis=0)) for k, d in
             (("new", new), ("named", named))}
    assert np.all(width["new"] > 2 * width["named"])
    true_r2 = truth["T_C"][2] + truth["c_v"][2] * grid["velocity"]
    lo, hi = np.quantile(named.mu.reshape(-1, 2), [0.005, 0.995], axis=0)
    assert np.all((lo <= true_r2) & (true_r2 <= hi))
    assert float(jnp.abs(np.median(new.mu.reshape(-1, 2)[:, 0]) - 3.0)) < 0.5  # typical run: T_C + c_v ≈ 3


@pytest.mark.slow
def test_predict_and_score_a_new_run_log(hier_fit):
    """A seventh SIMULATED run, never fitted: the new-run answer covers it; a named run's answer,
    pinned to another run's levels, is sharper but (on that run's own data) only right for it."""
    import bayesfric

    ds, _, fit = hier_fit
    new_log, truth = simulate_runs(get_law("coulomb_viscous"), {"velocity": np.linspace(0.1, 2.0, 20)}, TRUTH,
                                   {"T_C": 0.15, "c_v": 0.15}, runs=7, sigma=0.05, seed=1)
    seventh = new_log.isel(obs=np.asarray(new_log["run"].values) == "r6")
    pred = bayesfric.predict(fit, seventh)
    assert "new run" in pred.attrs["answer_for"]
    lo, hi = (pred["curve"].sel(quantile=q).values.reshape(-1) for q in (0.05, 0.95))
    curve = truth["T_C"][6] + truth["c_v"][6] * np.asarray(seventh["velocity"].values)
    assert np.mean((lo <= curve) & (curve <= hi)) >= 0.9
    scores = bayesfric.score(fit, ds, group="r2").set_index("metric")["value"]
    own = bayesfric.score(fit, ds.isel(obs=np.asarray(ds["run"].values) == "r2"), group="r2")
    assert own.set_index("metric")["value"]["coverage_90"] >= 0.8 > scores["coverage_90"]


def test_a_best_claim_counts_the_claimed_law_with_group_terms_as_the_same_form():
    import xarray as xr

    from bayesfric.study.claims import _form

    fits = {"cv": {"law": "coulomb_viscous", "law_recipe": ""},
            "cv_run": {"law": "cv_run",
                       "law_recipe": json.dumps({"base": "coulomb_viscous", "vary_by": {"run": ["T_C"]}})},
            "cv_off": {"law": "cv_off", "law_recipe": json.dumps({"base": "coulomb_viscous", "add": ["offset"]})}}
    tree = xr.DataTree.from_dict({f"fits/{k}": xr.Dataset(attrs=v) for k, v in fits.items()})
    assert _form(tree, "cv_run") == _form(tree, "cv") == {"base": "coulomb_viscous"}
    assert _form(tree, "cv_off") != _form(tree, "cv")
    assert _form(tree, "absent") == {"label": "absent"}


@pytest.mark.slow
def test_a_study_of_runs_ranks_the_hierarchical_law_first_by_leave_one_run_out(tmp_path):
    """Six SIMULATED runs through a whole study (Python API, a law given as a vary_by object): the
    study folds by run on its own, scores each held-out run's rows jointly, ranks the law with
    group terms first there, and its sizing says it answers for a new run."""
    import bayesfric

    ds, _ = _runs()
    rows = ["speed,torque,run"] + [f"{a:.10g},{b:.10g},{c}" for a, b, c in
                                   zip(ds["velocity"].values, ds["torque"].values, ds["run"].values, strict=True)]
    (tmp_path / "runs.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "runs.toml").write_text(
        '[dataset]\nname = "runs"\nprovenance = "simulated"\nsource = "test"\n'
        '[columns.speed]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n'
        '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n[columns.run]\nrole = "group"\n')
    by_run = bayesfric.law("coulomb_viscous").vary_by("run", "T_C", "c_v")
    study = bayesfric.Study("runs", tmp_path / "runs.csv", laws=["coulomb_viscous", by_run],
                            sampler={"draws": 500, "tune": 500, "chains": 4},
                            compare={"evidence": False}, sizing=[{"at": {"velocity": "2..3 rad/s"}}])
    assert study.grouped == "run"
    result = bayesfric.run(study, tmp_path / "reports")
    scores = result.scores
    logo = scores[(scores.metric == "elpd_cv") & scores.scheme.str.contains("run")].set_index("law")
    hier = next(i for i in logo.index if i != "coulomb_viscous")
    assert logo.loc[hier, "estimate"] - logo.loc["coulomb_viscous", "estimate"] > 3 * logo.loc[hier, "se"]
    summary = (tmp_path / "reports" / "runs" / "summary.md").read_text()
    # the recommendation leads with what it is for a new run (the runs were flagged), then the tested ones
    recommendation = next(line for line in summary.splitlines() if line.startswith("**") and "Recommended:" in line)
    assert recommendation.startswith(f"**For a NEW 'run' (the default question of sizing, predict and score): use "
                                     f"**{hier.replace('_', chr(92) + '_')}**")
    assert "answers for a NEW run" in recommendation  # said where the decision is, not only under Sizing
    checked = next(line for line in summary.splitlines() if "Answers for a new group" in line)
    diag = result.tree["diagnostics"].to_dataset()
    assert 0.75 <= float(diag["group_coverage_90"].sel(law=hier)) <= 1.0
    assert f"{hier.replace('_', chr(92) + '_')} {float(diag['group_coverage_90'].sel(law=hier)):.0%}" in checked
    # inside the tested speeds, the new-run answer is weighed by how well each law predicted a run it had not seen
    assert set(result.sizing["basis"]) == {"stacking leave-one-group-out"}
    weights = result.tree["weights"].to_dataset()["weight"].sel(law=hier)
    assert float(weights.sel(weighting=next(w for w in weights["weighting"].values if "run" in str(w)))) > 0.5
    # the report's band figure adds, for the law with group terms, where a NEW run may lie: wider than the tested runs'
    from bayesfric.report.study_figures import _band, _new_group_band

    data = bayesfric.load_data(tmp_path / "runs.csv")
    axis = next(k for k, v in data.coords.items() if v.attrs.get("role") == "input")
    grid, lo, hi = _new_group_band(data, "torque", result.fits[hier], axis, data[axis].values)
    tested = _band(data, "torque", result.fits[hier])
    top = np.argmax(data[axis].values)
    assert hi[-1] - lo[-1] > 1.5 * (tested[2][top] - tested[0][top])
    assert _new_group_band(data, "torque", result.fits["coulomb_viscous"], axis, data[axis].values) is None
