"""A predictive distribution per data row as a weighted mixture of posterior draws, evaluated exactly.

Each posterior draw ``s`` of a law gives, at row ``i``, the mean function ``mu[s, i]`` and the
fit's observation distribution around it (:meth:`bayesfric.model.Program.observation`): a
normal or a Student-t of location ``mu[s, i]`` and scale ``scale[s, i]`` (``df[s]``). The
predictive of row ``i`` is the mixture ``Σ_s w_s p_s(y)`` with ``w_s = 1/S`` for one law and
``w_k / S_k`` for a model average of laws ``k`` (:func:`join`). Everything here is computed from
that mixture without resampling noise:

* the **mean curve**: the weighted empirical distribution of ``mu`` (posterior mean ``Σ w_s mu_s``,
  quantiles by :func:`bayesfric.sizing.compute.weighted_quantiles`, the inverse of its CDF);
* the **noisy predictive**: CDF ``F(y) = Σ w_s F_s(y)`` (PIT values, band coverage), log density
  ``log Σ w_s p_s(y)`` (elpd), quantiles by inverting ``F`` (safeguarded Newton inside the bracket
  of the components' own quantiles, which always holds the mixture's, to 1e-10 in probability).

Rows are processed in blocks of at most :data:`bayesfric.limits.CHUNK_NUMBERS` draws × rows, so
memory does not grow with draws × rows beyond the draws themselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special

from bayesfric.limits import CHUNK_NUMBERS

__all__ = ["Mixture", "join", "curve_mean", "curve_quantiles", "predictive_quantiles", "pit", "log_density"]

_NEWTON_STEPS = 60
_TOLERANCE = 1e-10


@dataclass(frozen=True)
class Mixture:
    """Weighted location-scale components per row.

    Attributes
    ----------
    mu : ndarray, shape (S, n)
        Mean-function draws (the components' locations).
    scale : ndarray, shape (S, 1) or (S, n)
        The observation distribution's scale per draw (and row).
    df : ndarray or None, shape (S, 1) or (S, n)
        Student-t degrees of freedom (``inf``: a normal component); None: every component normal.
    weight : ndarray, shape (S,)
        Draw weights, summing to 1.
    """

    mu: np.ndarray
    scale: np.ndarray
    df: np.ndarray | None
    weight: np.ndarray

    @property
    def n_rows(self) -> int:
        return int(self.mu.shape[1])

    def rows(self, a: int, b: int) -> Mixture:
        """The components of rows ``a:b``."""

        def cut(x):
            return None if x is None else (x[:, a:b] if x.shape[-1] > 1 else x)

        return Mixture(self.mu[:, a:b], cut(self.scale), cut(self.df), self.weight)


def join(parts: Sequence[Mixture], weights: Sequence[float]) -> Mixture:
    """The mixture of ``parts`` with total weights ``weights`` (renormalised): each draw of part
    ``k`` weighs ``w_k`` times its weight in the part. Normal and Student-t parts are joined by
    giving the normal ones ``df = inf``."""
    w = np.asarray(weights, dtype=float) / float(np.sum(weights))
    n = parts[0].n_rows
    mixed = any(p.df is not None for p in parts)

    def full(x, s):
        return np.broadcast_to(x, (s, n))

    return Mixture(np.concatenate([p.mu for p in parts]),
                   np.concatenate([full(p.scale, p.mu.shape[0]) for p in parts]),
                   np.concatenate([full(np.inf if p.df is None else p.df, p.mu.shape[0]) for p in parts])
                   if mixed else None,
                   np.concatenate([wk * p.weight for wk, p in zip(w, parts, strict=True)]))


def _blocks(m: Mixture):
    size = max(1, CHUNK_NUMBERS // max(1, m.mu.shape[0]))
    for a in range(0, m.n_rows, size):
        yield a, m.rows(a, min(a + size, m.n_rows))


def curve_mean(m: Mixture) -> np.ndarray:
    """Posterior mean of the mean curve per row, ``Σ_s w_s mu[s, i]``."""
    return m.weight @ m.mu


def curve_quantiles(m: Mixture, levels: Sequence[float]) -> np.ndarray:
    """Quantiles of the mean curve, shape (levels, n): the weighted draws' inverse CDF."""
    from bayesfric.sizing.compute import weighted_quantiles

    out = np.empty((len(levels), m.n_rows))
    for a, block in _blocks(m):
        q = weighted_quantiles(block.mu, block.weight, levels)
        out[:, a:a + block.n_rows] = [q[level] for level in levels]
    return out


def _z(m: Mixture, y):
    return (np.asarray(y) - m.mu) / m.scale


def _cdf(m: Mixture, y) -> np.ndarray:
    z = _z(m, y)
    return special.ndtr(z) if m.df is None else special.stdtr(m.df, z)


def _logpdf(m: Mixture, y) -> np.ndarray:
    z = _z(m, y)
    if m.df is None:
        return -0.5 * z**2 - 0.5 * np.log(2 * np.pi) - np.log(m.scale)
    df = np.asarray(m.df, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        t = (special.gammaln((df + 1) / 2) - special.gammaln(df / 2) - 0.5 * np.log(df * np.pi)
             - (df + 1) / 2 * np.log1p(z**2 / df))
    normal = -0.5 * z**2 - 0.5 * np.log(2 * np.pi)  # df = inf: a normal part of a joined mixture
    return np.where(np.isinf(df), normal, t) - np.log(m.scale)


def _component_quantile(m: Mixture, level: float) -> np.ndarray:
    if m.df is None:
        return m.mu + m.scale * special.ndtri(level)
    return m.mu + m.scale * np.where(np.isinf(m.df), special.ndtri(level), special.stdtrit(m.df, level))


def pit(m: Mixture, y: np.ndarray) -> np.ndarray:
    """The predictive CDF at the observed ``y`` per row, ``Σ_s w_s F_s(y_i)`` (the PIT value)."""
    out = np.empty(m.n_rows)
    for a, block in _blocks(m):
        out[a:a + block.n_rows] = block.weight @ _cdf(block, y[a:a + block.n_rows])
    return out


def log_density(m: Mixture, y: np.ndarray) -> np.ndarray:
    """The log predictive density at the observed ``y`` per row, ``log Σ_s w_s p_s(y_i)``."""
    out = np.empty(m.n_rows)
    for a, block in _blocks(m):
        out[a:a + block.n_rows] = special.logsumexp(_logpdf(block, y[a:a + block.n_rows]),
                                                    b=block.weight[:, None], axis=0)
    return out


def _invert(m: Mixture, level: float) -> np.ndarray:
    """The mixture's ``level``-quantile per row of one block (module docstring)."""
    q = _component_quantile(m, level)
    lo, hi = q.min(axis=0), q.max(axis=0)
    x = m.weight @ q
    for _ in range(_NEWTON_STEPS):
        gap = m.weight @ _cdf(m, x) - level
        if np.all(np.abs(gap) < _TOLERANCE) or np.all(hi - lo <= 1e-14 * np.maximum(1.0, np.abs(x))):
            break
        lo, hi = np.where(gap < 0, x, lo), np.where(gap > 0, x, hi)
        density = m.weight @ np.exp(_logpdf(m, x))
        with np.errstate(divide="ignore", invalid="ignore"):
            step = x - gap / density
        x = np.where((step > lo) & (step < hi), step, 0.5 * (lo + hi))
    return x


def predictive_quantiles(m: Mixture, levels: Sequence[float]) -> np.ndarray:
    """Quantiles of the noisy predictive (the mixture), shape (levels, n)."""
    out = np.empty((len(levels), m.n_rows))
    for a, block in _blocks(m):
        for j, level in enumerate(levels):
            out[j, a:a + block.n_rows] = _invert(block, float(level))
    return out
