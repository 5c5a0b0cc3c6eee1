"""Initial points of the NUTS chains: prior medians (default), or multi-path Pathfinder.

``"median"`` (default): each chain starts at the median of 15 prior draws of its own seed
(numpyro's ``init_to_median``), in the bulk of the prior. On most laws all chains reach the
posterior during the warm-up. On posteriors with minor modes a chain can settle in one: on
simulated two-element GMS loops (520 points, ``tests/laws/test_slip.py``) one chain in four stayed
at F_c = 0.66, σ2 = 12 (truth 1.0, 2.0), with a log density ~900 nats below the others', and the
fit failed the gate (R-hat 1.58).

``"pathfinder"``: multi-path Pathfinder (Zhang, Carpenter, Gelman & Vehtari 2022, JMLR 23(306),
§3.3), built from blackjax's public L-BFGS pieces (``blackjax.optimizers.lbfgs``: the optimiser,
the inverse-Hessian factors and the Gaussian draws that ``blackjax.vi.pathfinder.approximate``
uses). From :data:`PATHS` prior-median starts, each path follows L-BFGS towards a mode and fits a
Gaussian approximation at every iterate; the iterate whose :data:`ELBO_DRAWS` draws give the
highest ELBO is the path's approximation. The pooled :data:`DRAWS_PER_PATH` draws of all paths are
importance-weighted (``log p − log q``) and the chains start at draws resampled by weight, without
replacement. A path that stopped in a minor mode gets a negligible weight, so no chain starts
there. Plain importance weights, not Pareto-smoothed ones as in the paper: the draws only choose
starting points, the warm-up and the gate follow. On the GMS loops above all four chains then
passed the gate (R-hat 1.009). The starts lie close together: the chains' independence, and so
R-hat, rests on the warm-up from there with different random keys.

**Memory.** ``blackjax.vi.pathfinder.approximate`` evaluates the log density at every draw of
every iterate at once (101 iterates × 200 draws, vmapped again over the paths: 161 600
evaluations of every data row side by side); on 800 rows of tribometer loops a LuGre study
peaked at 16.7 GB. Here every stage evaluates the log density at no more than
``limits.INIT_NUMBERS // rows`` points at once (:func:`plan`): the paths' L-BFGS runs and the
draws are mapped in batches (``jax.lax.map``), the iterates one after another, and iterates past a
path's last step are skipped. The numbers are those of blackjax's approximation (same keys, same
iterates: ``tests/test_init_memory.py``); only the order of evaluation changes. Data with more
rows than :data:`~bayesfric.limits.INIT_NUMBERS` cannot be evaluated once within the budget: the
chains then start at prior medians, with a warning saying so.

Pathfinder's two stages (:func:`stages`) are compiled once per program and plan
(:func:`bayesfric.exported.program_jit`) and run before the sampler; the engine's compiled sampler
is unchanged (its starts are an argument).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from blackjax.optimizers.lbfgs import bfgs_sample, lbfgs_inverse_hessian_factors, minimize_lbfgs

from bayesfric.density import median_starts, pending_median_starts, start_seeds
from bayesfric.errors import UserError
from bayesfric.exported import program_jit
from bayesfric.limits import INIT_NUMBERS
from bayesfric.model import Program

__all__ = ["INITS", "PATHS", "Plan", "plan", "chain_starts", "pending_chain_starts", "pathfinder_starts", "multipath",
           "stages"]

Init = Literal["median", "pathfinder"]
INITS: tuple[str, ...] = ("median", "pathfinder")
PATHS = 8  #: Pathfinder paths (each from its own prior-median start)
DRAWS_PER_PATH = 100  #: draws of each path's Gaussian approximation, pooled for the resampling
ELBO_DRAWS = 200  #: draws per L-BFGS iterate for its ELBO (blackjax's default ``num_samples``)
MAXITER = 100  #: L-BFGS iterations per path
MAXCOR = 10  #: L-BFGS history size (blackjax's default, as are the tolerances below)
GTOL, FTOL, MAXLS = 1e-8, 1e-5, 1000


Stage = Callable[..., tuple[jax.Array, ...]]


class Plan(NamedTuple):
    """How many log-density evaluations (each over every data row) Pathfinder runs at once."""

    paths_at_once: int  #: L-BFGS paths mapped side by side (one gradient each)
    draws_at_once: int  #: draws whose log density is evaluated side by side


def plan(rows: int, paths: int = PATHS, budget: int = INIT_NUMBERS) -> Plan | None:
    """Batch sizes that keep ``evaluations at once × rows ≤ budget`` in every stage.

    Parameters
    ----------
    rows : int
        Data rows of one log-density evaluation.
    paths : int
        Pathfinder paths.
    budget : int
        Row evaluations at once (default :data:`bayesfric.limits.INIT_NUMBERS`).

    Returns
    -------
    Plan or None
        None when one evaluation alone has more rows than ``budget``.
    """
    at_once = budget // max(rows, 1)
    if at_once < 1:
        return None
    return Plan(min(paths, at_once), min(max(ELBO_DRAWS, DRAWS_PER_PATH), at_once))


def chain_starts(program: Program, chains: int, seed: int, init: Init = "median") -> jax.Array:
    """Flat unconstrained starting points ``(chains, dim)`` of the NUTS chains (see the module notes)."""
    if init not in INITS:
        raise UserError(f"unknown init {init!r}; choose one of {', '.join(INITS)}", "init")
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


def pathfinder_starts(program: Program, chains: int, seed: int, paths: int = PATHS,
                      budget: int = INIT_NUMBERS) -> jax.Array:
    """``chains`` starting points resampled from multi-path Pathfinder draws (see the module notes).

    Falls back to the prior-median starts, with a warning, when one log-density evaluation
    exceeds ``budget`` (:func:`plan`) or no path gives a finite weight.
    """
    starts = median_starts(program, start_seeds(seed, max(paths, chains)))
    chosen = plan(program.n_obs, len(starts), budget)
    if chosen is None:
        warnings.warn(f"Pathfinder skipped for {program.law.name!r}: one evaluation of its {program.n_obs} rows "
                      f"exceeds the initialisation budget of {budget} row evaluations (limits.INIT_NUMBERS); "
                      f"chains start at prior medians", stacklevel=2)
        return starts[:chains]
    density = program.density(seed)
    what = f"pathfinder maxiter={MAXITER} paths_at_once={chosen.paths_at_once}"
    optimise, approximate = stages(density.log_joint, chosen)
    paths = program_jit(program, f"{what} lbfgs", optimise, optimised=True)(starts)
    what += f" draws={DRAWS_PER_PATH} elbo_draws={ELBO_DRAWS} draws_at_once={chosen.draws_at_once}"
    keys = jax.random.split(jax.random.PRNGKey(seed), len(starts))
    draws, log_w = program_jit(program, what, approximate, optimised=True)(keys, *paths)
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


def multipath(log_joint: Callable[[jax.Array], jax.Array], chosen: Plan,
              draws: int = DRAWS_PER_PATH) -> Callable[[jax.Array, jax.Array], tuple[jax.Array, jax.Array]]:
    """``(keys, starts) -> (draws, log weights)`` of every path, ``(paths, draws, dim)`` and
    ``(paths, draws)``: the two :func:`stages` in one function."""
    optimise, approximate = stages(log_joint, chosen, draws)
    return lambda keys, starts: approximate(keys, *optimise(starts))


def stages(log_joint: Callable[[jax.Array], jax.Array], chosen: Plan,
           draws: int = DRAWS_PER_PATH) -> tuple[Stage, Stage]:
    """Pathfinder's two stages, each evaluating at most the plan's numbers of points at once.

    ``optimise(starts)``: every path's L-BFGS history ``(x, g, alpha, update_mask, iterations)``,
    ``chosen.paths_at_once`` paths side by side. ``approximate(keys, *history)``: each path's best
    Gaussian approximation (:func:`best_iterate`) and ``draws`` draws of it with their log importance
    weights, ``(paths, draws, dim)`` and ``(paths, draws)``. Path ``p`` uses ``k_fit, k_draw =
    split(keys[p])`` as ``blackjax.vi.pathfinder.approximate`` (``k_fit``) and ``sample``
    (``k_draw``) would. Compiled apart, the two take less memory to compile than one program
    (LuGre, 800 rows: 1.09 GB peak against 1.34 GB).
    """
    def log_p(points: jax.Array) -> jax.Array:
        return jax.lax.map(log_joint, points, batch_size=min(chosen.draws_at_once, points.shape[0]))

    def lbfgs(x0: jax.Array) -> tuple[jax.Array, ...]:
        last, history = minimize_lbfgs(lambda x: -log_joint(x), x0, MAXITER, MAXCOR, GTOL, FTOL, MAXLS)
        return history.x, history.g, history.alpha, history.update_mask, last.state.iter_num

    def one_path(args: tuple[jax.Array, ...]) -> tuple[jax.Array, jax.Array]:
        key, *path = args
        k_fit, k_draw = jax.random.split(key)
        approximation = best_iterate(k_fit, *path, log_p)
        phi, log_q = bfgs_sample(k_draw, draws, *approximation)
        return phi, log_p(phi) - log_q

    def optimise(starts: jax.Array) -> tuple[jax.Array, ...]:
        return jax.lax.map(lbfgs, starts, batch_size=min(chosen.paths_at_once, starts.shape[0]))

    def approximate(keys: jax.Array, *paths: jax.Array) -> tuple[jax.Array, ...]:
        return jax.lax.map(one_path, (keys, *paths))

    return optimise, approximate


def best_iterate(key: jax.Array, x: jax.Array, g: jax.Array, alpha: jax.Array, update_mask: jax.Array,
                 iterations: jax.Array, log_p: Callable[[jax.Array], jax.Array]) -> tuple[jax.Array, ...]:
    """``(position, gradient, alpha, beta, gamma)`` of the L-BFGS iterate whose Gaussian
    approximation has the highest ELBO (Pathfinder's Algorithm 1, as in
    ``blackjax.vi.pathfinder.approximate``), one iterate after another; iterates from
    ``iterations`` on are not evaluated (their ELBO is −∞, as there)."""
    s = jnp.where(update_mask[1:], jnp.diff(x, axis=0), 0.0)
    z = jnp.where(update_mask[1:], jnp.diff(g, axis=0), 0.0)
    s = jnp.pad(s, ((MAXCOR, 0), (0, 0)))
    z = jnp.pad(z, ((MAXCOR, 0), (0, 0)))

    def factors(i: jax.Array) -> tuple[jax.Array, jax.Array]:
        window = i + jnp.arange(MAXCOR)
        return lbfgs_inverse_hessian_factors(s[window].T, z[window].T, alpha[i])

    def elbo(args: tuple[jax.Array, jax.Array]) -> jax.Array:
        i, key_i = args

        def evaluate() -> jax.Array:
            phi, log_q = bfgs_sample(key_i, ELBO_DRAWS, x[i], g[i], alpha[i], *factors(i))
            return jnp.mean(log_p(phi) - log_q)

        return jax.lax.cond(i < iterations, evaluate, lambda: jnp.asarray(-jnp.inf, dtype=x.dtype))

    index = jnp.arange(MAXITER + 1)
    elbos = jax.lax.map(elbo, (index, jax.random.split(key, MAXITER + 1)))
    best = jnp.argmax(jnp.where(jnp.isfinite(elbos), elbos, -jnp.inf))
    beta, gamma = factors(best)
    return x[best], g[best], alpha[best], beta, gamma
