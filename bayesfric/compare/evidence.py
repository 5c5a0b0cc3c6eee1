"""Log evidence (marginal likelihood) of a fitted law from two independent estimators.

* :func:`bridge_log_evidence` -- bridge sampling on the NUTS draws of a fit (Meng & Wong 1996,
  iterative scheme; Gronau et al. 2017 tutorial): a multivariate-normal proposal is fitted in
  numpyro's unconstrained space on the first half of every chain, the second half enters the
  bridge. Error: the relative mean-squared error approximation of Frühwirth-Schnatter (2004) as
  in the R package ``bridgesampling``; since d log Z ≈ dZ / Z, its square root is the Monte Carlo
  standard error of log Z in nats.
* :func:`smc_log_evidence` -- blackjax adaptive tempered SMC from the prior to the posterior
  (NUTS moves preconditioned by the particle covariance, step size adapted to the acceptance
  rate); log Z is the sum of the log mean incremental weights. Error: the standard error over a few independent runs.

The two share nothing but the model's unconstrained log density, so they check each other:
:func:`compare_estimators` flags a disagreement beyond a threshold and never averages them.

Both are Monte Carlo approximations. Their stated errors are Monte Carlo errors only: a bridge
proposal that misses posterior mass, or SMC moves that do not mix, bias an estimate without
widening its error. The disagreement flag is the guard against that.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import Any

import arviz as az
import blackjax
import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from blackjax.smc import adaptive_tempered, extend_params, resampling
from numpyro.infer import Predictive
from scipy.special import logsumexp
from scipy.stats import multivariate_normal

from bayesfric.errors import UserError
from bayesfric.inference.modes import by_mode, is_multimodal
from bayesfric.limits import CHUNK_NUMBERS
from bayesfric.model import Program

__all__ = ["Evidence", "EstimatorAgreement", "bridge_log_evidence", "smc_log_evidence", "compare_estimators"]


@dataclass(frozen=True)
class Evidence:
    """A log-evidence estimate in nats with its Monte Carlo standard error (also in nats)."""

    log_z: float
    error: float
    method: str
    diagnostics: dict[str, Any] = field(default_factory=dict)

    def __str__(self) -> str:
        return f"log Z = {self.log_z:.3f} ± {self.error:.3f} ({self.method})"


@dataclass(frozen=True)
class EstimatorAgreement:
    """Outcome of :func:`compare_estimators`; both estimates are kept, never averaged."""

    a: Evidence
    b: Evidence
    difference: float  # a.log_z - b.log_z, nats
    threshold: float
    agree: bool

    def __str__(self) -> str:
        verdict = "agree" if self.agree else "DISAGREE"
        return (f"{self.a.method} vs {self.b.method}: difference {self.difference:+.3f} nat "
                f"({verdict} at {self.threshold} nat)")


def _finite(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    return np.where(np.isfinite(x), x, -np.inf)


def chunked(log_joint_batch, rows: int):
    """``log_joint_batch`` (a compiled function of ``(n, dim)`` points) over chunks of at most
    ``CHUNK_NUMBERS // rows`` points, the last one padded to the same shape (one compilation):
    the log density of every point needs points × rows numbers at once otherwise (8000 importance
    draws × 10⁵ rows: 6.4 GB per intermediate array). One call, as before, while it fits."""
    size = max(1, CHUNK_NUMBERS // max(1, rows))

    def run(x) -> np.ndarray:
        x = np.asarray(x)
        if x.shape[0] <= size:
            return np.asarray(log_joint_batch(jnp.asarray(x)))
        out = []
        for a in range(0, x.shape[0], size):
            part = x[a:a + size]
            padded = np.concatenate([part, np.repeat(part[:1], size - part.shape[0], axis=0)])
            out.append(np.asarray(log_joint_batch(jnp.asarray(padded)))[: part.shape[0]])
        return np.concatenate(out)

    return run


# -- bridge sampling ------------------------------------------------------------------------------
def bridge_log_evidence(
    program: Program,
    dt: xr.DataTree,
    *,
    seed: int = 0,
    max_iter: int = 1000,
    tol: float = 1e-10,
) -> Evidence:
    """Bridge-sampling estimate of log p(y) from the posterior draws of a fit.

    Parameters
    ----------
    program : Program
        The program the fit sampled (same law, priors, noise and data).
    dt : xarray.DataTree
        The fit (its ``posterior`` group must hold every latent site of the program).
    seed : int
        Seed of the proposal draws.
    max_iter, tol : int, float
        Iterations and relative tolerance on log Z of the Meng-Wong fixed-point scheme.

    Returns
    -------
    Evidence
        ``log_z`` and ``error`` in nats; diagnostics: draws used, proposal draws, effective
        sample size of the bridge half, iterations, relative MSE of Z.

    Notes
    -----
    Iteration (Gronau et al. 2017, Eq. 4 with the ``bridgesampling`` choices)::

        r ← (1/N2) Σ_j l2_j / (s1 l2_j + s2 r)  /  (1/N1) Σ_i 1 / (s1 l1_i + s2 r)

    with l = q(θ)/g(θ) the unnormalised posterior over the proposal, at posterior (l1) and
    proposal (l2) draws, s1 = N_eff/(N_eff+N2), s2 = N2/(N_eff+N2). The relative MSE is
    Var(f1)/(N2 E[f1]²) + Var(f2)/(ESS(f2) E[f2]²) (Frühwirth-Schnatter 2004); ``bridgesampling``
    gets the autocorrelation factor of f2 from an AR spectral density at zero, here it is the
    arviz ESS of f2 over the chains (the same quantity, N / integrated autocorrelation time).

    A multimodal fit (:mod:`bayesfric.inference.modes`): per mode, on its own chains
    (``posterior_chains``) with its own proposal, log Z = log Σ_k Z_k (:func:`~bayesfric.inference.modes.by_mode`);
    not on the combined draws, whose modes are in stacking proportions, not posterior mass.
    """
    if is_multimodal(dt):
        return by_mode(dt, lambda part: bridge_log_evidence(program, part, seed=seed, max_iter=max_iter, tol=tol))
    density = program.density(seed)
    x = _unconstrained_draws(program, density, dt)
    n_chains, n_draws = x.shape[:2]
    half = n_draws // 2
    fit_half = x[:, :half].reshape(-1, density.dim)
    bridge_half = x[:, half : 2 * half]  # (chain, half, dim)
    n1 = n_chains * half
    n2 = n1

    mean = fit_half.mean(axis=0)
    cov = np.atleast_2d(np.cov(fit_half, rowvar=False))
    proposal = multivariate_normal(mean, cov, allow_singular=False)
    rng = np.random.default_rng(seed)
    proposal_draws = np.atleast_2d(proposal.rvs(size=n2, random_state=rng)).reshape(n2, density.dim)

    log_joint = chunked(density.log_joint_batch, program.n_obs)
    flat_bridge = bridge_half.reshape(-1, density.dim)
    q11 = _finite(log_joint(jnp.asarray(flat_bridge)))  # unnormalised posterior at posterior draws
    q12 = proposal.logpdf(flat_bridge).reshape(-1)  # proposal at posterior draws
    q21 = _finite(log_joint(jnp.asarray(proposal_draws)))
    q22 = proposal.logpdf(proposal_draws).reshape(-1)
    if not np.all(np.isfinite(q11)):
        raise UserError("non-finite log density at posterior draws; is the fit from this program?")

    ess = az.ess(xr.Dataset({"x": (("chain", "draw", "d"), bridge_half)}), method="bulk")["x"]
    n_eff = float(np.median(np.asarray(ess)))
    n_eff = min(max(n_eff, 1.0), float(n1))
    log_z, n_iter = _meng_wong(q11 - q12, q21 - q22, n1, n2, n_eff, max_iter, tol)
    re2 = _relative_mse(q11 - log_z, q12, q21 - log_z, q22, n1, n2, n_chains)
    diagnostics = {
        "n_posterior_bridge": n1, "n_proposal": n2, "n_posterior_fit": int(fit_half.shape[0]),
        "n_eff": n_eff, "iterations": n_iter, "relative_mse": float(re2), "dim": density.dim,
        "proposal": "multivariate normal in numpyro's unconstrained space",
    }
    return Evidence(float(log_z), float(np.sqrt(re2)), "bridge", diagnostics)


def _unconstrained_draws(program: Program, density, dt: xr.DataTree) -> np.ndarray:
    """The fit's posterior draws in numpyro's unconstrained space, ``(chain, draw, dim)``."""
    post = dt["posterior"].to_dataset()
    missing = [s for s in density.sites if s not in post]
    if missing:
        raise UserError(
            f"fit posterior lacks latent site(s) {missing} of law {program.law.name!r}"
        )
    n_chains, n_draws = post.sizes["chain"], post.sizes["draw"]
    if n_draws // 2 < 20:
        raise UserError(f"bridge sampling needs at least 40 draws per chain, got {n_draws}", "draws")
    constrained = {s: np.asarray(post[s].values).reshape((n_chains * n_draws,) + post[s].shape[2:])
                   for s in density.sites}
    return np.asarray(density.to_unconstrained(constrained)).reshape(n_chains, n_draws, density.dim)


def _relative_mse(lp_p, lg_p, lp_g, lg_g, n1: int, n2: int, n_chains: int) -> float:
    """Frühwirth-Schnatter (2004) relative MSE of Z (all ratios in log space): ``lp``/``lg`` are
    the normalised posterior and the proposal at the posterior (``_p``) and proposal (``_g``) draws."""
    s1, s2 = n1 / (n1 + n2), n2 / (n1 + n2)
    f1 = np.exp(lp_g - np.logaddexp(np.log(s1) + lp_g, np.log(s2) + lg_g))
    f2 = np.exp(lg_p - np.logaddexp(np.log(s1) + lp_p, np.log(s2) + lg_p))
    ess_f2 = float(az.ess(xr.Dataset({"f": (("chain", "draw"), f2.reshape(n_chains, -1))}),
                          method="mean")["f"])
    ess_f2 = min(max(ess_f2, 1.0), float(n1))
    return (np.var(f1, ddof=1) / (n2 * np.mean(f1) ** 2)
            + np.var(f2, ddof=1) / (ess_f2 * np.mean(f2) ** 2))


def _meng_wong(l1, l2, n1, n2, n_eff, max_iter, tol) -> tuple[float, int]:
    """Meng-Wong fixed point for log r, in log space; l1, l2 are log q/g at both draw sets."""
    s1, s2 = n_eff / (n_eff + n2), n2 / (n_eff + n2)
    log_s1, log_s2 = np.log(s1), np.log(s2)
    log_r = float(np.median(l1))  # start at a typical value (bridgesampling: lstar)
    for it in range(1, max_iter + 1):
        num = logsumexp(l2 - np.logaddexp(log_s1 + l2, log_s2 + log_r)) - np.log(n2)
        den = logsumexp(-np.logaddexp(log_s1 + l1, log_s2 + log_r)) - np.log(n1)
        new = num - den
        if not np.isfinite(new):
            raise FloatingPointError("bridge-sampling iteration diverged")
        if abs(new - log_r) < tol * max(1.0, abs(new)):
            return new, it
        log_r = new
    return log_r, max_iter


# -- tempered SMC ---------------------------------------------------------------------------------
def smc_log_evidence(
    program: Program,
    *,
    seed: int = 0,
    particles: int = 1000,
    runs: int = 4,
    target_ess: float = 0.9,
    mcmc_steps: int = 5,
    kernel: str = "nuts",
    mass_matrix: str = "dense",
    step_size: float = 0.5,
    target_accept: float = 0.8,
    integration_steps: int = 5,
    max_doublings: int = 6,
) -> Evidence:
    """Adaptive tempered SMC estimate of log p(y) (blackjax), independent of any fit.

    Parameters
    ----------
    program : Program
        The law bound to its data.
    seed : int
        Seed of the prior draws and of every SMC move.
    particles : int
        Particles per run.
    runs : int
        Independent runs (vectorised); the estimate is their mean log Z, the error its
        standard error over the runs (``runs >= 2``).
    target_ess : float
        Fraction of particles kept effective at each tempering step (sets the step size in
        temperature; higher means more, gentler steps and a smaller variance of log Z).
    mcmc_steps : int
        MCMC moves per tempering step.
    kernel : {"nuts", "hmc"}
        Move kernel. NUTS (default) adapts its path length per move and mixes hierarchical
        (funnel-shaped) posteriors where fixed-length HMC left log Z biased low by 1-2 nats in
        a 9-parameter test.
    mass_matrix : {"dense", "diagonal"}
        Inverse mass matrix of the moves, recomputed after every tempering step from the
        weighted particles: their covariance (default; friction laws have strongly correlated
        coefficients, e.g. the two terms of a coast-down, where the diagonal version left SMC
        runs scattered over ~10 nats) or only their variances.
    step_size : float
        Initial leapfrog step, in units of the particle spread. After every tempering step it is
        multiplied by ``exp(mean acceptance − target_accept)``, clipped to [1e-3, 2] (a
        Robbins–Monro-style rule; the moves stay valid MCMC for each stage's target whatever
        the step, the rule only keeps them efficient as the tempered posterior narrows).
    target_accept : float
        Mean acceptance probability the step-size rule aims for.
    integration_steps, max_doublings
        HMC path length; NUTS tree depth limit.

    Returns
    -------
    Evidence
        diagnostics: per-run log Z, tempering steps per run, final step sizes, settings.

    Notes
    -----
    Particles start as prior draws mapped to numpyro's unconstrained space; the tempered target
    is prior(x)·|J| · likelihood(x)^β with β chosen by blackjax's ESS solver. The mean of log Z
    over runs is biased low by about half its variance (Jensen); the reported error (standard
    error over runs) is the guide to whether that matters.
    """
    if runs < 2:
        raise UserError("smc_log_evidence needs runs >= 2 to estimate its error", "runs")
    if mass_matrix not in ("dense", "diagonal"):
        raise UserError(f"must be 'dense' or 'diagonal', not {mass_matrix!r}", "mass_matrix")
    density = program.density(seed)
    step_fn, init_fn, fixed, kernel_text = _move_kernel(kernel, integration_steps, max_doublings)

    def log_likelihood(x):
        return jnp.sum(density.log_likelihood(x))

    smc_kernel = adaptive_tempered.build_kernel(density.log_prior, log_likelihood, step_fn, init_fn,
                                                resampling.systematic, target_ess)
    move_parameters = partial(_move_parameters, dense=mass_matrix == "dense", fixed=fixed)
    one_run = partial(_one_run, smc_kernel, move_parameters, partial(_prior_particles, program, density, particles),
                      particles=particles, mcmc_steps=mcmc_steps, step_size=step_size, target_accept=target_accept)
    keys = jax.random.split(jax.random.PRNGKey(seed), runs)
    log_zs, steps, final_steps = jax.jit(jax.vmap(one_run))(keys)
    log_zs = np.asarray(log_zs, dtype=float)
    if not np.all(np.isfinite(log_zs)):
        raise FloatingPointError(f"non-finite SMC log evidence in some runs: {log_zs}")
    diagnostics = {
        "run_log_z": log_zs.tolist(), "tempering_steps": np.asarray(steps).tolist(),
        "final_step_size": np.asarray(final_steps).tolist(),
        "particles": particles, "runs": runs, "target_ess": target_ess, "mcmc_steps": mcmc_steps,
        "kernel": f"{kernel_text}, {mass_matrix} mass matrix from the weighted particles, "
                  f"step size adapted to acceptance {target_accept}",
    }
    error = float(np.std(log_zs, ddof=1) / np.sqrt(runs))
    return Evidence(float(np.mean(log_zs)), error, "smc", diagnostics)


def _move_kernel(kernel: str, integration_steps: int, max_doublings: int) -> tuple:
    """The SMC move's blackjax step and init functions, its fixed parameters and its description."""
    if kernel == "nuts":
        step_fn = partial(blackjax.nuts.build_kernel(), max_num_doublings=max_doublings)
        return step_fn, blackjax.nuts.init, {}, f"NUTS, ≤ 2^{max_doublings} leapfrog steps"
    if kernel == "hmc":
        return (blackjax.hmc.build_kernel(), blackjax.hmc.init, {"num_integration_steps": integration_steps},
                f"HMC, {integration_steps} leapfrog steps")
    raise UserError(f"must be 'nuts' or 'hmc', not {kernel!r}", "kernel")


def _prior_particles(program: Program, density, particles: int, key):
    """``particles`` prior draws of the program's sites, in numpyro's unconstrained space."""
    predictive = Predictive(program.model, num_samples=particles, return_sites=density.sites)
    draws = predictive(key, **dict(program.model_kwargs, response=None))
    return density.to_unconstrained({k: draws[k] for k in density.sites})


def _move_parameters(x, log_weights, step, *, dense: bool, fixed: dict):
    """The moves' parameters from the weighted particles: their (dense or diagonal) covariance as
    inverse mass matrix, the step size and the kernel's fixed parameters."""
    w = jax.nn.softmax(log_weights)
    centred = x - w @ x
    if dense:
        cov = (centred * w[:, None]).T @ centred
        cov = cov + 1e-10 * jnp.eye(x.shape[1]) * jnp.maximum(jnp.trace(cov), 1e-12)
    else:
        cov = jnp.diag(w @ centred**2)
    return extend_params({"inverse_mass_matrix": cov, "step_size": step, **fixed})


def _one_run(smc_kernel, move_parameters, prior_particles, key, *, particles: int, mcmc_steps: int,
             step_size: float, target_accept: float):
    """One tempered run from prior draws to β = 1: its log Z, tempering steps and final step size."""
    key_prior, key_smc = jax.random.split(key)
    x0 = prior_particles(key_prior)
    uniform = jnp.zeros(particles)

    def not_done(carry):
        return carry[0].tempering_param < 1.0

    def step(carry):
        state, params, key, log_z, n = carry
        key, sub = jax.random.split(key)
        state, info = smc_kernel(sub, state, mcmc_steps, params)
        accept = jnp.mean(info.update_info.acceptance_rate)
        new_step = jnp.clip(params["step_size"][0] * jnp.exp(accept - target_accept), 1e-3, 2.0)
        params = move_parameters(state.particles, jnp.log(state.weights), new_step)
        return state, params, key, log_z + info.log_likelihood_increment, n + 1

    state0 = adaptive_tempered.init(x0)
    carry = (state0, move_parameters(x0, uniform, jnp.asarray(step_size)), key_smc, jnp.zeros(()),
             jnp.zeros((), dtype=jnp.int32))
    _, params, _, log_z, n = jax.lax.while_loop(not_done, step, carry)
    return log_z, n, params["step_size"][0]


def compare_estimators(a: Evidence, b: Evidence, *, z: float = 3.0, floor: float = 0.2) -> EstimatorAgreement:
    """Flag two log-evidence estimates of one model that differ beyond their combined error.

    They agree when ``|a − b| ≤ max(z · sqrt(se_a² + se_b²), floor)`` and neither estimator
    marked itself unreliable (``diagnostics["reliable"] is False``, e.g. importance weights with
    Pareto-k̂ > 0.7). The floor: each estimator is held to 0.1 nat of exact evidences in the
    tests, so two sound estimates may differ by up to 0.2 nat through biases that their Monte
    Carlo errors do not contain. The estimates are never averaged: a disagreement means at least
    one of them is biased (a poor proposal, a multimodal posterior), the report shows both and
    the law leaves the evidence ranking.
    """
    difference = a.log_z - b.log_z
    threshold = max(z * float(np.hypot(a.error, b.error)), floor)
    reliable = all(e.diagnostics.get("reliable", True) for e in (a, b))
    agree = bool(abs(difference) <= threshold and reliable)
    return EstimatorAgreement(a, b, float(difference), float(threshold), agree)
