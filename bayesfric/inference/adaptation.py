"""One NUTS chain with Stan's windowed warm-up and the sampling phase in ONE ``lax.scan``.

Built from blackjax's public primitives only (present unchanged since blackjax 1.2):
``blackjax.nuts.init`` / ``blackjax.nuts.build_kernel`` for the transition,
``dual_averaging_adaptation`` for the step size and the Welford estimator
(``welford_algorithm``) for the inverse mass matrix, stepped along a schedule from
``build_schedule``. ``blackjax.window_adaptation(...).run`` followed by a sampling loop would
trace the NUTS kernel twice (once in each loop) and so compile it twice; stepping one kernel
through both phases compiles it once. The rules are Stan's, as in blackjax's own window
adaptation: fast windows adapt the step size by dual averaging; slow windows also accumulate
the Welford variance; at the end of each slow window the inverse mass matrix is replaced by the
window's (regularised) variance and dual averaging restarts from the current step size; the
sampling phase uses the averaged step size.

The schedule is *data*, not a constant of the compiled code: a ``(steps + draws, 4)`` integer
array of (stage 0 fast / 1 slow, slow-window end, active, sampling). Inactive steps leave the chain untouched
(a real ``lax.cond``, not evaluated work: the schedule is the same for every chain), so one
compiled sampler runs both a full Stan warm-up and a shorter warm-up that starts from a
previous posterior, with the same number of scan steps.

One rule differs from Stan's, so that the warm-up does not degrade as data grow:

* **How a window's estimate is regularised.** Stan (and blackjax's ``mass_matrix_adaptation``) shrinks a window's
  estimate towards ``1e-3 I``, an *absolute* scale: as data narrow the posterior, true
  variances fall far below that term (~1e-7 for log T_C of a Stribeck fit at 10⁵ rows), the
  metric is wrong by orders of magnitude and the steps per draw grow with the data. Here the
  estimate is shrunk towards ``1e-3`` times the *current* metric (its diagonal for a dense one)
  with Stan's weights ``n / (n + 5)`` and ``5 / (n + 5)``: the first window regularises towards
  ``1e-3 I`` as Stan does (the metric starts at the identity), later ones towards a thousandth
  of the scale already estimated.

* **The ``auto`` metric (the engine's default).** Every slow window estimates a *dense*
  covariance; the chain keeps it dense when the condition number κ of its correlation matrix
  exceeds :data:`DENSE_ABOVE` (20: a diagonal metric then needs about √κ times the leapfrog
  steps per U-turn) and the window has at least 10 draws per coordinate, else its diagonal,
  which is exactly the diagonal metric's estimate (:func:`_auto_metric`). The kernel gets
  blackjax's Gaussian metric of both forms and selects per call (:func:`_switching_metric`),
  so a chain none of whose windows went dense gets the diagonal metric's draws bit for bit
  (``tests/test_inference.py``; a chain dense in an early window only samples with its last
  window's diagonal but has moved differently on the way). Why not always dense: on curved or weakly identified
  posteriors (robot_joint ``coulomb_viscous``, the unwinder's ``thermal_vogel_power``) a dense
  metric passed the gate less often than the diagonal one.

* **Measured, not adopted: the Fisher diagonal.** :data:`DIAGONAL` = ``"fisher"`` estimates a
  diagonal metric as ``sqrt(Var[x] / Var[∇ log p])`` per coordinate (the Fisher-divergence
  diagonal nutpie uses, from positions and gradients: :func:`_fisher_metric`). It cut the steps
  per draw (Stribeck data 18.2 / 18.7 at 10³ / 10⁵ rows) and the warm-cache main job's fit stage
  (102 s against 183–242 s), but the draws are correspondingly more autocorrelated (robot_joint
  coulomb_viscous: 10.9 steps, bulk ESS 557, R-hat 1.011, against 19.0 steps, ESS 938, R-hat
  1.004): at a fixed number of draws the seed studies had 6 gate failures instead of 4. The
  default stays Stan's positions' variance; the benchmark shows both.

Measured on steady-state Stribeck data, 2 chains × (1000 + 1000), steps per draw at 10³ / 10⁵
rows: Stan's rules 26.5 / 52.5, relative regulariser 28.2 / 24.1 (fit 139.8 s against 301.1 s
at 10⁵), the same posterior throughout (``benchmarks/bench_scale_rows.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import blackjax
import jax
import jax.numpy as jnp
import numpy as np
from blackjax.adaptation.mass_matrix import welford_algorithm
from blackjax.adaptation.step_size import dual_averaging_adaptation
from blackjax.adaptation.window_adaptation import build_schedule
from blackjax.mcmc.metrics import Metric, gaussian_euclidean

from bayesfric.errors import UserError

__all__ = ["ChainDraws", "sampling_schedule", "nuts_chain", "chain_start", "chain_steps", "step_keys"]


class ChainDraws(NamedTuple):
    """Post-warm-up output of one chain (leading axis: draw)."""

    position: jax.Array
    diverging: jax.Array
    energy: jax.Array
    n_steps: jax.Array
    acceptance_rate: jax.Array
    dense_metric: jax.Array  # whether the step's metric was dense (``auto`` and ``dense`` metrics)


def sampling_schedule(steps: int, draws: int, active: int | None = None, warm: bool = True) -> np.ndarray:
    """``(steps + draws, 4)`` rows (stage, slow-window end, active, sampling) for :func:`nuts_chain`.

    The first ``steps`` rows are the warm-up, the last ``draws`` the sampling phase.
    ``active=None``: Stan's default warm-up over all ``steps`` (75-step fast window, doubling
    slow windows from 25 steps, 50-step final fast window). ``active=m ≤ steps``: the first
    ``steps - m`` rows are inactive and the last ``m`` form a shorter warm-up: with ``warm``
    (chains that start inside the posterior) a 50-step fast window, one slow window that
    re-estimates the mass matrix, and a 50-step fast window (``m`` ≥ 120); without, Stan's
    default warm-up of ``m`` steps (chains that start cold, e.g. from the prior median).
    """
    sampling = np.column_stack([np.zeros((draws, 2), dtype=int), np.ones((draws, 2), dtype=int)])
    if active is None:
        rows = np.asarray(build_schedule(steps), dtype=int).reshape(-1, 2)
        warm = np.column_stack([rows, np.ones(steps, dtype=int), np.zeros(steps, dtype=int)])
        return np.vstack([warm, sampling])
    if not 120 <= active <= steps:
        raise UserError(f"a short warm-up needs 120 to {steps} steps (got {active})", "tune")
    if warm:
        short = np.asarray(build_schedule(active, initial_buffer_size=50, final_buffer_size=50,
                                          first_window_size=active - 100), dtype=int).reshape(-1, 2)
    else:
        short = np.asarray(build_schedule(active), dtype=int).reshape(-1, 2)
    idle = np.zeros((steps - active, 2), dtype=int)
    warm = np.column_stack([np.vstack([idle, short]),
                            np.r_[np.zeros(steps - active, dtype=int), np.ones(active, dtype=int)],
                            np.zeros(steps, dtype=int)])
    return np.vstack([warm, sampling])


class _Adaptation(NamedTuple):
    step_size: jax.Array
    inverse_mass_matrix: jax.Array
    dual_averaging: tuple
    mass_matrix: tuple


def nuts_chain(key, z0, logdensity, schedule, init_imm, target_accept: float, depth: int,
               auto: bool = False) -> ChainDraws:
    """Warm up and sample one chain along ``schedule`` (rows of :func:`sampling_schedule`).

    ``init_imm`` is the initial inverse mass matrix: a vector for a diagonal metric (ones, or a
    previous posterior's unconstrained variances), a square matrix for a dense one (identity,
    or a previous posterior's covariance). The slow windows estimate the same kind (blackjax's
    Welford estimator, regularised towards a thousandth of the current metric: the module
    notes). Returns every step's
    output; the caller keeps the sampling rows (inactive rows return zeros).

    The same as :func:`chain_start` followed by :func:`chain_steps` over the whole schedule
    with ``step_keys(key, len(schedule))``; a caller that wants to report progress runs
    :func:`chain_steps` on consecutive slices of the schedule and keys instead (the same
    draws: the chain's carry and its per-step keys do not depend on the slicing).
    """
    carry = chain_start(z0, logdensity, init_imm, auto)
    _, out = chain_steps(carry, step_keys(key, schedule.shape[0]), schedule, logdensity, target_accept, depth, auto)
    return out


def step_keys(key, steps: int) -> jax.Array:
    """The per-step keys of a chain of ``steps`` scan steps (warm-up and sampling)."""
    return jax.random.split(key, steps)


def chain_start(z0, logdensity, init_imm, auto: bool = False) -> tuple:
    """The carry of a chain before its first step: NUTS state at ``z0`` and fresh adaptation.

    ``auto``: ``init_imm`` is a square matrix used as a diagonal metric while it is diagonal
    and as a dense one otherwise, and each slow window picks one of the two
    (:func:`_auto_metric`)."""
    mm_init = _estimator(init_imm, auto)[0]
    da_init = dual_averaging_adaptation(0.8)[0]  # the initial state does not depend on the target
    adapt0 = _Adaptation(jnp.asarray(1.0, dtype=z0.dtype), init_imm, da_init(1.0), mm_init(z0.shape[0]))
    # python scalars in blackjax's initial states become arrays: the carry is a function's output
    return jax.tree.map(jnp.asarray, (blackjax.nuts.init(z0, logdensity), adapt0))


def chain_steps(carry, keys, schedule, logdensity, target_accept: float, depth: int,
                auto: bool = False, dense_above=None) -> tuple[tuple, ChainDraws]:
    """Advance a chain's ``carry`` (:func:`chain_start`, the same ``auto``) by the rows of
    ``schedule`` with one key per row; return the new carry and every step's output (inactive
    rows: zeros). ``dense_above``: the ``auto`` metric's threshold (default
    :data:`DENSE_ABOVE`; an argument of the compiled code, so ``inf``, the diagonal metric,
    compiles nothing new)."""
    da_init, da_update, da_final = dual_averaging_adaptation(target_accept)
    _, mm_update, mm_final = _estimator(carry[1].inverse_mass_matrix, auto, dense_above)
    kernel = blackjax.nuts.build_kernel()
    metric_of = _switching_metric if auto else (lambda imm: imm)

    def adapt_step(adapt: _Adaptation, row, position, grad, acceptance_rate) -> _Adaptation:
        da = da_update(adapt.dual_averaging, acceptance_rate)
        mm = jax.lax.cond(row[0] == 1, lambda m: mm_update(m, position, grad), lambda m: m, adapt.mass_matrix)
        adapt = _Adaptation(jnp.exp(da.log_step_size), adapt.inverse_mass_matrix, da, mm)

        def close_window(a: _Adaptation) -> _Adaptation:
            imm, mm_restart = mm_final(a.mass_matrix, a.inverse_mass_matrix)
            da_restart = da_init(da_final(a.dual_averaging))
            return _Adaptation(jnp.exp(da_restart.log_step_size), imm, da_restart, mm_restart)

        return jax.lax.cond(row[1] == 1, close_window, lambda a: a, adapt)

    def move(carry, k, row):
        state, adapt = carry
        sampling = row[3] == 1  # adaptation frozen; the averaged step size of the warm-up
        step_size = jnp.where(sampling, da_final(adapt.dual_averaging), adapt.step_size)
        imm = adapt.inverse_mass_matrix
        state, info = kernel(k, state, logdensity, step_size, metric_of(imm), max_num_doublings=depth)
        updated = adapt_step(adapt, row, state.position, state.logdensity_grad, info.acceptance_rate)
        adapt = jax.tree.map(lambda old, new: jnp.where(sampling, old, new), adapt, updated)
        out = ChainDraws(state.position, info.is_divergent, info.energy, info.num_integration_steps,
                         info.acceptance_rate, _is_dense(imm))
        return (state, adapt), out

    def idle(carry):  # an inactive row: the chain untouched, zeros for the step's output
        position = carry[0].position
        return carry, ChainDraws(jnp.zeros_like(position), jnp.zeros((), bool), jnp.zeros((), position.dtype),
                                 jnp.zeros((), int), jnp.zeros((), position.dtype), jnp.zeros((), bool))

    def step(carry, xs):
        k, row = xs
        return jax.lax.cond(row[2] == 1, lambda c: move(c, k, row), idle, carry)

    return jax.lax.scan(step, carry, (keys, schedule))


#: The diagonal metric's estimator: "fisher" (positions and gradients, :func:`_fisher_metric`) or
#: "welford" (positions only, Stan's).
DIAGONAL = "welford"
#: Stan's regularisation: a window of ``n`` draws gets weight ``n / (n + PSEUDO_COUNT)``, the
#: target ``SHRINK_TO`` times the current metric the rest.
PSEUDO_COUNT = 5.0
SHRINK_TO = 1e-3


def _scale_relative_metric(diagonal: bool):
    """(init, update, final) of the windowed metric estimate (blackjax's public Welford estimator).

    ``final(state, current)`` returns the window's regularised estimate, shrunk towards
    ``SHRINK_TO × current`` (its diagonal for a dense metric), and a fresh estimator state.
    """
    wc_init, wc_update, wc_final = welford_algorithm(diagonal)

    def final(state, current):
        covariance, count, _ = wc_final(state)
        return _regularised(covariance, count, current, diagonal), wc_init(covariance.shape[0])

    return wc_init, lambda state, position, grad: wc_update(state, position), final


def _regularised(estimate, count, current, diagonal: bool):
    target = SHRINK_TO * (current if diagonal else jnp.diag(jnp.diag(current)))
    return (count / (count + PSEUDO_COUNT)) * estimate + (PSEUDO_COUNT / (count + PSEUDO_COUNT)) * target


def _fisher_metric():
    """(init, update, final) of the diagonal estimate ``sqrt(Var[x] / Var[∇ log p])`` per
    coordinate over a window (the Fisher-divergence diagonal of Seyboldt et al., nutpie's
    default), from two of blackjax's public Welford estimators (positions and gradients);
    regularised as :func:`_scale_relative_metric` is. Exact for a Gaussian posterior, and it
    uses every gradient, so a short window estimates a narrow coordinate's scale better than
    the positions' variance alone."""
    wc_init, wc_update, wc_final = welford_algorithm(True)

    def final(state, current):
        var_x, count, _ = wc_final(state[0])
        var_g, _, _ = wc_final(state[1])
        ok = (var_x > 0) & (var_g > 0) & jnp.isfinite(var_x) & jnp.isfinite(var_g)
        estimate = jnp.where(ok, jnp.sqrt(jnp.where(ok, var_x, 1.0) / jnp.where(ok, var_g, 1.0)), current)
        n = var_x.shape[0]
        return _regularised(estimate, count, current, True), (wc_init(n), wc_init(n))

    return (lambda n: (wc_init(n), wc_init(n)),
            lambda state, position, grad: (wc_update(state[0], position), wc_update(state[1], grad)), final)


#: ``auto`` metric: a slow window's estimate is used dense when the condition number of its
#: correlation matrix exceeds this (a diagonal metric then needs about sqrt(κ) times the steps
#: of a dense one), and only from a window of at least ``DENSE_MIN_DRAWS_PER_DIM`` draws per
#: coordinate (the sample correlation of fewer draws is ill-conditioned by chance alone).
DENSE_ABOVE = 20.0
DENSE_MIN_DRAWS_PER_DIM = 10


def _estimator(init_imm, auto: bool, dense_above=None):
    """(init, update, final) of the windowed metric estimate of a chain started at ``init_imm``."""
    if auto:
        return _auto_metric(DENSE_ABOVE if dense_above is None else dense_above)
    if init_imm.ndim == 1 and DIAGONAL == "fisher":
        return _fisher_metric()
    return _scale_relative_metric(init_imm.ndim == 1)


def _auto_metric(dense_above):
    """(init, update, final) of the ``auto`` metric: the dense estimate of
    :func:`_scale_relative_metric`, kept dense where its correlations are strong (condition
    number of the correlation matrix above ``dense_above``) and cut to its diagonal
    otherwise, so a weakly correlated posterior samples with the diagonal metric it would have
    had (the diagonal of the dense estimate is the diagonal estimate)."""
    wc_init, wc_update, wc_final = welford_algorithm(False)

    def final(state, current):
        covariance, count, _ = wc_final(state)
        estimate = _regularised(covariance, count, current, False)
        scale = jnp.sqrt(jnp.diag(estimate))
        eigenvalues = jnp.linalg.eigvalsh(estimate / jnp.outer(scale, scale))
        kappa = eigenvalues[-1] / eigenvalues[0]
        dense = (jnp.isfinite(kappa) & (eigenvalues[0] > 0) & (kappa > dense_above)
                 & (count >= DENSE_MIN_DRAWS_PER_DIM * estimate.shape[0]))
        return jnp.where(dense, estimate, jnp.diag(jnp.diag(estimate))), wc_init(covariance.shape[0])

    return wc_init, lambda state, position, grad: wc_update(state, position), final


def _is_dense(imm) -> jax.Array:
    """Whether ``imm`` is used as a dense metric: a matrix with a nonzero off-diagonal entry."""
    if imm.ndim == 1:
        return jnp.zeros((), bool)
    return jnp.any(imm != jnp.diag(jnp.diag(imm)))


def _switching_metric(imm) -> Metric:
    """blackjax's Gaussian metric of the square matrix ``imm``: dense where it has a nonzero
    off-diagonal entry, else the diagonal metric of its diagonal, chosen per call by
    ``lax.cond`` (one branch runs; under ``vmap`` both run and one is selected)."""
    dense, diagonal, use_dense = gaussian_euclidean(imm), gaussian_euclidean(jnp.diag(imm)), _is_dense(imm)

    def pick(name: str):
        def picked(*args, **kwargs):
            return jax.lax.cond(use_dense, lambda *a: getattr(dense, name)(*a, **kwargs),
                                lambda *a: getattr(diagonal, name)(*a, **kwargs), *args)
        return picked

    return Metric(**{name: pick(name) for name in Metric._fields})
