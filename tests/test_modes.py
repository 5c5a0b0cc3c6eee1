"""Multimodal fits (bayesfric.inference.modes): detection, stacking, combined draws, still-failed fits.

The bimodal case is built by hand with exactly known modes: y_i ~ Normal(θ x_i, 1), and the chains
of mode k draw θ from N(μ_k, s²) (chains 0, 1 at μ = +1, chains 2, 3 at μ = -1, s² = 1/Σx²).
Each mode's exact leave-one-out predictive density is Gaussian (removing y_i's likelihood from
N(μ_k, s²): precision 1/s² - x_i², mean s'²(μ_k/s² - x_i y_i)), so the exact stacking weights and
the exact stacked predictive density are known, and the combination is checked against them.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scipy.optimize import minimize_scalar
from scipy.special import logsumexp
from scipy.stats import norm

from bayesfric.inference.diagnostics import Verdict, check
from bayesfric.inference.modes import (
    by_mode,
    chain_health,
    group_chains,
    is_multimodal,
    resolve,
    single_mode_note,
    stacking_weights,
)

CHAINS, DRAWS, N = 4, 1000, 40
MU = (1.0, 1.0, -1.0, -1.0)  # each chain's mode


def _data(seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """x in [0.5, 1.5]; y from slope +1 for 60 % of the rows and slope -1 for the rest, so that
    each mode predicts some rows better and the stacking weights are inside (0, 1)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.5, 1.5, N)
    slope = np.where(np.arange(N) < int(0.6 * N), 1.0, -1.0)
    return x, slope * x + rng.normal(size=N)


def _fit(theta: np.ndarray, x: np.ndarray, y: np.ndarray, diverging: np.ndarray | None = None) -> xr.DataTree:
    """A fit DataTree of draws ``theta`` (chain × draw) of y ~ Normal(θ x, 1)."""
    ll = norm.logpdf(y[None, None], theta[..., None] * x[None, None], 1.0)
    div = np.zeros(theta.shape, bool) if diverging is None else diverging
    dt = xr.DataTree.from_dict({
        "posterior": xr.Dataset({"theta": (("chain", "draw"), theta)}),
        "sample_stats": xr.Dataset({"diverging": (("chain", "draw"), div)}),
        "log_likelihood": xr.Dataset({"y": (("chain", "draw", "obs"), ll)}),
    })
    for group in ("posterior", "sample_stats", "log_likelihood"):
        dt[group] = dt[group].to_dataset().assign_coords(chain=np.arange(theta.shape[0]), draw=np.arange(DRAWS))
    return dt


def _bimodal(seed: int = 2) -> tuple[xr.DataTree, float, np.ndarray, np.ndarray]:
    x, y = _data()
    s = 1.0 / np.sqrt(np.sum(x ** 2))
    theta = np.asarray(MU)[:, None] + s * np.random.default_rng(seed).normal(size=(CHAINS, DRAWS))
    return _fit(theta, x, y), s, x, y


def _exact_loo(mu: float, s: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """log p_k(y_i | y_-i) for the mode N(mu, s²) (see the module notes)."""
    var = 1.0 / (1.0 / s ** 2 - x ** 2)
    mean = var * (mu / s ** 2 - x * y)
    return norm.logpdf(y, mean * x, np.sqrt(1.0 + var * x ** 2))


def _exact_weight(lpd: np.ndarray, prior: tuple[float, float] = (0.0, 0.0)) -> float:
    """The exact stacking weight of mode 0 (two modes; ``prior``: Dirichlet pseudo-counts), by a
    bounded scalar search."""
    def loss(w):
        return -np.sum(logsumexp(lpd, axis=0, b=np.array([[w], [1 - w]]))) - prior[0] * np.log(w) \
            - prior[1] * np.log(1 - w)

    return float(minimize_scalar(loss, bounds=(1e-12, 1 - 1e-12), method="bounded", options={"xatol": 1e-10}).x)


def test_bimodal_fit_is_multimodal_with_two_modes():
    dt, *_ = _bimodal()
    verdict = check(dt)
    assert not verdict.passed and any(p.startswith("R-hat") for p in verdict.problems)
    combined, resolved = resolve(dt, verdict, seed=0)
    assert resolved.passed and resolved.multimodal
    assert resolved.modes == ((0, 1), (2, 3))
    assert len(resolved.weights) == 2 and abs(sum(resolved.weights) - 1) < 1e-9
    lo0, hi0 = resolved.mode_ranges["theta"][0]
    lo1, hi1 = resolved.mode_ranges["theta"][1]
    assert 0.6 < lo0 < 1 < hi0 < 1.4 and -1.4 < lo1 < -1 < hi1 < -0.6
    assert "multimodal: 2 modes" in str(resolved) and str(resolved).startswith("MULTIMODAL")
    back = Verdict.from_json(resolved.to_json())
    assert back.modes == resolved.modes and back.weights == resolved.weights and back.multimodal
    combined.attrs["diagnostics"] = resolved.to_json()
    assert is_multimodal(combined) and "posterior_chains" in combined.children
    assert "2 modes" in single_mode_note(combined)


def test_stacking_weights_match_the_exact_ones():
    dt, s, x, y = _bimodal()
    combined, resolved = resolve(dt, check(dt), seed=0)
    lpd = np.array([_exact_loo(MU[0], s, x, y), _exact_loo(MU[2], s, x, y)])
    exact = _exact_weight(lpd, (0.5, 0.5))  # resolve's objective: one pseudo-observation, 2 chains each
    assert 0.2 < exact < 0.8  # the case is not trivial: both modes carry weight
    # PSIS on 2000 draws per mode against the exact LOO densities
    assert abs(resolved.weights[0] - exact) < 0.01, (resolved.weights, exact)
    # the EM fixed point reaches the maximum the scalar search finds on the same densities
    assert abs(stacking_weights(lpd)[0] - _exact_weight(lpd)) < 1e-5
    assert abs(stacking_weights(lpd, np.array([0.5, 0.5]))[0] - exact) < 1e-5


def test_modes_that_predict_alike_keep_the_chains_share():
    """A sign ambiguity (y ~ Normal(θ² x, 1), modes ±θ): the stacking objective is flat up to Monte
    Carlo noise; the pseudo-observation keeps the weights at the chains' share (3 : 1), not a corner."""
    x, y = _data()
    y = np.abs(y)
    s = 0.05
    theta = np.array([1.0, 1.0, 1.0, -1.0])[:, None] + s * np.random.default_rng(6).normal(size=(CHAINS, DRAWS))
    ll = norm.logpdf(y[None, None], theta[..., None] ** 2 * x[None, None], 1.0)
    dt = _fit(theta, x, y)
    dt["log_likelihood"] = dt["log_likelihood"].to_dataset().assign(y=(("chain", "draw", "obs"), ll))
    resolved = resolve(dt, check(dt), seed=0)[1]
    assert resolved.modes == ((0, 1, 2), (3,))
    assert abs(resolved.weights[0] - 0.75) < 0.05, resolved.weights


def test_combined_draws_give_the_stacked_predictive_density():
    dt, s, x, y = _bimodal()
    combined, resolved = resolve(dt, check(dt), seed=0)
    theta = combined["posterior"]["theta"].values
    assert theta.shape == (CHAINS, DRAWS)
    # each draw keeps its own log-likelihood (the groups stay aligned)
    ll = combined["log_likelihood"]["y"].values
    np.testing.assert_allclose(ll, norm.logpdf(y[None, None], theta[..., None] * x[None, None], 1.0))
    # share of the combined draws in mode 0 = its weight (largest remainders over 4000 draws)
    assert abs(np.mean(theta > 0) - resolved.weights[0]) <= 1 / theta.size
    # predictive density at new points: Monte Carlo over the combined draws vs the exact mixture
    # Σ_k w_k N(ỹ; μ_k x̃, 1 + s² x̃²) with the same weights
    grid_x, grid_y = np.array([0.7, 1.0, 1.3]), np.linspace(-3, 3, 13)
    per_draw = norm.pdf(grid_y[:, None, None], theta.ravel()[None, None] * grid_x[None, :, None], 1.0)
    estimate, mcse = per_draw.mean(-1), per_draw.std(-1) / np.sqrt(theta.size)
    w = np.asarray(resolved.weights)
    exact = sum(wk * norm.pdf(grid_y[:, None], mu * grid_x[None], np.sqrt(1 + s ** 2 * grid_x[None] ** 2))
                for wk, mu in zip(w, (MU[0], MU[2]), strict=True))
    # the draws are resampled from 2000 per mode (no independent draws): 5 Monte Carlo se
    assert np.all(np.abs(estimate - exact) < 5 * mcse + 1e-4), np.max(np.abs(estimate - exact) / mcse)


def test_divergences_within_a_chain_still_fail():
    dt, *_ = _bimodal()
    div = np.zeros((CHAINS, DRAWS), bool)
    div[1, 10:13] = True
    dt["sample_stats"] = dt["sample_stats"].to_dataset().assign(diverging=(("chain", "draw"), div))
    verdict = check(dt)
    fit, resolved = resolve(dt, verdict, seed=0)
    assert not resolved.passed and not resolved.multimodal and fit is dt
    assert "divergent" in resolved.mode_note
    health = chain_health(dt["posterior"].to_dataset(), dt["sample_stats"].to_dataset())
    assert [h.healthy for h in health] == [True, False, True, True]


def test_chain_not_converged_within_still_fails():
    x, y = _data()
    s = 1.0 / np.sqrt(np.sum(x ** 2))
    rng = np.random.default_rng(3)
    theta = np.asarray(MU)[:, None] + s * rng.normal(size=(CHAINS, DRAWS))
    theta[3] = np.linspace(-1.0, 1.0, DRAWS) + s * rng.normal(size=DRAWS)  # drifts across: unconverged
    resolved = resolve(_fit(theta, x, y), check(_fit(theta, x, y)), seed=0)[1]
    assert not resolved.passed and not resolved.multimodal
    assert "chain 3" in resolved.mode_note and "FAILED" in str(resolved)


def test_chains_drifting_apart_without_modes_fail():
    """Chains a fraction of a posterior sd apart are not separate modes."""
    x, y = _data()
    s = 1.0 / np.sqrt(np.sum(x ** 2))
    theta = 1.0 + s * np.array([0.0, 0.0, 0.8, 0.8])[:, None] + s * np.random.default_rng(4).normal(size=(4, DRAWS))
    dt = _fit(theta, x, y)
    resolved = resolve(dt, check(dt), seed=0)[1]
    assert not resolved.passed and not resolved.multimodal and "apart" in resolved.mode_note


def test_a_passed_fit_is_left_alone():
    x, y = _data()
    theta = 1.0 + 0.1 * np.random.default_rng(5).normal(size=(CHAINS, DRAWS))
    dt = _fit(theta, x, y)
    verdict = check(dt)
    assert verdict.passed
    fit, same = resolve(dt, verdict, seed=0)
    assert fit is dt and same == verdict and not same.multimodal


def test_group_chains_single_linkage():
    means = np.array([[0.0, 0.0], [0.1, 0.0], [3.0, 0.0], [3.1, 0.0], [0.0, 9.0]])
    groups, d = group_chains(means, np.ones_like(means), link=0.5)
    assert groups == ((0, 1), (2, 3), (4,))
    assert d[0, 2] == pytest.approx(3.0)


def test_evidence_by_mode_sums_the_modes():
    dt, *_ = _bimodal()
    combined, resolved = resolve(dt, check(dt), seed=0)
    combined.attrs["diagnostics"] = resolved.to_json()
    from bayesfric.compare.evidence import Evidence

    seen = []

    def estimate(part):  # a stand-in estimator: Z_k = number of chains in the mode, ±10 %
        seen.append(part["posterior"].sizes["chain"])
        mean = float(part["posterior"]["theta"].mean())
        return Evidence(float(np.log(part["posterior"].sizes["chain"])), 0.1, "bridge", {"mean": mean})

    result = by_mode(combined, estimate)
    assert seen == [2, 2]
    assert result.log_z == pytest.approx(np.log(4.0)) and result.method == "bridge"
    assert result.error == pytest.approx(0.1 * np.sqrt(0.5 ** 2 + 0.5 ** 2))
    means = [d["mean"] for d in result.diagnostics["per_mode"]]
    assert means[0] > 0.8 and means[1] < -0.8  # each mode's estimate saw its own chains only


def test_nuts_fit_of_a_sign_ambiguous_law_is_multimodal_and_combined():
    """End to end through the sampler: T = k² q̇ with a prior symmetric in k. Chains start at their
    own prior medians and settle at k = +1 or -1; a fit whose chains split is multimodal (its
    groups aligned, its chains kept), one whose chains agree passes as before."""
    import bayesfric
    from bayesfric.datasets.synthetic import make_dataset
    from bayesfric.inference.diagnostics import verdict_of
    from bayesfric.priors import Prior

    def squared_gain(velocity, k):
        return k * k * velocity

    law = bayesfric.law(squared_gain, units={"k": "(N*m*s/rad)**0.5"},
                        priors={"k": Prior("Normal", loc=0.0, scale=2.0)})
    rng = np.random.default_rng(0)
    v = rng.uniform(0.5, 1.5, 60)
    ds = make_dataset({"velocity": v}, v + 0.1 * rng.normal(size=60))
    split = 0
    for seed in range(3):
        fit = bayesfric.fit(law, ds, draws=500, tune=300, chains=4, seed=seed)
        verdict = verdict_of(fit)
        signs = np.sign(fit["posterior_chains" if verdict.multimodal else "posterior"]["k"].mean("draw").values)
        assert verdict.passed
        if len(set(signs)) == 1:
            assert not verdict.multimodal and "posterior_chains" not in fit.children
            continue
        split += 1
        assert verdict.multimodal and len(verdict.modes) == 2
        assert sorted(len(m) for m in verdict.modes) == sorted([int(np.sum(signs > 0)), int(np.sum(signs < 0))])
        k, sigma = fit["posterior"]["k"].values, fit["posterior"]["sigma"].values
        ll = next(iter(fit["log_likelihood"].data_vars.values())).values
        np.testing.assert_allclose(ll, norm.logpdf(ds["torque"].values, k[..., None] ** 2 * v, sigma[..., None]),
                                   rtol=1e-6, atol=1e-6)
        share = np.mean(k > 0)
        assert abs(share - verdict.weights[[np.sign(np.mean(fit["posterior_chains"]["k"].isel(chain=list(m))))
                                            for m in verdict.modes].index(1.0)]) < 1e-3
    assert split >= 1  # on these data and seeds some chains always split (seeds 0 and 1 do)


def test_law_result_and_tree_node_keep_the_modes():
    """The study's law result marks the law multimodal (used, not failed) with each mode's weight
    and 5-95 % ranges, its flags say so in one line, and the tree's ``/modes`` node has a row per
    mode and variable."""
    from bayesfric.laws import get_law
    from bayesfric.study.lawresult import law_result, mode_node

    dt, *_ = _bimodal()
    verdict = resolve(dt, check(dt), seed=0)[1]
    ds = law_result(get_law("coulomb"), "fits/x.nc", verdict)
    assert bool(ds["passed"]) and bool(ds["multimodal"]) and str(ds["modes"].values).startswith("multimodal: 2 modes")
    assert ds["mode_weight"].sizes["mode"] == 2 and float(ds["mode_weight"].sum()) == pytest.approx(1.0)
    assert float(ds["mode_q05"].sel(mode="1", mode_parameter="theta")) > 0 > float(ds["mode_q95"].sel(
        mode="2", mode_parameter="theta"))
    flags = str(ds["flags"].values).split("\n")
    assert flags[0].startswith("multimodal: 2 modes") and "theta" in flags[0]
    assert not any("FAILED" in f for f in flags)
    node = mode_node([ds])["modes"]
    assert list(node["mode"].values) == ["1", "2"] and list(node["chains"].values) == ["0,1", "2,3"]
    failed = law_result(get_law("coulomb"), "fits/x.nc", check(dt))
    assert not bool(failed["multimodal"]) and "mode_weight" not in failed and mode_node([failed]) == {}


def _ridge(drift: bool, seed: int = 6) -> xr.DataTree:
    """y ~ Normal((a + b) x, 1): only a + b is identified. Every chain draws a + b from its
    posterior; chain 3's ``a`` wanders (half its draws 3 units up, ``b`` compensating), so a and b
    do not mix. With ``drift`` the wandering also moves a + b: then the fit to the rows disagrees."""
    x, y = _data()
    s = 1.0 / np.sqrt(np.sum(x ** 2))
    rng = np.random.default_rng(seed)
    total = 0.2 + s * rng.normal(size=(CHAINS, DRAWS))
    a = rng.normal(size=(CHAINS, DRAWS)) * 0.05
    a[3, DRAWS // 2:] += 3.0
    if drift:
        total[3, DRAWS // 2:] += 4 * s
    b = total - a
    ll = norm.logpdf(y[None, None], total[..., None] * x[None, None], 1.0)
    dt = xr.DataTree.from_dict({
        "posterior": xr.Dataset({"a": (("chain", "draw"), a), "b": (("chain", "draw"), b),
                                 "total": (("chain", "draw"), total)}),
        "sample_stats": xr.Dataset({"diverging": (("chain", "draw"), np.zeros((CHAINS, DRAWS), bool))}),
        "log_likelihood": xr.Dataset({"y": (("chain", "draw", "obs"), ll)}),
    })
    for group in ("posterior", "sample_stats", "log_likelihood"):
        dt[group] = dt[group].to_dataset().assign_coords(chain=np.arange(CHAINS), draw=np.arange(DRAWS))
    return dt


def test_chains_unmixed_along_an_unidentified_ridge_are_used_pooled():
    """Chains that wander along a direction the data do not determine, agreeing on the fit to every
    row, are not a failed fit: the verdict passes, names the variables that did not mix, keeps the
    chains as sampled (pooled), and says the predictions converged but those variables did not."""
    dt = _ridge(drift=False)
    verdict = check(dt)
    assert not verdict.passed and verdict.predictions_converged
    fit, resolved = resolve(dt, verdict, seed=0)
    assert fit is dt and resolved.passed and not resolved.multimodal
    assert resolved.unidentified == ("a", "b")
    assert str(resolved).startswith("UNIDENTIFIED") and "not identified by the data: a, b" in str(resolved)
    assert "chain 3" in resolved.mode_note  # why it is not multimodal: chain 3 wanders within itself
    again = Verdict.from_json(resolved.to_json())
    assert again == resolved and again.unidentified == ("a", "b")


def test_chains_that_disagree_on_the_rows_still_fail():
    """The same wandering chain, but moving the fit to the rows too: not converged, failed."""
    dt = _ridge(drift=True)
    verdict = check(dt)
    assert not verdict.predictions_converged
    resolved = resolve(dt, verdict, seed=0)[1]
    assert not resolved.passed and not resolved.unidentified and "FAILED" in str(resolved)


def test_an_unidentified_fit_with_a_divergence_still_fails():
    dt = _ridge(drift=False)
    div = np.zeros((CHAINS, DRAWS), bool)
    div[0, 5] = True
    dt["sample_stats"] = dt["sample_stats"].to_dataset().assign(diverging=(("chain", "draw"), div))
    resolved = resolve(dt, check(dt), seed=0)[1]
    assert not resolved.passed and not resolved.unidentified


def test_law_result_marks_an_unidentified_fit_used_not_failed():
    """The study's law result of such a fit: passed, ``unidentified`` naming the variables, one
    flag line saying which did not mix and that the predictions converged; the report's gate word."""
    from bayesfric.laws import get_law
    from bayesfric.study.lawresult import law_result

    dt = _ridge(drift=False)
    ds = law_result(get_law("coulomb"), "fits/x.nc", resolve(dt, check(dt), seed=0)[1])
    assert bool(ds["passed"]) and not bool(ds["multimodal"]) and str(ds["unidentified"].values) == "a, b"
    flags = str(ds["flags"].values).split("\n")
    assert flags[0].startswith("not identified by the data: a, b") and "predictions on the tested rows" in flags[0]
    assert not any("FAILED" in f for f in flags)

