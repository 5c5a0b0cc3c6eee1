"""What a law predicted at the points a fold held out: the raw material of model-form error.

A blocked extrapolation fold trains a law inside part of the tested envelope and scores it
beyond. Its log predictive density says *how much* worse the law is out there; sizing also needs
*how far* its mean curve missed, per point and with its own uncertainty, to widen an
extrapolated answer by the miss the data measured (:mod:`bayesfric.sizing.calibration`).

:func:`heldout_predictive` keeps, per held-out point, thinned draws of the fold posterior's mean
function (group offsets included, exactly as in the model) and the mean noise variance of the
program's own observation distribution (:meth:`bayesfric.model.Program.observation`). Draws and
points are thinned to :data:`MAX_DRAWS` × :data:`MAX_POINTS` (evenly spaced), so what is kept
does not grow with the data; the covariance of the misses across points is estimated from
those draws. The mean function runs over every row (a law's row may depend on the rows before
it) in chunks of draws of at most ``limits.CHUNK_NUMBERS`` draws × rows, so computing it does
not grow with draws × rows either (one chunk, as before, up to 10 485 rows).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from bayesfric.hierarchy import law_mean, site_names
from bayesfric.limits import CHUNK_NUMBERS
from bayesfric.model import Program

__all__ = ["MAX_DRAWS", "MAX_POINTS", "HeldOut", "heldout_predictive"]

#: Posterior draws of each fold kept per held-out point (evenly thinned).
MAX_DRAWS = 400
#: Held-out points kept per scheme (evenly spaced in data order).
MAX_POINTS = 1000


@dataclass(frozen=True)
class HeldOut:
    """Fold-posterior predictive at held-out points (kept points in data order).

    Attributes
    ----------
    index : ndarray of int, shape (m,)
        Row of each kept point in the data.
    fold : ndarray of int, shape (m,)
        Fold whose posterior predicted the point (draws of different folds are independent).
    mu : ndarray, shape (S, m)
        Thinned draws of the mean function (signed, group offsets included).
    noise_var : ndarray, shape (m,)
        Posterior mean of the observation variance (a Student-t draw with ``nu ≤ 2``, which
        has none, counts with its squared scale).
    """

    index: np.ndarray
    fold: np.ndarray
    mu: np.ndarray
    noise_var: np.ndarray


def _thin(n: int, keep: int) -> np.ndarray:
    return np.unique(np.linspace(0, n - 1, min(n, keep)).round().astype(int))


def _fold_draws(program: Program, samples: dict[str, np.ndarray], k: int) -> tuple[dict, dict, np.ndarray]:
    """Thinned (law parameters, noise parameters, group offsets or None) of fold ``k``."""
    first = next(iter(samples.values()))
    s = first.shape[1] * first.shape[2]
    pick = _thin(s, MAX_DRAWS)

    def flat(name: str) -> np.ndarray:
        v = np.asarray(samples[name][k])
        return v.reshape((s,) + v.shape[2:])[pick]

    params = {name: flat(name) for name in program.law.params}
    # group terms: each level's values (a level the fold held out whole was drawn from its prior:
    # the new-level predictive)
    params |= {name: flat(level) for name, (_, _, level) in site_names(program.law, program.groupings).items()}
    noise = {name: flat(name) for name in program.noise.sites() if name != "group_sd"}
    offsets = flat("group_offset") if program.noise.group is not None else None
    return params, noise, offsets


def _means_at(program: Program, inputs: dict, params: dict[str, np.ndarray], rows: np.ndarray) -> np.ndarray:
    """``(draws, rows)``: the law's mean function of each draw of ``params`` at ``rows``, computed
    over every row in chunks of draws (at most ``CHUNK_NUMBERS`` draws × rows each)."""
    index = {c: jnp.asarray(g.index) for c, g in program.groupings.items()}
    mean = jax.vmap(lambda p: law_mean(program.law, inputs, p, program.constants, index))
    n_draws = len(next(iter(params.values())))
    size = max(1, CHUNK_NUMBERS // max(1, program.n_obs))
    parts = []
    for a in range(0, n_draws, size):
        mu = np.asarray(mean({n: jnp.asarray(v[a:a + size]) for n, v in params.items()}), dtype=float)
        parts.append(np.broadcast_to(mu, (mu.shape[0], program.n_obs))[:, rows])
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def heldout_predictive(program: Program, samples: dict[str, np.ndarray], heldout: np.ndarray) -> HeldOut:
    """Mean-function draws and noise variance of each fold's posterior at the points it held out.

    Parameters
    ----------
    program : Program
        The law's program on the full data (the one its folds were fitted with).
    samples : dict of str to ndarray
        Fold draws shaped ``(fold, chain, draw, ...)`` (:class:`bayesfric.inference.engine.FoldFits`).
    heldout : ndarray of bool, shape (fold, n_obs)
        Points each fold held out (each at most once).
    """
    rows = np.flatnonzero(heldout.any(axis=0))
    rows = rows[_thin(rows.size, MAX_POINTS)] if rows.size else rows
    fold_of = np.argmax(heldout, axis=0)
    inputs = {k: jnp.asarray(v) for k, v in program.inputs.items()}
    mus, noise_vars = [], []
    for k in range(heldout.shape[0]):
        mine = rows[fold_of[rows] == k]
        if mine.size == 0:
            continue
        params, noise, offsets = _fold_draws(program, samples, k)
        mu = _means_at(program, inputs, params, mine)
        if offsets is not None:
            mu = mu * np.exp(offsets[:, program.group_index[mine]])
        obs = program.observation(jnp.asarray(mu), {n: jnp.asarray(v)[:, None] for n, v in noise.items()})
        var = np.asarray(jnp.broadcast_to(obs.variance, mu.shape), dtype=float)
        # a Student-t draw with nu <= 2 has no variance: its squared scale stands in (a weight
        # for the misses, not a claim about the noise)
        var = np.where(np.isfinite(var), var, np.asarray(jnp.broadcast_to(obs.scale, mu.shape), dtype=float) ** 2)
        mus.append(mu)
        noise_vars.append(var.mean(axis=0))
    if not mus:
        return HeldOut(rows, np.zeros(0, dtype=int), np.zeros((0, 0)), np.zeros(0))
    order = np.argsort(np.concatenate([rows[fold_of[rows] == k] for k in range(heldout.shape[0])
                                       if (fold_of[rows] == k).any()]), kind="stable")
    s = min(m.shape[0] for m in mus)
    mu = np.concatenate([m[:s] for m in mus], axis=1)[:, order]
    return HeldOut(rows, fold_of[rows], mu, np.concatenate(noise_vars)[order])
