"""emcee backend: affine-invariant ensemble moves on the JAX-jitted log density of the same
numpyro program, in the unconstrained space numpyro uses for NUTS."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from scipy.optimize import minimize

from bayesfric.inference.datatree import assemble
from bayesfric.model import Program

__all__ = ["sample_emcee"]


def _map_point(value_and_grad, x0: np.ndarray) -> np.ndarray:
    """Posterior mode in unconstrained space (L-BFGS on the compiled ``-log density`` and its gradient)."""

    def fun(x):
        value, grad = value_and_grad(jnp.asarray(x))
        return float(value), np.asarray(grad, dtype=float)

    result = minimize(fun, x0, jac=True, method="L-BFGS-B")
    return result.x if np.all(np.isfinite(result.x)) else x0


def sample_emcee(
    program: Program,
    ds: xr.Dataset,
    *,
    draws: int = 2500,
    tune: int = 2500,
    walkers: int | None = None,
    thin: int = 10,
    seed: int = 0,
    progress: bool = False,
) -> xr.DataTree:
    """Sample with emcee's stretch/DE moves and return the fit's DataTree.

    Walkers are reported as chains (``chains = walkers``); ``draws`` counts kept steps *before*
    thinning by ``thin``, so each walker contributes ``draws // thin`` draws. Walkers start in a
    small ball around the posterior mode (found with L-BFGS from the prior median): started
    from the prior, walkers stranded in secondary modes keep R-hat high for thousands of steps.
    Defaults: ``walkers = max(32, 4 * ndim)``.
    """
    import emcee  # here, not at the top: `bayesfric fit` with NUTS never needs it (30 ms of its import)

    density = program.density(seed)
    ndim = density.dim
    n_walkers = walkers or max(32, 4 * ndim)
    log_prob_batch = density.log_joint_batch

    def log_prob(x):
        lp = np.asarray(log_prob_batch(jnp.asarray(x)))
        return np.where(np.isfinite(lp), lp, -np.inf)

    rng = np.random.default_rng(seed)
    centre = _map_point(density.neg_value_and_grad, np.asarray(density.x0))
    p0 = centre + 1e-3 * rng.standard_normal((n_walkers, ndim))
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(n_walkers, ndim, log_prob, vectorize=True, moves=moves)
    sampler.random_state = np.random.RandomState(seed).get_state()  # reproducible moves
    state = sampler.run_mcmc(p0, tune, progress=progress)
    sampler.reset()
    sampler.run_mcmc(state, draws, progress=progress, thin_by=1)
    chain = sampler.get_chain(thin=thin)  # (steps, walkers, ndim)
    chain = np.swapaxes(chain, 0, 1)  # (walkers, steps, ndim)
    w, s, _ = chain.shape
    constrained = jax.vmap(density.constrain)(jnp.asarray(chain.reshape(w * s, ndim)))
    samples = {k: np.asarray(v).reshape((w, s) + np.shape(v)[1:]) for k, v in constrained.items()}
    lp = np.swapaxes(sampler.get_log_prob(thin=thin), 0, 1)
    stats = {
        "lp": lp,
        "acceptance_fraction": np.repeat(sampler.acceptance_fraction[:, None], s, axis=1),
    }
    settings = dict(draws=draws, tune=tune, walkers=n_walkers, thin=thin,
                    moves="DE 0.8 + DESnooker 0.2")
    return assemble(program, ds, samples, stats, sampler="emcee", settings=settings, seed=seed)
