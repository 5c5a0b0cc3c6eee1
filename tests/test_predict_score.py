"""``bayesfric predict`` / ``score`` and ``bayesfric.predict`` / ``score`` (issue 47 item 5).

Every number is checked against a hand computation on fits made by hand (known posterior draws,
no sampling, :func:`tests.sizing_helpers.hand_fit`): the mean curve's mean and quantiles, the noisy
predictive's quantiles (the mixture of the draws' normals inverted with ``scipy.optimize.brentq``),
the elpd (``log`` of the mean over draws of ``scipy.stats`` densities), the RMS error and the
coverage counts; the model average against a hand-weighted mixture; a stateful law (Dahl) along a
new log's two trajectories against the law evaluated directly; and the CLI's one-line errors.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from scipy import optimize, stats

from bayesfric.api.predicting import predict, predictions_table, score
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.errors import DataError, UserError
from bayesfric.inference import save_fit
from bayesfric.model import Noise
from tests.hostile.harness import assert_user_error, run_cli
from tests.sizing_helpers import hand_fit, write_basis

TESTED = {"velocity": np.linspace(0.1, 2.0, 6)}
CV = {"T_C": np.array([[1.0, 1.2]]), "c_v": np.array([[0.5, 0.7]]), "sigma": np.array([[0.1, 0.2]])}
V = np.array([0.5, 1.0, 3.0, -1.0, 2.0])
Y = np.array([1.35, 2.6, 2.9, -1.38, 2.45])


def _mixture_quantile(locs, sds, weights, level):
    def cdf(y):
        return sum(w * stats.norm.cdf(y, m, s) for m, s, w in zip(locs, sds, weights, strict=True)) - level

    return optimize.brentq(cdf, min(locs) - 20 * max(sds), max(locs) + 20 * max(sds), xtol=1e-13)


def _hand(locs, sds, weights, y):
    """(elpd_i, PIT_i) of one row by hand."""
    dens = sum(w * stats.norm.pdf(y, m, s) for m, s, w in zip(locs, sds, weights, strict=True))
    return np.log(dens), sum(w * stats.norm.cdf(y, m, s) for m, s, w in zip(locs, sds, weights, strict=True))


def test_one_fit_matches_the_hand_computation():
    fit = hand_fit("coulomb_viscous", CV, TESTED)
    ds = make_dataset({"velocity": V}, Y)
    mu = np.array([1.0 * np.sign(V) + 0.5 * V, 1.2 * np.sign(V) + 0.7 * V])  # the two draws' mean curves
    pred = predict(fit, ds, quantiles=[0.05, 0.5, 0.95])
    np.testing.assert_allclose(pred["mean"].sel(law="coulomb_viscous"), mu.mean(axis=0), rtol=1e-12)
    # the mean curve's quantiles invert the draws' empirical CDF (each draw 1/2): the lower draw up to 0.5
    curve = pred["curve"].sel(law="coulomb_viscous")
    np.testing.assert_allclose(curve.sel(quantile=0.05), mu.min(axis=0))
    np.testing.assert_allclose(curve.sel(quantile=0.5), mu.min(axis=0))
    np.testing.assert_allclose(curve.sel(quantile=0.95), mu.max(axis=0))
    for j in range(V.size):
        for level in (0.05, 0.5, 0.95):
            hand = _mixture_quantile(mu[:, j], [0.1, 0.2], [0.5, 0.5], level)
            assert float(pred["predictive"].sel(law="coulomb_viscous", quantile=level)[j]) == pytest.approx(hand,
                                                                                                           abs=1e-8)
    table = score(fit, ds).set_index(["law", "metric"])["value"]
    lpd, u = np.array([_hand(mu[:, j], [0.1, 0.2], [0.5, 0.5], Y[j]) for j in range(V.size)]).T
    got = table.loc["coulomb_viscous"]
    assert got["elpd"] == pytest.approx(lpd.sum(), rel=1e-10)
    assert got["elpd_per_point"] == pytest.approx(lpd.mean(), rel=1e-10)
    assert got["rms"] == pytest.approx(np.sqrt(np.mean((Y - mu.mean(axis=0)) ** 2)), rel=1e-12)
    assert got["n"] == V.size
    # rows 1, 3 and 5 lie near the middle; row 2 (2.6 vs 1.75 / 2.05) beyond the 90 % band; row 4
    # (-1.38 vs -1.5 / -1.9: PIT 0.94) inside the 90 % band, outside the 50 % one
    inside50, inside90 = ((u >= 0.25) & (u <= 0.75)), ((u >= 0.05) & (u <= 0.95))
    assert inside50.tolist() == [True, False, True, False, True] and inside90.tolist() == [True, False, True, True,
                                                                                             True]
    assert got["coverage_50"] == pytest.approx(3 / 5) and got["coverage_90"] == pytest.approx(4 / 5)
    assert pred.attrs["weighting"] == "single fit" and "no group structure" in pred.attrs["answer_for"]
    assert list(pred["law"].values) == ["coulomb_viscous"]


def test_student_t_noise_and_a_reduced_logs_standard_errors():
    """The program's own observation distribution: Student-t, its scale with the log's se in quadrature."""
    draws = {"T_C": np.array([[2.0, 2.5]]), "sigma": np.array([[0.3, 0.4]]), "nu": np.array([[3.0, 8.0]])}
    fit = hand_fit("coulomb", draws, TESTED, noise=Noise("student_t"))
    se = np.array([0.1, 0.5, 0.0])
    ds = make_dataset({"velocity": np.array([0.5, 1.0, 2.0])}, np.array([2.1, 3.5, 2.2]))
    ds["torque_se"] = ("obs", se, {"role": "se"})
    got = score(fit, ds).set_index("metric")["value"]
    hand = [np.log(np.mean([stats.t.pdf(y, nu, t, np.sqrt(s**2 + e**2))
                            for t, s, nu in ((2.0, 0.3, 3.0), (2.5, 0.4, 8.0))]))
            for y, e in zip([2.1, 3.5, 2.2], se, strict=True)]
    assert got["elpd"] == pytest.approx(sum(hand), rel=1e-10)


def _study(folder: Path, weights: dict[str, float], failed: tuple[str, ...] = ()) -> dict:
    """A study's report folder made by hand: its fits and the nodes sizing reads, LOO weights ``weights``."""
    fits = {"coulomb_viscous": hand_fit("coulomb_viscous", CV, TESTED),
            "coulomb": hand_fit("coulomb", {"T_C": np.array([[1.5, 1.6, 1.8]]), "sigma": np.array([[0.3] * 3])},
                                TESTED)}
    (folder / "fits").mkdir(parents=True)
    for name, fit in fits.items():
        save_fit(fit, folder / "fits" / f"{name}.nc")
    write_basis(folder, list(fits))
    with xr.open_datatree(folder / "results.nc", engine="h5netcdf") as opened:
        tree = opened.load()
    node = tree["weights"].to_dataset()
    node["weight"][:] = np.array([[weights[n]] for n in fits])
    diagnostics = xr.Dataset({"passed": ("law", [n not in failed for n in fits]),
                              "problems": ("law", ["R-hat 1.3" if n in failed else "" for n in fits])},
                             coords={"law": list(fits)})
    tree["weights"], tree["diagnostics"] = node, diagnostics
    tree.to_netcdf(folder / "results.nc", engine="h5netcdf")
    return fits


def test_the_model_average_is_the_weighted_mixture_of_the_laws_draws(tmp_path):
    _study(tmp_path / "r", {"coulomb_viscous": 0.7, "coulomb": 0.3})
    ds = make_dataset({"velocity": V}, Y)
    mu_cv = np.array([np.sign(V) + 0.5 * V, 1.2 * np.sign(V) + 0.7 * V])
    mu_c = np.array([t * np.sign(V) for t in (1.5, 1.6, 1.8)])
    locs, sds = np.vstack([mu_cv, mu_c]), [0.1, 0.2, 0.3, 0.3, 0.3]
    w = [0.35, 0.35, 0.1, 0.1, 0.1]
    for source in (tmp_path / "r", tmp_path / "r" / "results.nc"):
        pred = predict(source, ds, quantiles=[0.1, 0.9])
        assert list(pred["law"].values) == ["coulomb_viscous", "coulomb", "model average"]
        np.testing.assert_allclose(pred["mean"].sel(law="model average"), np.asarray(w) @ locs, rtol=1e-12)
        hand = [_mixture_quantile(locs[:, j], sds, w, 0.9) for j in range(V.size)]
        np.testing.assert_allclose(pred["predictive"].sel(law="model average", quantile=0.9), hand, atol=1e-8)
        assert pred.attrs["weighting"] == "stacking LOO" and json.loads(pred.attrs["weights"]) == pytest.approx(
            {"coulomb_viscous": 0.7, "coulomb": 0.3})
    table = score(tmp_path / "r", ds).set_index(["law", "metric"])["value"]
    lpd = [_hand(locs[:, j], sds, w, Y[j])[0] for j in range(V.size)]
    assert table.loc[("model average", "elpd")] == pytest.approx(sum(lpd), rel=1e-10)


def test_a_law_that_failed_the_gate_is_left_out_of_the_average_and_named(tmp_path):
    _study(tmp_path / "r", {"coulomb_viscous": 0.7, "coulomb": 0.3}, failed=("coulomb_viscous",))
    pred = predict(tmp_path / "r", make_dataset({"velocity": V}, Y))
    np.testing.assert_allclose(pred["mean"].sel(law="model average"), pred["mean"].sel(law="coulomb"))
    assert "coulomb_viscous: failed the diagnostics gate (R-hat 1.3)" in pred.attrs["excluded"]
    assert pred["excluded"].sel(law="coulomb_viscous").item().startswith("failed")
    assert float(pred["weight"].sel(law="coulomb_viscous")) == 0.0


def test_a_stateful_law_runs_along_the_new_logs_trajectories():
    from bayesfric.datasets.views import law_inputs
    from bayesfric.laws import get_law

    draws = {"F_c0": np.array([[0.5, 0.6]]), "gamma": np.array([[0.5, 0.4]]), "x_c0": np.array([[0.02, 0.03]]),
             "i": np.array([[1.0, 1.5]]), "sigma": np.array([[0.05, 0.05]])}
    angle = np.concatenate([np.linspace(0, 0.2, 20), np.linspace(0.2, -0.1, 30)])
    fit = hand_fit("dahl", draws, {"angle": angle, "preload": np.full(50, 90.0)})
    new = np.concatenate([np.linspace(0, 0.15, 15), np.linspace(0.15, -0.2, 25),  # run 1: out and back
                          np.linspace(0.0, -0.1, 10), np.linspace(-0.1, 0.1, 20)])  # run 2 starts again at rest
    ds = make_dataset({"angle": new, "preload": np.full(70, 120.0)}, np.ones(70), groups={"run": [1] * 40 + [2] * 30},
                      trajectory="run")
    law = get_law("dahl")
    direct = np.array([law.mean(law_inputs(ds, law), {k: v[0, s] for k, v in draws.items() if k != "sigma"})
                       for s in range(2)])
    pred = predict(fit, ds)
    np.testing.assert_allclose(pred["mean"].sel(law="dahl"), direct.mean(axis=0), rtol=1e-10, atol=1e-12)
    one_run = law_inputs(ds, law) | {"trajectory_start": np.eye(1, 70, dtype=bool)[0]}  # run 2's start ignored
    flat = np.array([law.mean(one_run, {k: v[0, s] for k, v in draws.items() if k != "sigma"}) for s in range(2)])
    # ignoring run 2's start would be off by far more than the tolerance above (2 % of F_c here)
    assert np.abs(flat.mean(axis=0) - direct.mean(axis=0))[40:].max() > 0.01


def _grouped_fit():
    rng = np.random.default_rng(0)
    offsets = np.array([[[0.1, -0.2]] * 400])  # (chain, draw, group): series 0 runs high, 1 low
    post = {"T_C": np.full((1, 400), 2.0), "sigma": np.full((1, 400), 0.1), "group_sd": np.full((1, 400), 0.3),
            "group_z": rng.normal(size=(1, 400, 2))}
    fit = hand_fit("coulomb", post, TESTED, noise=Noise(group="series"))
    fit["posterior"] = fit["posterior"].to_dataset().assign(
        group_offset=(("chain", "draw", "group"), offsets)).assign_coords(group=["0", "1"])
    return fit


def test_a_named_group_uses_its_offset_and_a_new_group_draws_one():
    fit = _grouped_fit()
    ds = make_dataset({"velocity": np.array([1.0, 2.0])}, np.array([2.0, 2.0]))
    named = predict(fit, ds, group="1")
    np.testing.assert_allclose(named["mean"].sel(law="coulomb"), 2.0 * np.exp(-0.2))
    assert named.attrs["answer_for"].startswith("series '1'")
    new = predict(fit, ds, quantiles=[0.5])
    assert new.attrs["answer_for"].startswith("a new series")
    # a new group: log offsets ~ N(0, 0.3) per draw, so the mean curve's mean is 2 E[exp(b)] = 2 exp(0.045)
    assert float(new["mean"][0, 0]) == pytest.approx(2.0 * np.exp(0.3**2 / 2), rel=0.05)
    with pytest.raises(UserError, match=r"group: '7' is not a group of the fit of coulomb \(series: 0, 1\)"):
        predict(fit, ds, group="7")
    with pytest.raises(UserError, match="no group structure"):
        predict(hand_fit("coulomb_viscous", CV, TESTED), ds, group="1")


def test_errors_name_the_argument():
    fit = hand_fit("coulomb_viscous", CV, TESTED)
    ds = make_dataset({"velocity": V}, Y)
    with pytest.raises(UserError, match=r"quantiles: each quantile must be a number in \(0, 1\), got 1.5"):
        predict(fit, ds, quantiles=[0.5, 1.5])
    with pytest.raises(DataError, match="no column gives input 'velocity'"):
        predict(fit, make_dataset({"angle": V}, Y))
    with pytest.raises(UserError, match="has no response column"):
        score(fit, ds.drop_vars("torque"))
    assert predict(fit, ds.drop_vars("torque"))["mean"].shape == (1, V.size)  # predict needs no response


def test_ar1_noise_is_taken_at_its_stationary_marginal_and_says_so():
    fit = hand_fit("coulomb", {"T_C": np.full((1, 2), 1.0), "sigma": np.full((1, 2), 0.6)}, TESTED)
    fit.attrs["noise"] = '{"kind": "ar1", "group": null, "sigma": null}'
    fit["posterior"] = fit["posterior"].to_dataset().assign(rho=fit["posterior"]["sigma"] * 0 + 0.8)
    pred = predict(fit, make_dataset({"velocity": np.array([1.0])}, np.array([1.0])), quantiles=[0.95])
    assert float(pred["predictive"][0, 0, 0]) == pytest.approx(1.0 + stats.norm.ppf(0.95) * 0.6 / np.sqrt(1 - 0.64))
    assert "stationary marginal" in pred.attrs["noise_note"]


# -- the command line -----------------------------------------------------------------------------
def _log(folder: Path, name: str, columns: dict[str, tuple[str, str, str]], rows: list[list[float]]) -> Path:
    """A CSV + sidecar log: ``columns`` header -> (role, quantity, unit)."""
    (folder / f"{name}.csv").write_text(",".join(columns) + "\n" + "".join(",".join(map(str, r)) + "\n"
                                                                           for r in rows))
    meta = '[dataset]\nname = "new"\nprovenance = "simulated"\nsource = "test"\n' + "".join(
        f'[columns.{c}]\nrole = "{role}"\nquantity = "{q}"\nunit = "{u}"\n' for c, (role, q, u) in columns.items())
    (folder / f"{name}.toml").write_text(meta)
    return folder / f"{name}.csv"


def test_the_cli_predicts_and_scores_a_new_log(tmp_path):
    save_fit(hand_fit("coulomb_viscous", CV, TESTED), tmp_path / "fit.nc")
    _log(tmp_path, "new", {"speed": ("input", "velocity", "rad/s"), "torque": ("response", "torque", "N*m")},
         [[v, y] for v, y in zip(V, Y, strict=True)])
    code, out, err = run_cli(["predict", "fit.nc", "new.csv", "--out", "pred.csv", "--quantiles", "0.25", "0.75"],
                             tmp_path)
    assert code == 0, err
    assert "answering for: the fitted laws as they are" in out and "pred.csv" in out
    import pandas as pd

    table = pd.read_csv(tmp_path / "pred.csv")
    assert list(table.columns) == ["law", "row", "velocity", "response", "mean", "curve_q0.25", "curve_q0.75",
                                   "predictive_q0.25", "predictive_q0.75"]
    expected = predictions_table(predict(tmp_path / "fit.nc", tmp_path / "new.csv", quantiles=[0.25, 0.75]))
    np.testing.assert_allclose(table["predictive_q0.75"], expected["predictive_q0.75"], rtol=1e-12)
    code, out, err = run_cli(["score", "fit.nc", "new.csv", "--out", "score.csv"], tmp_path)
    assert code == 0, err
    assert "coulomb_viscous" in out and "60.0%" in out and "80.0%" in out  # coverage 3/5 and 4/5
    assert set(pd.read_csv(tmp_path / "score.csv")["metric"]) == {"elpd", "elpd_per_point", "elpd_se", "rms",
                                                                    "coverage_50", "coverage_90", "n"}


def test_the_cli_refuses_a_log_without_an_input_a_group_it_lacks_and_a_bad_target(tmp_path):
    save_fit(hand_fit("coulomb_viscous", CV, TESTED), tmp_path / "fit.nc")
    save_fit(_grouped_fit(), tmp_path / "grouped.nc")
    _log(tmp_path, "angles", {"phi": ("input", "angle", "rad"), "torque": ("response", "torque", "N*m")},
         [[0.1, 1.0], [0.2, 1.1]])
    _log(tmp_path, "new", {"speed": ("input", "velocity", "rad/s"), "torque": ("response", "torque", "N*m")},
         [[0.5, 1.0], [1.0, 2.0]])
    assert_user_error(["predict", "fit.nc", "angles.csv", "--out", "p.csv"], tmp_path,
                      ["angles.csv", "'velocity'", "coulomb_viscous", "angle"])
    assert_user_error(["score", "fit.nc", "angles.csv", "--out", "s.csv"], tmp_path, ["angles.csv", "'velocity'"])
    assert_user_error(["predict", "grouped.nc", "new.csv", "--out", "p.csv", "--group", "7"], tmp_path,
                      ["--group", "'7'", "series: 0, 1"])
    assert_user_error(["predict", "fit.nc", "new.csv", "--out", "p.csv", "--quantiles", "0"], tmp_path,
                      ["--quantiles", "(0, 1)"])
    assert_user_error(["score", "nowhere", "new.csv"], tmp_path, ["nowhere", "no such file"])
    assert_user_error(["score", "new.csv", "new.csv"], tmp_path, ["new.csv", "not a readable NetCDF"])


def test_the_private_mean_draws_agree_with_the_one_in_use():
    """:func:`bayesfric.predictive._mean_draws` (kept for a checkout without ``bayesfric.hierarchy``)
    and the function in use give the same draws where both are deterministic (a named group)."""
    from bayesfric.predictive import _mean_draws, _mean_function, _thinned, program_on

    fit = _grouped_fit()
    program = program_on(fit, make_dataset({"velocity": np.array([1.0, 2.0])}, np.ones(2)), "the log")
    posterior = _thinned(fit["posterior"].to_dataset(), 50)
    np.testing.assert_allclose(_mean_function()(program, posterior, group="0"), _mean_draws(program, posterior, "0"))


def test_a_results_file_alone_predicts_from_its_fits_nodes(tmp_path):
    """A study's ``results.nc`` keeps each fit under ``/fits/<law>`` (:data:`bayesfric.study.tree.FIT_GROUPS`):
    moved away from its report folder, it predicts the same as the folder."""
    import shutil

    fits = _study(tmp_path / "r", {"coulomb_viscous": 0.7, "coulomb": 0.3})
    ds = make_dataset({"velocity": V}, Y)
    expected = predict(tmp_path / "r", ds)
    with xr.open_datatree(tmp_path / "r" / "results.nc", engine="h5netcdf") as opened:
        tree = opened.load()
    for name, fit in fits.items():
        tree[f"fits/{name}"] = xr.DataTree.from_dict(
            {"/": xr.Dataset(attrs=dict(fit.attrs))}
            | {g: fit[g].to_dataset() for g in ("posterior", "observed_data", "constant_data")})
    (tmp_path / "alone").mkdir()
    tree.to_netcdf(tmp_path / "alone" / "results.nc", engine="h5netcdf")
    shutil.rmtree(tmp_path / "r")
    got = predict(tmp_path / "alone" / "results.nc", ds)
    xr.testing.assert_allclose(got.drop_attrs(), expected.drop_attrs())


def test_a_planned_log_without_a_response_is_predicted_and_refused_for_scoring(tmp_path):
    """A log of inputs only (a planned trajectory): predict reads it; score says it needs the
    response; a sidecar with two responses is still refused."""
    save_fit(hand_fit("coulomb_viscous", CV, TESTED), tmp_path / "fit.nc")
    _log(tmp_path, "plan", {"speed": ("input", "velocity", "rad/s")}, [[v] for v in V])
    code, out, err = run_cli(["predict", "fit.nc", "plan.csv", "--out", "pred.csv"], tmp_path)
    assert code == 0, err
    import pandas as pd

    table = pd.read_csv(tmp_path / "pred.csv")
    assert "response" not in table.columns and len(table) == len(V)
    expected = predictions_table(predict(tmp_path / "fit.nc", tmp_path / "plan.csv"))
    np.testing.assert_allclose(table["mean"], expected["mean"], rtol=1e-12)
    assert_user_error(["score", "fit.nc", "plan.csv"], tmp_path, ["plan.csv", "no response column"])
    _log(tmp_path, "two", {"speed": ("input", "velocity", "rad/s"), "a": ("response", "torque", "N*m"),
                           "b": ("response", "torque", "N*m")}, [[0.5, 1.0, 1.0]])
    assert_user_error(["predict", "fit.nc", "two.csv", "--out", "p.csv"], tmp_path,
                      ["two.toml", "at most one column must have role 'response' (found 2)"])
