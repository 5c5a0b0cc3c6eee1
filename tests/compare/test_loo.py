"""PSIS-LOO with exact refits of high Pareto-k points; extrapolation penalty."""

import arviz as az
import numpy as np
import pytest

from bayesfric.compare.folds import blocked_masks
from bayesfric.compare.loo import extrapolation_penalty, psis_loo
from bayesfric.compare.refit import CVResult, pointwise_lpd, program_from_fit
from bayesfric.datasets.synthetic import make_dataset, simulate
from bayesfric.inference import fit
from bayesfric.laws.base import get_law
from bayesfric.model import Noise, build_program

LAW = "coulomb_viscous"
SPEEDS = np.linspace(0.1, 4.0, 30)
SIGMA = 0.05
NOISE = Noise(sigma=SIGMA)  # known sigma: the exact LOO predictive is Gaussian, see below


@pytest.fixture(scope="module")
def outlier_data():
    """30 points of Coulomb + viscous friction; the last (highest speed, most leverage) is
    shifted by 8 noise standard deviations."""
    ds = simulate(get_law(LAW), {"velocity": SPEEDS}, {"T_C": 1.0, "c_v": 0.5}, sigma=SIGMA,
                  seed=2)
    torque = ds["torque"].values.copy()
    torque[-1] += 8 * SIGMA
    return make_dataset({"velocity": SPEEDS}, torque, name="planted_outlier")


@pytest.fixture(scope="module")
def outlier_fit(outlier_data):
    return fit(get_law(LAW), outlier_data, noise=NOISE, draws=500, tune=300, chains=2, seed=0)


def exact_loo_lpd(ds, i: int) -> float:
    """Closed-form log p(y_i | y_-i) of T = T_C + c_v v (v > 0) with known sigma.

    The HalfNormal priors are treated as the full Normal(0, s): the posterior sits ~50 sd
    from zero, so the truncation changes nothing at double precision.
    """
    program = build_program(get_law(LAW), ds, noise=NOISE)
    scales = np.array([program.resolved[k].args["scale"] for k in ("T_C", "c_v")])
    X = np.stack([np.ones_like(SPEEDS), SPEEDS], axis=1)
    y = ds["torque"].values
    keep = np.arange(y.size) != i
    precision = X[keep].T @ X[keep] / SIGMA**2 + np.diag(1 / scales**2)
    mean = np.linalg.solve(precision, X[keep].T @ y[keep] / SIGMA**2)
    var = SIGMA**2 + X[i] @ np.linalg.solve(precision, X[i])
    return float(-0.5 * (y[i] - X[i] @ mean) ** 2 / var - 0.5 * np.log(2 * np.pi * var))


def test_loo_without_data_is_finite_and_flags_unrefitted_points(outlier_fit):
    result = psis_loo(outlier_fit)
    reference = az.loo(outlier_fit, pointwise=True, var_name="response")
    assert np.isfinite(result.elpd) and np.isfinite(result.pareto_k).all()
    np.testing.assert_allclose(result.pareto_k, reference.pareto_k.values)
    np.testing.assert_allclose(result.elpd, reference.elpd)
    assert result.k_threshold == pytest.approx(min(1 - 1 / np.log10(1000), 0.7))
    np.testing.assert_array_equal(result.high_k,
                                  np.flatnonzero(result.pareto_k > result.k_threshold))
    assert 29 in result.high_k  # the planted outlier
    assert "not refitted" in result.handling and not result.reliable
    lppd = pointwise_lpd(outlier_fit["log_likelihood"]["response"].values)
    assert result.p_loo == pytest.approx(float((lppd - result.elpd_i).sum()))


def test_an_engine_factory_is_called_only_when_a_point_needs_a_refit(outlier_fit, outlier_data):
    """A study passes a function that builds its warm-started engine: without high-k points the
    engine is never built; with one, it is built once (and a failing factory shows it ran)."""
    calls = []

    def factory():
        calls.append(1)
        raise RuntimeError("engine requested")

    clean = outlier_fit.copy()
    clean["log_likelihood"] = clean["log_likelihood"].isel(obs=slice(0, 29))  # drop the outlier
    result = psis_loo(clean, engine=factory)
    if result.high_k.size:  # the 29 clean points must not need a refit, or this test proves nothing
        pytest.fail(f"clean points with high k: {result.high_k}")
    assert calls == [] and result.handling == "none above threshold"
    with pytest.raises(RuntimeError, match="engine requested"):
        psis_loo(outlier_fit, engine=factory)
    assert calls == [1]


def test_a_known_sigma_is_recorded_so_the_program_can_be_rebuilt(outlier_fit, outlier_data):
    import json

    rebuilt = program_from_fit(outlier_fit, outlier_data)
    assert rebuilt.noise == NOISE and "sigma" not in rebuilt.priors
    legacy = outlier_fit.copy()  # a fit written before the sigma was recorded
    legacy.attrs["noise"] = json.dumps({"kind": "normal", "group": None})
    with pytest.raises(ValueError, match="known noise sigma"):
        program_from_fit(legacy, outlier_data)


@pytest.mark.slow
def test_high_k_points_are_refitted_exactly(outlier_fit, outlier_data):
    psis = psis_loo(outlier_fit)
    result = psis_loo(outlier_fit, program=build_program(get_law(LAW), outlier_data, noise=NOISE))
    high = result.high_k
    others = np.setdiff1d(np.arange(30), high)
    np.testing.assert_array_equal(high, psis.high_k)
    np.testing.assert_allclose(result.elpd_i[others], psis.elpd_i[others])  # untouched
    assert "exact refits" in result.handling and not result.refit_failed
    assert result.elpd == pytest.approx(result.elpd_i.sum())
    for i in high:
        # Monte Carlo error of the refit's log mean density: a few tenths of a nat
        assert result.elpd_i[i] == pytest.approx(exact_loo_lpd(outlier_data, i), abs=0.5)
        assert result.elpd_i[i] != psis.elpd_i[i]


def test_extrapolation_penalty_compares_the_same_points(outlier_fit, outlier_data):
    loo = psis_loo(outlier_fit)
    folds = blocked_masks(outlier_data, "velocity", quantile=0.8)
    held = folds.heldout[0]
    blocked_i = np.where(held, loo.elpd_i - 0.25, np.nan)  # a law losing 0.25 nats per point
    blocked = CVResult(LAW, folds.scheme, float(np.nansum(blocked_i)), 0.0, blocked_i, held,
                       [], 0.0)
    penalty = extrapolation_penalty(loo, blocked)
    assert penalty.per_point == pytest.approx(0.25)
    assert penalty.n_points == held.sum()
    assert penalty.se == pytest.approx(0.0, abs=1e-12)
