"""AR(1) residual noise (bayesfric.noise): exact likelihood against the joint Gaussian,
conditional pointwise terms, masked gaps integrated out, recovery of ρ, evidence against i.i.d."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy.stats import multivariate_normal, norm

from bayesfric.compare.evidence import bridge_log_evidence
from bayesfric.compare.loo import psis_loo
from bayesfric.datasets.loader import DataError
from bayesfric.inference import check, fit
from bayesfric.laws import get_law
from bayesfric.model import Noise, build_program
from bayesfric.noise import AR1Residuals, ar1_log_prob


def ar1_covariance(start: np.ndarray, sigma: float, rho: float) -> np.ndarray:
    """Stationary AR(1) covariance σ²/(1−ρ²) ρ^|i−j| within a trajectory, 0 across."""
    traj = np.cumsum(start)
    i = np.arange(start.size)
    lag = np.abs(i[:, None] - i[None, :])
    same = traj[:, None] == traj[None, :]
    return np.where(same, sigma**2 / (1 - rho**2) * rho**lag, 0.0)


def two_trajectories(n1=7, n2=5):
    start = np.zeros(n1 + n2, dtype=bool)
    start[[0, n1]] = True
    return start


@pytest.mark.parametrize("rho", [0.8, -0.6, 0.0])
def test_joint_log_likelihood_equals_multivariate_normal(rho):
    start = two_trajectories()
    e = np.random.default_rng(0).normal(size=start.size)
    sigma = 0.7
    terms = np.asarray(ar1_log_prob(e, sigma, rho, start))
    expected = multivariate_normal(np.zeros(start.size), ar1_covariance(start, sigma, rho)).logpdf(e)
    assert terms.sum() == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize("rho", [0.9, -0.5])
def test_masked_gaps_are_integrated_out_exactly(rho):
    # points 2-4 of trajectory 1 and the first point of trajectory 2 held out
    start = two_trajectories()
    observed = np.ones(start.size, dtype=bool)
    observed[[2, 3, 4, 7]] = False
    e = np.random.default_rng(1).normal(size=start.size)
    sigma = 0.3
    terms = np.asarray(ar1_log_prob(e, sigma, rho, start, observed))
    cov = ar1_covariance(start, sigma, rho)[np.ix_(observed, observed)]
    expected = multivariate_normal(np.zeros(observed.sum()), cov).logpdf(e[observed])
    assert terms[observed].sum() == pytest.approx(expected, rel=1e-10)


def test_pointwise_terms_are_one_step_conditionals():
    # hand computation: e_t | e_{t-1} ~ N(ρ e_{t-1}, σ²); a trajectory's first point: N(0, σ²/(1-ρ²));
    # after a gap of k = 3 steps: N(ρ³ e_s, σ²(1-ρ⁶)/(1-ρ²))
    start = two_trajectories(6, 4)
    e = np.array([0.5, -0.2, 0.1, 0.4, 0.0, -0.3, 1.0, 0.2, -0.1, 0.3])
    sigma, rho = 0.5, 0.6
    observed = np.ones(10, dtype=bool)
    observed[[2, 3]] = False
    terms = np.asarray(ar1_log_prob(e, sigma, rho, start, observed))
    marginal_sd = sigma / np.sqrt(1 - rho**2)
    assert terms[0] == pytest.approx(norm(0, marginal_sd).logpdf(0.5), rel=1e-12)
    assert terms[1] == pytest.approx(norm(rho * 0.5, sigma).logpdf(-0.2), rel=1e-12)
    gap_sd = sigma * np.sqrt((1 - rho**6) / (1 - rho**2))
    assert terms[4] == pytest.approx(norm(rho**3 * -0.2, gap_sd).logpdf(0.0), rel=1e-12)
    assert terms[6] == pytest.approx(norm(0, marginal_sd).logpdf(1.0), rel=1e-12)  # new trajectory
    assert terms[7] == pytest.approx(norm(rho * 1.0, sigma).logpdf(0.2), rel=1e-12)


def _coulomb_viscous_data(simulator, *, rho, n_traj=4, per_traj=60, seed=0):
    """Coulomb + viscous sweeps with AR(1) residuals (σ = 0.02 N·m) along each trajectory."""
    law = get_law("coulomb_viscous")
    v = np.tile(np.linspace(-2.0, 2.0, per_traj), n_traj)
    truth = {"T_C": 0.5, "c_v": 0.2}
    runs = np.repeat(np.arange(n_traj), per_traj)
    ds = simulator(law, {"velocity": v}, truth, sigma=1e-12, seed=seed, groups={"run": runs},
                   trajectory="run")
    start = np.r_[True, runs[1:] != runs[:-1]]
    sigma = 0.02
    noise = AR1Residuals(np.zeros(v.size), sigma, rho, start).sample(jax.random.PRNGKey(seed))
    ds["torque"].values[:] += np.asarray(noise)
    return law, ds, truth, sigma


def test_program_density_matches_scipy_with_a_fold_mask(simulator):
    law, ds, _, _ = _coulomb_viscous_data(simulator, rho=0.7, n_traj=2, per_traj=8)
    program = build_program(law, ds, noise=Noise(kind="ar1"))
    density = program.density()
    params = {"T_C": 0.45, "c_v": 0.25, "sigma": 0.03, "rho": 0.5}
    mu = np.asarray(law.mean(program.inputs, params))
    resid = program.response - mu
    x = density.to_unconstrained({k: np.array([v]) for k, v in params.items()})[0]
    mask = np.ones(program.n_obs, dtype=bool)
    mask[[3, 4, 8, 12]] = False
    loglik = float(density.log_joint(x, mask=mask) - density.log_prior(x))
    cov = ar1_covariance(program.chain_start, 0.03, 0.5)[np.ix_(mask, mask)]
    expected = multivariate_normal(np.zeros(mask.sum()), cov).logpdf(resid[mask])
    assert loglik == pytest.approx(expected, rel=1e-9)
    pointwise = np.asarray(density.log_likelihood(x))  # full data: conditional terms
    assert pointwise.sum() == pytest.approx(
        multivariate_normal(np.zeros(program.n_obs), ar1_covariance(program.chain_start, 0.03, 0.5)).logpdf(resid),
        rel=1e-9)


def test_draws_have_the_stationary_lag_one_correlation():
    start = np.zeros(4000, dtype=bool)
    start[::400] = True
    draws = np.asarray(AR1Residuals(np.zeros(4000), 1.0, 0.7, start).sample(jax.random.PRNGKey(3), (50,)))
    inside = ~start[1:]
    pairs = np.stack([draws[:, :-1][:, inside].ravel(), draws[:, 1:][:, inside].ravel()])
    # 50 × 3990 pairs: the sd of the lag-one correlation estimate is about (1-ρ²)/sqrt(n) ≈ 0.001
    assert np.corrcoef(pairs)[0, 1] == pytest.approx(0.7, abs=0.01)
    assert draws.var() == pytest.approx(1.0 / (1 - 0.7**2), rel=0.05)
    assert abs(np.corrcoef(draws[:, 399], draws[:, 400])[0, 1]) < 0.35  # across trajectories: independent


def test_ar1_needs_a_trajectory_group(dataset_factory):
    ds = dataset_factory({"velocity": np.linspace(-1, 1, 10)}, np.linspace(-1, 1, 10))
    with pytest.raises(DataError, match="ar1.*trajectory"):
        build_program(get_law("coulomb_viscous"), ds, noise=Noise(kind="ar1"))


@pytest.mark.slow
def test_recovers_rho_and_evidence_and_loo_prefer_ar1(simulator):
    # simulated: 4 sweeps of 60 points, ρ = 0.8 (SIMULATED data, known truth)
    law, ds, truth, sigma = _coulomb_viscous_data(simulator, rho=0.8)
    fits = {}
    for kind in ("ar1", "normal"):
        noise = Noise(kind=kind)
        dt = fit(law, ds, noise=noise, draws=400, tune=400, chains=2, seed=0)
        verdict = check(dt)
        assert verdict.rhat_max < 1.05 and verdict.divergences == 0, str(verdict)
        fits[kind] = (build_program(law, ds, noise=noise), dt)
    post = fits["ar1"][1]["posterior"]
    for name, value in {**truth, "rho": 0.8, "sigma": sigma}.items():
        lo, hi = np.quantile(np.asarray(post[name].values).ravel(), [0.05, 0.95])
        assert lo <= value <= hi, f"{name}: truth {value} outside 90 % interval [{lo:.4g}, {hi:.4g}]"
    z = {k: bridge_log_evidence(p, dt) for k, (p, dt) in fits.items()}
    assert z["ar1"].log_z - z["normal"].log_z > 10 * (z["ar1"].error + z["normal"].error + 1.0), z
    # PSIS-LOO of the conditional pointwise terms (one-step-ahead predictive) also prefers AR(1)
    loo = {k: psis_loo(dt, ds, program=p) for k, (p, dt) in fits.items()}
    assert loo["ar1"].elpd - loo["normal"].elpd > 4 * np.hypot(loo["ar1"].se, loo["normal"].se), loo


def test_predictive_draws_are_one_step_ahead_given_the_data():
    start = two_trajectories(6, 4)
    y = np.random.default_rng(5).normal(size=10)
    mu = np.linspace(-1, 1, 10)
    sigma, rho = 0.2, 0.9
    draws = np.asarray(AR1Residuals(mu, sigma, rho, start, past=y).sample(jax.random.PRNGKey(0), (20000,)))
    expected = mu + np.r_[0.0, rho * (y - mu)[:-1]] * ~start
    sd = np.where(start, sigma / np.sqrt(1 - rho**2), sigma)
    np.testing.assert_allclose(draws.mean(axis=0), expected, atol=4 * sd.max() / np.sqrt(20000) * 1.5)
    np.testing.assert_allclose(draws.std(axis=0), sd, rtol=0.03)
