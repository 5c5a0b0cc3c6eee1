"""What `bayesfric.size` returns: one tidy Dataset (law × point × quantile) with `.to_dataframe()` and
`q(p)` at any level from the kept draws; sizing.csv renders it; a fit in memory and the same fit saved
and read back in a fresh process answer bit for bit; a fit's diagnostics come back as a dict."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bayesfric
from bayesfric import sizing
from bayesfric.errors import UserError
from bayesfric.inference import save_fit
from bayesfric.sizing import make_question
from tests.sizing_helpers import hand_fit

REPO = Path(__file__).resolve().parents[1]
C, D = 2, 300
TESTED = {"velocity": np.linspace(0.1, 2.0, 10)}
AT = {"velocity": (0.5, 3, "rad/s")}


@pytest.fixture(scope="module")
def fit():
    """coulomb_viscous with scattered draws: a float32 evaluation would change every number."""
    rng = np.random.default_rng(7)
    draws = {"T_C": 5.123 + 0.1 * rng.normal(size=(C, D)), "c_v": 2.0417 + 0.05 * rng.normal(size=(C, D)),
             "sigma": 0.2 + 0.01 * rng.random(size=(C, D))}
    return hand_fit("coulomb_viscous", draws, TESTED)


@pytest.fixture(scope="module")
def two_laws():
    """Two hand-made fits averaged by their LOO weights 0.3 / 0.7."""
    rng = np.random.default_rng(3)
    a = hand_fit("coulomb_viscous", {"T_C": 5 + 0.2 * rng.normal(size=(C, D)), "c_v": 2 + 0.1 * rng.normal(size=(C, D)),
                                     "sigma": np.full((C, D), 0.3)}, TESTED)
    b = hand_fit("coulomb", {"T_C": 9 + 0.4 * rng.normal(size=(C, D)), "sigma": np.full((C, D), 0.3)}, TESTED)
    sources = [sizing.LawSource("coulomb_viscous", a, {sizing.LOO: 0.3}),
               sizing.LawSource("coulomb", b, {sizing.LOO: 0.7})]
    question = sizing.check_question(make_question({"velocity": "3 rad/s"}, 0.95, capacity="11 N*m"), ["velocity"],
                                     ["velocity"], "torque")
    answer = sizing.answer.answer([question], sources, TESTED, response="torque", response_unit="N*m",
                                  response_scale=1.0, provenance="simulated", source="test", seed=1, fan=False)
    return answer, (a, b)


KEPT = ("required", "p_exceed", "p_exceed_se", "mean_fn", "noisy", "var_param", "var_noise")


def test_a_saved_fit_read_back_in_a_fresh_process_answers_bit_for_bit(fit, tmp_path):
    path = save_fit(fit, tmp_path / "fit.nc")
    here = bayesfric.size(fit, at=AT, capacity=(12, "N*m"))
    # a fresh process: nothing has turned JAX's x64 on before the fit is read (it ran in float32)
    code = ("import sys, numpy as np, bayesfric\n"
            f"r = bayesfric.size(sys.argv[1], at={AT!r}, capacity=(12, 'N*m'))\n"
            f"np.savez(sys.argv[2], **{{k: r.dataset[k].values for k in {KEPT!r}}})\n")
    run = subprocess.run([sys.executable, "-c", code, str(path), str(tmp_path / "there.npz")], cwd=REPO,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    there = np.load(tmp_path / "there.npz")
    read_here = bayesfric.size(path, at=AT, capacity=(12, "N*m"))
    for k in KEPT:
        np.testing.assert_array_equal(here.dataset[k].values, there[k], err_msg=k)
        np.testing.assert_array_equal(here.dataset[k].values, read_here.dataset[k].values, err_msg=k)


def test_q_of_a_law_is_the_quantile_of_its_mean_function_draws(fit):
    result = bayesfric.size(fit, at={"velocity": (3, "rad/s")}, confidence=0.9)
    post = fit["posterior"]
    by_hand = np.quantile(np.abs(post["T_C"].values + 3.0 * post["c_v"].values).ravel(), 0.8)
    assert result.q(0.8, of="mean_fn").sel(law="coulomb_viscous", point=0).item() == pytest.approx(by_hand, rel=1e-12)
    ds = result.dataset.sel(law="coulomb_viscous")
    np.testing.assert_array_equal(result.q(0.9).sel(law="coulomb_viscous").values, ds["required"].values)
    for level in (0.05, 0.5, 0.95):
        for of in ("mean_fn", "noisy"):
            np.testing.assert_array_equal(result.q(level, of=of).sel(law="coulomb_viscous").values,
                                          ds[of].sel(quantile=level).values)
    assert np.isnan(result.q(0.9).sel(law="average").values).all()  # one fit: no average, and it says so
    assert result["single_fit"].values.all() and result["basis_note"].values[0].startswith("One fit: no model average")


def test_q_of_the_average_inverts_the_weighted_cdf_of_both_laws_draws(two_laws):
    result, (a, b) = two_laws
    mean_fn = [np.abs(f["posterior"]["T_C"].values.ravel() + (3.0 * f["posterior"]["c_v"].values.ravel()
                                                             if "c_v" in f["posterior"] else 0.0)) for f in (a, b)]
    values = np.concatenate(mean_fn)
    weights = np.concatenate([np.full(C * D, 0.3 / (C * D)), np.full(C * D, 0.7 / (C * D))])
    order = np.argsort(values, kind="stable")
    cdf = np.cumsum(weights[order])
    for level in (0.2, 0.5, 0.975):
        by_hand = values[order][np.searchsorted(cdf, level - 1e-12)]
        assert result.q(level, of="mean_fn").sel(law="average", point=0).item() == pytest.approx(by_hand, rel=1e-12)
    ds = result.dataset
    assert ds["mix_weight"].sel(law="average", component=["coulomb_viscous", "coulomb"]).values[:, 0] == \
        pytest.approx([0.3, 0.7])
    np.testing.assert_array_equal(result.q(0.95).values, ds["required"].values)  # q(confidence) is `required`
    np.testing.assert_array_equal(result.q(0.5).values, ds["noisy"].sel(quantile=0.5).values)


def test_to_dataframe_has_one_row_per_law_and_point_and_renders_sizing_csv(two_laws):
    from bayesfric.report.sizing import records

    result, _ = two_laws
    frame = result.to_dataframe()
    assert len(frame) == 4  # two laws and two averages (basis and LOO: the same weights here) at one point
    assert list(frame["role"]) == ["law", "law", "average", "average LOO"]
    for column in ("question", "point", "velocity", "distance_velocity", "law", "required", "p_exceed", "p_exceed_se",
                   "noisy_q95", "mean_fn_q5", "calibrated_required", "weight_used", "var_between", "warnings"):
        assert column in frame.columns, column
    assert not any(c.startswith(("draws_", "calibrated_draws_")) or c == "mix_weight" for c in frame.columns)
    rows = records(result)  # sizing.csv: the same numbers, rendered
    assert [r["law"] for r in rows] == list(frame["name"])
    np.testing.assert_array_equal([r["required"] for r in rows], frame["required"].to_numpy())
    np.testing.assert_array_equal([r["noisy_q95"] for r in rows], frame["noisy_q95"].to_numpy())


def test_the_dataset_says_what_the_answer_is_for_and_saves_as_netcdf(two_laws, tmp_path):
    import xarray as xr

    result, _ = two_laws
    attrs = result.dataset.attrs
    assert attrs["unit"] == "N*m" and "magnitudes |T|" in attrs["magnitudes"] and "Monte Carlo" in attrs["approximate"]
    assert "no group terms" in attrs["answers_for"]
    text = result["p_exceed_text"].sel(law="coulomb_viscous", point=0).item()
    p, se = (float(result[k].sel(law="coulomb_viscous", point=0)) for k in ("p_exceed", "p_exceed_se"))
    assert text == f"{p:.3g} ± {se:.2g}" if 0 < p < 1 else text.endswith("exceeds)")
    result.dataset.to_netcdf(tmp_path / "s.nc", engine="h5netcdf")
    back = xr.open_dataset(tmp_path / "s.nc", engine="h5netcdf").load()
    np.testing.assert_array_equal(back["required"].values, result.dataset["required"].values)


@pytest.mark.parametrize("p", [0, 1, 0.0, 1.0, -0.1, 1.5, math.nan, math.inf, True, "0.9", None])
def test_q_outside_zero_one_is_a_user_error(fit, p):
    result = bayesfric.size(fit, at={"velocity": (3, "rad/s")})
    with pytest.raises(UserError, match=r"^p: a quantile level must be a number in \(0, 1\)"):
        result.q(p)


def test_a_level_the_structured_answer_did_not_keep_names_the_levels_it_kept(fit):
    (law,) = bayesfric.size(fit, at={"velocity": (3, "rad/s")}, confidence=0.9).answers[0].laws
    with pytest.raises(UserError, match=r"level: 0\.8 is not one of the kept levels \(0\.05, 0\.5, 0\.9, 0\.95\)"):
        law.noisy.q(0.8)


def test_q_of_an_unknown_kind_is_a_user_error(fit):
    with pytest.raises(UserError, match="of: must be one of noisy, mean_fn"):
        bayesfric.size(fit, at={"velocity": (3, "rad/s")}).q(0.9, of="median")


def test_diagnostics_come_back_as_a_dict_in_memory_and_from_the_file(fit, tmp_path):
    d = bayesfric.diagnostics(fit)
    assert isinstance(d, dict) and d["passed"] is True and d["problems"] == [] and d["rhat_max"] == 1.0
    assert bayesfric.diagnostics(save_fit(fit, tmp_path / "fit.nc")) == d
    with pytest.raises(UserError, match="fit: expected a fit"):
        bayesfric.diagnostics({"diagnostics": "{}"})
