"""Trends over a service coordinate (bayesfric.trend): declaration, the levels' values by hand for
each form, forecasts for a new campaign, leave-future-out folds, crossing times by hand, and a
fit's time to exceed on SIMULATED campaigns (its calibration over 120 replicates is
benchmarks/bench_trend_forecast.py)."""

from __future__ import annotations

import numpy as np
import pytest
from numpyro import handlers

import bayesfric
from bayesfric import compare, hierarchy, inference
from bayesfric.datasets.synthetic import simulate_campaigns
from bayesfric.errors import DataError
from bayesfric.laws import get_law
from bayesfric.laws.variants import VariantError, describe
from bayesfric.model import build_program
from bayesfric.sizing.exceed import crossing_times, parse_horizon, time_to_exceed
from bayesfric.sizing.points import SizingError
from bayesfric.study.config import StudyError, study_from_raw

SPEEDS = np.linspace(0.1, 2.0, 10)
HOURS = [0, 500, 1000, 1500, 2000, 2500, 3000]


def truth(t):
    return 2.0 * (1 + t / 6000.0)


def _campaigns(hours=HOURS, rows=SPEEDS, seed=1, scatter=0.03):
    return simulate_campaigns(get_law("coulomb_viscous"), {"velocity": rows}, {"T_C": truth, "c_v": 1.0}, hours,
                              {"T_C": scatter}, sigma=0.05, seed=seed)


# -- declaration ----------------------------------------------------------------------------------
def test_trend_records_a_recipe_and_says_so():
    law = get_law("coulomb_viscous").trend("hours", "T_C", form="loglinear")
    assert law.name == "coulomb_viscous_trend_hours"
    assert law.trending == {"T_C": "hours"} and law.varying == {"T_C": "hours"} and law.trend_form == "loglinear"
    assert "T_C follow a loglinear trend over hours" in describe(law)
    assert get_law("coulomb_viscous").trend("hours", "T_C").trend_form == "linear"


@pytest.mark.parametrize("make, problem", [
    (lambda: get_law("coulomb_viscous").trend("hours", "T_C", form="cubic"), "trend_form 'cubic'"),
    (lambda: get_law("coulomb_viscous").trend("hours", "nope"), "no sampled parameter 'nope'"),
    (lambda: get_law("coulomb_viscous").vary_by("run", "T_C").trend("hours", "T_C"), "varies by both"),
    (lambda: get_law("coulomb_viscous").vary_by("hours", "c_v").trend("hours", "T_C"), "both a group and a trend"),
    (lambda: get_law("dahl").vary_by("run", "F_c0").trend("hours", "gamma"), "one group column"),
])
def test_trend_refuses_what_cannot_trend(make, problem):
    with pytest.raises(VariantError, match=problem):
        make()


def test_a_trend_column_must_hold_numbers():
    ds, _ = _campaigns()
    ds = ds.assign_coords(hours=("obs", np.where(ds["hours"].values == "0", "new", ds["hours"].values),
                                 ds["hours"].attrs))
    with pytest.raises(DataError, match="follows a trend over 'hours'.*'new' is not a number"):
        build_program(get_law("coulomb_viscous").trend("hours", "T_C"), ds)


def test_levels_are_in_numeric_order():
    ds, _ = _campaigns(hours=[0, 500, 1000, 2500, 10000])
    program = build_program(get_law("coulomb_viscous").trend("hours", "T_C"), ds)
    assert program.groupings["hours"].labels == ("0", "500", "1000", "2500", "10000")
    assert list(np.unique(program.groupings["hours"].index[::10])) == [0, 1, 2, 3, 4]


# -- the levels by hand ---------------------------------------------------------------------------
def _trace(law, ds, values):
    program = build_program(law, ds)
    with handlers.trace() as tr, handlers.seed(rng_seed=0), handlers.substitute(data=values):
        program.model(**program.model_kwargs)
    return {k: np.asarray(v["value"]) for k, v in tr.items()}, program


@pytest.mark.parametrize("form", ["linear", "loglinear"])
def test_a_trend_level_is_the_trend_scattered_on_the_log_scale(form):
    ds, _ = _campaigns(rows=np.linspace(0.1, 2, 4))  # 4 rows a campaign: non-centred
    law = get_law("coulomb_viscous").trend("hours", "T_C", form=form)
    z = np.linspace(-1, 1, 7)
    sites, program = _trace(law, ds, {"T_C": 2.0, "T_C_trend": 0.5, "T_C_sd": 0.1, "T_C_z": z, "c_v": 1.0})
    tau = np.asarray(HOURS) / 3000.0
    mid = np.log(2.0 * (1 + 0.5 * tau)) if form == "linear" else np.log(2.0) + 0.5 * tau
    np.testing.assert_allclose(sites["T_C_hours"], np.exp(mid + 0.1 * z), rtol=1e-10)
    assert program.priors["T_C_trend"].dist == "Normal"


def test_a_linear_trend_is_floored_where_it_falls_below_zero():
    ds, _ = _campaigns(rows=np.linspace(0.1, 2, 4))
    law = get_law("coulomb_viscous").trend("hours", "T_C")
    sites, _ = _trace(law, ds, {"T_C": 2.0, "T_C_trend": -2.0, "T_C_sd": 0.1, "T_C_z": np.zeros(7), "c_v": 1.0})
    np.testing.assert_allclose(sites["T_C_hours"][-1], 2.0 * 1e-3)  # 1 - 2 * 1 < 0: the floor
    np.testing.assert_allclose(sites["T_C_hours"][1], 2.0 * (1 - 2.0 / 6))


def test_a_walk_adds_increments_with_the_square_root_of_the_elapsed_span():
    ds, _ = _campaigns(hours=[0, 1000, 4000], rows=np.linspace(0.1, 2, 4))
    law = get_law("coulomb_viscous").trend("hours", "T_C", form="walk")
    z = np.array([0.3, 1.0, -1.0])
    sites, program = _trace(law, ds, {"T_C": 2.0, "T_C_sd": 0.2, "T_C_z": z, "c_v": 1.0})
    expected = np.log(2.0) + 0.2 * np.cumsum(np.sqrt([0.0, 0.25, 0.75]) * z)
    np.testing.assert_allclose(np.log(sites["T_C_hours"]), expected, rtol=1e-10)
    assert "T_C_trend" not in program.priors


def test_a_centred_walk_samples_its_increments():
    ds, _ = _campaigns(hours=[0, 1000, 4000])  # 10 rows a campaign: centred
    law = get_law("coulomb_viscous").trend("hours", "T_C", form="walk")
    w = np.log([2.2 / 2.0, 2.5 / 2.2])
    sites, program = _trace(law, ds, {"T_C": 2.0, "T_C_sd": 0.2, "T_C_w": w, "c_v": 1.0})
    np.testing.assert_allclose(sites["T_C_hours"], [2.0, 2.2, 2.5], rtol=1e-10)
    assert program.site_dims()["T_C_w"] == ["hours_step"]


@pytest.mark.parametrize("form", ["linear", "walk"])
def test_a_level_a_fold_holds_out_is_sampled_non_centred(form):
    """Its data out of the fold's training rows (``seen``), a centred column's level holds a
    standard-normal draw: no funnel; the engine passes each fold's mask as ``seen``."""
    ds, _ = _campaigns(hours=[0, 1000, 4000])
    law = get_law("coulomb_viscous").trend("hours", "T_C", form=form)
    program = build_program(law, ds)
    mask = ds["hours"].values != "4000"
    level = "T_C_w" if form == "walk" else "T_C_u"
    values = {"T_C": 2.0, "T_C_trend": 0.0, "T_C_sd": 0.2, "c_v": 1.0,
              level: np.array([0.1, 1.0]) if form == "walk" else np.array([np.log(2.0), np.log(2.1), 1.0])}
    with handlers.trace() as tr, handlers.seed(rng_seed=0), handlers.substitute(data=values):
        program.model(**program.model_kwargs, mask=mask, seen=mask)
    got = np.asarray(tr["T_C_hours"]["value"])
    if form == "walk":  # the step to 4000 h: sd · sqrt(Δτ) · 1.0, Δτ = 3000 / 4000
        start = np.log(2.0)
        np.testing.assert_allclose(np.log(got), [start, start + 0.1, start + 0.1 + 0.2 * np.sqrt(0.75)])
    else:
        np.testing.assert_allclose(np.log(got), [np.log(2.0), np.log(2.1), np.log(2.0) + 0.2 * 1.0])


# -- forecasts --------------------------------------------------------------------------------------
def test_a_forecast_follows_the_trend_and_the_typical_campaign_has_no_scatter():
    law = get_law("coulomb_viscous").trend("hours", "T_C")
    ds, _ = _campaigns()
    program = build_program(law, ds).at({"velocity": np.array([0.0])})
    s = 4000
    post = {"T_C": np.full(s, 2.0), "T_C_trend": np.full(s, 0.5), "T_C_sd": np.full(s, 0.1), "c_v": np.ones(s),
            "T_C_hours": np.full((s, 7), 2.0), "sigma": np.full(s, 0.05)}
    labels = {"hours": tuple(str(h) for h in HOURS)}
    typical = hierarchy.level_values(law, program.resolved, post, None, labels, np.random.default_rng(0),
                                     {"hours": 6000.0}, scatter=False)
    np.testing.assert_allclose(typical["T_C"], 2.0 * (1 + 0.5 * 2.0))
    new = hierarchy.level_values(law, program.resolved, post, None, labels, np.random.default_rng(0),
                                 {"hours": 6000.0})
    assert np.std(np.log(new["T_C"])) == pytest.approx(0.1, rel=0.05)
    last = hierarchy.level_values(law, program.resolved, post, None, labels, np.random.default_rng(0), scatter=False)
    np.testing.assert_allclose(last["T_C"], 2.0 * 1.5)  # default: at the last fitted campaign


# -- leave-future-out ---------------------------------------------------------------------------------
def test_forecast_folds_train_on_the_past_and_score_the_next_campaign():
    ds, _ = _campaigns(hours=[0, 500, 1000, 10000])
    folds = compare.forecast_masks(ds, "hours", first=2)
    assert folds.labels == ["hours=1000", "hours=10000"]
    hours = ds["hours"].values.astype(float)
    np.testing.assert_array_equal(folds.train[0], hours < 1000)
    np.testing.assert_array_equal(folds.heldout[1], hours == 10000)
    assert not (folds.train[1] & (hours == 10000)).any()
    with pytest.raises(DataError, match="needs more than 4"):
        compare.forecast_masks(ds, "hours", first=4)


def test_a_study_takes_a_trend_and_forecasts_along_it(tmp_path):
    raw = {"study": {"name": "t"}, "data": {"dataset": "drum_campaigns"},
           "laws": [{"name": "coastdown_oring_closed_form", "trend": {"hours": ["T_C"]}, "trend_form": "walk"}]}
    study = study_from_raw(tmp_path / "t.toml", raw)
    assert study.forecast == "hours" and study.laws[0].build().trend_form == "walk"
    raw["laws"][0]["trend_form"] = "cubic"
    with pytest.raises(StudyError, match="trend_form"):
        study_from_raw(tmp_path / "t.toml", raw)


# -- time to exceed ---------------------------------------------------------------------------------
def test_crossing_times_by_hand():
    curves = np.array([[1.0, 2.0, 3.0], [1.0, 1.0, 1.0], [4.0, 5.0, 6.0], [-1.0, -2.0, -3.0]])
    np.testing.assert_allclose(crossing_times(curves, np.array([0.0, 10.0, 20.0]), 2.5), [15.0, np.inf, 0.0, 15.0])


def test_horizon_in_the_coordinates_unit():
    assert parse_horizon("2 kh", "h") == pytest.approx(2000.0)
    assert parse_horizon(500) == 500.0
    for bad in ("soon", "-5 h", "3 m"):
        with pytest.raises(SizingError, match="horizon"):
            parse_horizon(bad, "h")


@pytest.fixture(scope="module")
def trend_fit():
    ds, _ = _campaigns()
    return inference.fit(get_law("coulomb_viscous").trend("hours", "T_C"), ds, draws=500, tune=500, chains=4, seed=0)


def test_time_to_exceed_covers_the_true_crossing(trend_fit):
    assert inference.verdict_of(trend_fit).passed
    out = time_to_exceed(trend_fit, {"velocity": "1 rad/s"}, "5 N*m", "20000 h", unit="h")
    lo, hi = out["crossing_q"].sel(quantile=[0.05, 0.95]).values
    assert lo < 6000.0 < hi and hi - lo < 4000.0  # the truth's crossing; the band is informative
    assert np.all(np.diff(out["p_exceed"].values) >= 0) and out["p_exceed"].values[0] == 0.0
    assert (out["fan_new"].sel(quantile=0.95) >= out["fan"].sel(quantile=0.95) - 1e-9).all()
    assert out.attrs["form"] == "linear" and "typical campaign" in out.attrs["curve"]
    assert out.sizes["campaign"] == 7


def test_time_to_exceed_refuses_a_law_without_trend_and_a_horizon_in_the_past(trend_fit):
    with pytest.raises(SizingError, match="horizon"):
        time_to_exceed(trend_fit, {"velocity": 1.0}, 5.0, 2000.0)
    ds, _ = _campaigns()
    plain = inference.fit(get_law("coulomb_viscous"), ds, draws=100, tune=100, chains=1, seed=0)
    with pytest.raises(SizingError, match="follows no trend"):
        time_to_exceed(plain, {"velocity": 1.0}, 5.0, 9000.0)


def test_a_saved_trend_fit_forecasts_the_same(trend_fit, tmp_path):
    again, program = bayesfric.load_fit(inference.save_fit(trend_fit, tmp_path / "fit.nc"))
    assert program.law.trending == {"T_C": "hours"}
    a = time_to_exceed(trend_fit, {"velocity": 1.0}, 5.0, 20000.0)
    b = time_to_exceed(again, {"velocity": 1.0}, 5.0, 20000.0)
    np.testing.assert_array_equal(a["crossing"].values, b["crossing"].values)


def test_the_api_and_the_cli_answer_the_same_time_to_exceed(trend_fit, tmp_path, capsys):
    import bayesfric
    from bayesfric.cli import main
    from bayesfric.report.service import text

    path = inference.save_fit(trend_fit, tmp_path / "fit.nc")
    out = bayesfric.time_to_exceed(trend_fit, {"velocity": "1 rad/s"}, capacity="5 N*m", horizon="20 kh", unit="h")
    assert out.attrs["horizon"] == 20000.0 and "curve" not in out
    assert main(["size", str(path), "--at", "velocity=1 rad/s", "--capacity", "5 N*m", "--horizon", "20000 h"]) == 0
    printed = capsys.readouterr().out
    again = bayesfric.time_to_exceed(path, "velocity=1 rad/s", capacity="5 N*m", horizon="20000 h")
    assert printed == text(again) + "\n"
    assert "90 % interval" in printed and "typical campaign" in printed
    assert main(["size", str(path), "--at", "velocity=1 rad/s", "--horizon", "20000 h"]) == 2
    assert "--capacity: required with --horizon" in capsys.readouterr().err


def test_a_forecast_fold_reads_its_held_out_campaign_as_its_sampler_did():
    """The engine's constrained draws and lpd of a leave-future-out fold use the fold's own
    parametrisation: the held-out campaign's forecast lies about the trend, not at a standard
    normal (a forecast of T_C about exp(N(0, 1)) would be the bug this guards against)."""
    from bayesfric.inference.engine import NutsEngine

    ds, truth_values = _campaigns()
    program = build_program(get_law("coulomb_viscous").trend("hours", "T_C"), ds)
    hours = ds["hours"].values.astype(float)
    fold = NutsEngine.build(program, draws=300, tune=300, chains=2, seed=0).run((hours < 3000)[None], seed=0)
    forecast = fold.samples["T_C_hours"][0].reshape(-1, 7)[:, 6]
    assert np.quantile(forecast, 0.05) > 2.5 and np.quantile(forecast, 0.95) < 3.6  # truth at 3000 h: 3.0
    assert np.quantile(forecast, 0.05) < truth_values["T_C"][6] < np.quantile(forecast, 0.95)


def test_a_model_average_is_the_weighted_mixture(trend_fit):
    from bayesfric.sizing.exceed import combine

    one = time_to_exceed(trend_fit, {"velocity": 1.0}, 5.0, 20000.0, seed=1)
    two = time_to_exceed(trend_fit, {"velocity": 3.0}, 7.0, 20000.0, seed=2)  # 2 N*m above: a separate mode
    mix = combine({"one": one, "two": two}, {"one": 0.25, "two": 0.75})
    np.testing.assert_allclose(mix["p_exceed"], 0.25 * one["p_exceed"] + 0.75 * two["p_exceed"])
    share = np.mean(np.isin(mix["crossing"].values, one["crossing"].values))
    assert abs(share - 0.25) < 0.05  # draws in proportion to the weights
    pooled = np.abs(np.concatenate([one["curve_new"].values, two["curve_new"].values]))
    weights = np.concatenate([np.full(one.sizes["draw"], 0.25 / one.sizes["draw"]),
                              np.full(two.sizes["draw"], 0.75 / two.sizes["draw"])])
    from bayesfric.sizing.compute import weighted_quantiles

    exact = weighted_quantiles(pooled, weights, (0.05, 0.95))
    for q in (0.05, 0.95):  # the resampled mixture's quantiles, within Monte Carlo error of the exact ones
        gap = np.abs(mix["fan_new"].sel(quantile=q).values - exact[q]) / exact[q]
        averaged = 0.25 * one["fan_new"].sel(quantile=q).values + 0.75 * two["fan_new"].sel(quantile=q).values
        off = np.abs(averaged - exact[q]) / exact[q]  # averaging the quantiles instead
        assert np.median(gap) < 0.03 and np.median(gap) < 0.5 * np.median(off)


def test_a_measured_forecast_miss_widens_the_time_to_exceed_and_keeps_the_trends_own(trend_fit):
    from bayesfric.sizing.calibration import Miss
    from bayesfric.sizing.forecast import allowance

    plain = time_to_exceed(trend_fit, {"velocity": 1.0}, 5.0, 20000.0)
    assert plain.attrs["allowance"].startswith("none:")
    zero = time_to_exceed(trend_fit, {"velocity": 1.0}, 5.0, 20000.0, miss=Miss("lfo", 0.0, 1e-10, 1e-9, 20, 0.2))
    np.testing.assert_array_equal(zero["crossing"], plain["crossing"])  # a zero rate changes nothing
    assert zero.attrs["allowance"].startswith("measured, zero")
    miss = Miss("lfo", 3e-9, 3e-9, 0.0, 20, 0.2)
    wide = time_to_exceed(trend_fit, {"velocity": 1.0}, 5.0, 20000.0, miss=miss)
    np.testing.assert_array_equal(wide["crossing_within"], plain["crossing"])
    np.testing.assert_allclose(wide["allowance"], allowance(miss, wide["service"].values, first=0.0, last=3000.0))

    def width(out, name="crossing_q"):
        return float(out[name].sel(quantile=0.95) - out[name].sel(quantile=0.05))

    assert width(wide) > 1.2 * width(plain) and width(wide, "crossing_within_q") == width(plain)
    assert "relative sd" in wide.attrs["allowance"]


# -- the shape check: accelerating wear against a linear trend ----------------------------------------
@pytest.fixture(scope="module")
def accelerating_fit():
    """Wear accelerating as 2 (1 + (t/6000)²), a linear trend fitted: the campaigns bend upward
    (scatter 1 %: the curvature stands 5 standard errors out), the truth crosses at 6000 h."""
    ds, _ = simulate_campaigns(get_law("coulomb_viscous"), {"velocity": SPEEDS},
                               {"T_C": lambda t: 2.0 * (1 + (t / 6000.0) ** 2), "c_v": 1.0}, HOURS, {"T_C": 0.01},
                               sigma=0.05, seed=1)
    return inference.fit(get_law("coulomb_viscous").trend("hours", "T_C"), ds, draws=500, tune=500, chains=4, seed=0)


def test_a_time_to_exceed_says_first_that_the_campaigns_bend_upward(accelerating_fit, trend_fit):
    from types import SimpleNamespace

    import xarray as xr

    from bayesfric.compare.trendfit import trend_bends
    from bayesfric.report.service import headlines, sections, text
    from bayesfric.sizing.exceed import answer_study

    out = time_to_exceed(accelerating_fit, {"velocity": 1.0}, 5.0, 20000.0, unit="h")
    assert out.attrs["bend"] == "upward" and out.attrs["shape_calibrated"] == 0
    assert float(out["crossing_q"].sel(quantile=0.05)) > 6000.0  # the miss it warns of: the truth comes sooner
    assert text(out.drop_vars(["curve", "curve_new"])).startswith("WARNING: The campaign levels bend upward")
    assert trend_bends(accelerating_fit)["T_C"].direction == "upward"  # on T_C's log scale too
    plain = time_to_exceed(trend_fit, {"velocity": 1.0}, 5.0, 20000.0)  # linear truth: no statement
    assert plain.attrs["bend"] == "none" and plain.attrs["statement"] == "" and plain.attrs["shape_calibrated"] == 1
    q = SimpleNamespace(at={"velocity": SimpleNamespace(lo=1.0)}, capacity=SimpleNamespace(lo=5.0, text="5 N*m"),
                        horizon="20000 h", label="drive", describe=lambda: "velocity 1 rad/s")
    weights = xr.Dataset({"weight": (("weighting", "law"), [[1.0]])},
                         coords={"weighting": ["stacking leave-future-out"], "law": ["acc"]})
    node = answer_study([q], {"acc": accelerating_fit}, xr.DataTree.from_dict({"weights": weights}), unit="h")
    assert node["q0"].attrs["shape_calibrated"] == 0 and "In every law carrying" in node["q0"].attrs["statement"]
    head = headlines(node)[0]
    assert head.warning and head.text.index("bend upward") < head.text.index("median")
    assert sections(node)[0].lines[0] == node["q0"].attrs["statement"]
