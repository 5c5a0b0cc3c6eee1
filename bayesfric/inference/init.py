"""Initial points of the NUTS chains: prior medians (default), or multi-path Pathfinder.

``"median"`` (default): each chain starts at the median of 15 prior draws of its own seed
(numpyro's ``init_to_median``), in the bulk of the prior. On most laws all chains reach the
posterior during the warm-up. On posteriors with minor modes a chain can settle in one: on
simulated two-element GMS loops (520 points, ``tests/laws/test_slip.py``) one chain in four stayed
at F_c = 0.66, σ2 = 12 (truth 1.0, 2.0), with a log density ~900 nats below the others', and the
fit failed the gate (R-hat 1.58).

``"pathfinder"``: multi-path Pathfinder (Zhang, Carpenter, Gelman & Vehtari 2022, JMLR 23(306),
§3.3), with blackjax's public ``blackjax.vi.pathfinder``. From :data:`PATHS` prior-median starts,
each path follows L-BFGS towards a mode and fits a Gaussian approximation along the way; the
pooled draws of all paths are importance-weighted (``log p − log q``) and the chains start at
draws resampled by weight, without replacement. A path that stopped in a minor mode gets a
negligible weight, so no chain starts there. Plain importance weights, not Pareto-smoothed ones
as in the paper: the draws only choose starting points, the warm-up and the gate follow. On the
GMS loops above all four chains then passed the gate (R-hat 1.009); Pathfinder cost 18 s
against the fit's 99 s (compilation included). The starts then lie close together: the chains'
independence, and so R-hat, rests on the warm-up from there with different random keys.

The Pathfinder program is compiled once per program (:func:`bayesfric.exported.program_jit`) and
runs before the sampler; the engine's compiled sampler is unchanged (its starts are an argument).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Literal

import blackjax
import jax
import jax.numpy as jnp
import numpy as np

from bayesfric.density import median_starts, pending_median_starts, start_seeds
from bayesfric.exported import program_jit
from bayesfric.model import Program

__all__ = ["INITS", "PATHS", "chain_starts", "pending_chain_starts", "pathfinder_starts"]

Init = Literal["median", "pathfinder"]
INITS: tuple[str, ...] = ("median", "pathfinder")
PATHS = 8  #: Pathfinder paths (each from its own prior-median start)
DRAWS_PER_PATH = 100  #: draws of each path's Gaussian approximation, pooled for the resampling
MAXITER = 100  #: L-BFGS iterations per path


def chain_starts(program: Program, chains: int, seed: int, init: Init = "median") -> jax.Array:
    """Flat unconstrained starting points ``(chains, dim)`` of the NUTS chains (see the module notes)."""
    if init not in INITS:
        raise ValueError(f"unknown init {init!r}; choose one of {', '.join(INITS)}")
    if init == "median":
        return median_starts(program, start_seeds(seed, chains))
    return pathfinder_starts(program, chains, seed)


def pending_chain_starts(program: Program, chains: int, seed: int, init: Init = "median") -> Callable[[], jax.Array]:
    """:func:`chain_starts` as a function to call later: prior-median starts compile in the
    background meanwhile (:func:`bayesfric.density.pending_median_starts`); Pathfinder runs now."""
    if init == "median":
        return pending_median_starts(program, start_seeds(seed, chains))
    starts = chain_starts(program, chains, seed, init)
    return lambda: starts


def pathfinder_starts(program: Program, chains: int, seed: int, paths: int = PATHS) -> jax.Array:
    """``chains`` starting points resampled from multi-path Pathfinder draws (see the module notes).

    Falls back to the prior-median starts, with a warning, when no path gives a finite weight.
    """
    density = program.density(seed)
    starts = median_starts(program, start_seeds(seed, max(paths, chains)))

    def all_paths(keys, starts):
        def one_path(key, x0):
            k_fit, k_draw = jax.random.split(key)
            state, _ = blackjax.vi.pathfinder.approximate(k_fit, density.log_joint, x0, maxiter=MAXITER)
            draws, log_q = blackjax.vi.pathfinder.sample(k_draw, state, DRAWS_PER_PATH)
            return draws, jax.vmap(density.log_joint)(draws) - log_q

        return jax.vmap(one_path)(keys, starts)

    what = f"pathfinder draws={DRAWS_PER_PATH} maxiter={MAXITER}"
    draws, log_w = program_jit(program, what, all_paths)(jax.random.split(jax.random.PRNGKey(seed), len(starts)),
                                                         starts)
    draws = np.asarray(draws).reshape(-1, density.dim)
    log_w = np.asarray(log_w).ravel()
    finite = np.isfinite(log_w) & np.isfinite(draws).all(axis=1)
    if not finite.any():
        warnings.warn(f"Pathfinder found no finite draw for {program.law.name!r}; chains start at prior medians",
                      stacklevel=2)
        return starts[:chains]
    weights = np.where(finite, np.exp(log_w - log_w[finite].max()), 0.0)
    weights /= weights.sum()
    rng = np.random.default_rng(seed)
    replace = int((weights > 0).sum()) < chains
    return jnp.asarray(draws[rng.choice(weights.size, size=chains, replace=replace, p=weights)])
