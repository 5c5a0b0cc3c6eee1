"""Stacking / pseudo-BMA+ weights, exclusion of unreliable fits, Bayes factors, averaging.

Fits here are hand-built DataTrees (posterior, log likelihood, predictions): no sampling."""

import arviz as az
import numpy as np
import pytest
from scipy.stats import norm

from bayesfric.compare.loo import psis_loo
from bayesfric.compare.refit import CVResult
from bayesfric.compare.weights import averaged_predictive, bayes_factors, model_weights
from bayesfric.inference.diagnostics import Verdict

RNG = np.random.default_rng(5)
Y = RNG.normal(0.0, 1.0, 40)


def verdict(passed: bool) -> Verdict:
    return Verdict(passed, 1.0, 1000.0, 1000.0, 0, 1.0, None, [] if passed else ["R-hat 1.2 > 1.01"])


def fake_fit(name: str, centre: float, passed: bool = True, fill: float = 0.0):
    """Posterior of a location mu ~ N(centre, 0.1^2), unit-variance normal likelihood of Y."""
    mu = RNG.normal(centre, 0.1, size=(2, 500))
    ll = norm.logpdf(Y[None, None, :], loc=mu[..., None], scale=1.0)
    dt = az.from_dict({
        "posterior": {"mu": mu},
        "log_likelihood": {"response": ll},
        "posterior_predictive": {"response": np.full((2, 500, Y.size), fill)},
        "observed_data": {"response": Y},
    }, dims={"response": ["obs"]})
    dt.attrs.update(law=name, diagnostics=verdict(passed).to_json())
    return dt


@pytest.fixture(scope="module")
def loos():
    return {"good": psis_loo(fake_fit("good", 0.0)), "off": psis_loo(fake_fit("off", 1.5)),
            "broken": psis_loo(fake_fit("broken", 0.0, passed=False))}


def cv(name: str, elpd_i: np.ndarray, heldout: np.ndarray, passed: bool = True) -> CVResult:
    values = np.where(heldout, elpd_i, np.nan)
    scored = values[heldout]
    return CVResult(name, "blocked velocity > 3 rad/s", float(scored.sum()),
                    float(np.sqrt(scored.size * scored.var())), values, heldout,
                    [verdict(passed)], 0.0)


@pytest.mark.parametrize("method", ["stacking", "BB-pseudo-BMA", "pseudo-BMA+"])
def test_loo_weights_sum_to_one_and_exclude_failed_fits(loos, method):
    weights = model_weights(loos, method=method)
    assert set(weights.weights) == {"good", "off"}
    assert sum(weights.weights.values()) == pytest.approx(1.0, abs=1e-9)
    assert all(w >= 0 for w in weights.weights.values())
    assert weights.excluded == {"broken": "fit failed the diagnostics gate"}
    assert weights.weights["good"] > 0.9  # the off-centre model loses ~1.1 nats per point
    assert "broken" in str(weights)


def test_include_failed_keeps_every_fit(loos):
    weights = model_weights(loos, include_failed=True)
    assert set(weights.weights) == {"good", "off", "broken"} and not weights.excluded
    assert sum(weights.weights.values()) == pytest.approx(1.0, abs=1e-9)


def test_blocked_stacking_favours_the_law_that_extrapolates():
    heldout = np.arange(40) >= 30
    base = norm.logpdf(Y)
    results = {
        "extrapolates": cv("extrapolates", base, heldout),
        "saturates": cv("saturates", base - 2.0, heldout),
        "failed_folds": cv("failed_folds", base + 1.0, heldout, passed=False),
    }
    weights = model_weights(results)
    assert weights.basis == "blocked velocity > 3 rad/s"
    assert weights.weights["extrapolates"] > 0.95
    assert sum(weights.weights.values()) == pytest.approx(1.0, abs=1e-9)
    assert "failed_folds" in weights.excluded and "failed_folds" not in weights.weights


def test_mixed_or_mismatched_results_are_refused(loos):
    heldout = np.arange(40) >= 30
    with pytest.raises(ValueError, match="one kind"):
        model_weights({"a": loos["good"], "b": cv("b", norm.logpdf(Y), heldout)})
    with pytest.raises(ValueError, match="same held-out"):
        model_weights({"a": cv("a", norm.logpdf(Y), heldout),
                       "b": cv("b", norm.logpdf(Y), np.arange(40) >= 20)})


def test_bayes_factors_with_propagated_errors():
    bf = bayes_factors({"a": (-10.0, 0.3), "b": (-12.0, 0.4), "c": (-10.5, 0.0)})
    assert bf.log_bf.loc["a", "b"] == pytest.approx(2.0)
    assert bf.log_bf.loc["b", "a"] == pytest.approx(-2.0)
    assert bf.err.loc["a", "b"] == pytest.approx(0.5)  # sqrt(0.3² + 0.4²)
    assert bf.log_bf.loc["c", "c"] == 0.0 and bf.err.loc["c", "c"] == 0.0
    with pytest.raises(ValueError):
        bayes_factors({"a": (float("nan"), 0.1)})


def test_averaged_predictive_mixes_draws_by_weight():
    fits = {"zeros": fake_fit("zeros", 0.0, fill=0.0), "ones": fake_fit("ones", 0.0, fill=1.0)}
    averaged = averaged_predictive(fits, {"zeros": 0.75, "ones": 0.25}, seed=1)
    draws = averaged["posterior_predictive"]["response"].values
    assert draws.shape[-1] == Y.size
    assert draws.mean() == pytest.approx(0.25)  # 250 of the 1000 draws come from "ones"
    single = averaged_predictive(fits, {"zeros": 1.0, "ones": 0.0})
    assert float(single["posterior_predictive"]["response"].mean()) == 0.0


def test_a_joint_scheme_stacks_the_folds_joint_densities_not_the_rows():
    """Leave-future-out / leave-one-group-out rank by each held-out group's rows together; their
    stacking weighs those joint densities: here the rows favour "a" one at a time, the groups
    favour "b" as wholes, and the weights follow the groups."""
    rng = np.random.default_rng(0)
    heldout = np.ones(40, dtype=bool)
    rows_a, rows_b = rng.normal(-1.0, 0.1, 40), rng.normal(-1.5, 0.1, 40)
    a, b = cv("a", rows_a, heldout), cv("b", rows_b, heldout)
    assert model_weights({"a": a, "b": b}).weights["a"] > 0.9  # pointwise
    a.elpd_fold, b.elpd_fold = np.array([-30.0, -32.0, -29.0, -31.0]), np.array([-20.0, -21.0, -19.0, -22.0])
    weights = model_weights({"a": a, "b": b})
    assert weights.weights["b"] > 0.9 and sum(weights.weights.values()) == pytest.approx(1.0)
