"""A law's misfit *inside* the tested envelope, measured on the full fit's own residuals.

Why
    The blocked folds (:mod:`bayesfric.sizing.calibration`) measure how far a law misses beyond
    the envelope it was trained on. A law can also miss inside the data: a mean curve bent the
    wrong way between its anchor points, or biased near the edge of the data, where a sizing
    point usually sits. The within-model band does not cover that bias (it is parameter and
    noise uncertainty given the law), and the fold's miss extrapolated back to the edge can be
    too small to cover it. Measured on simulated-truth seed data (robot_joint, reconstructed):
    at 3.9 and 4.2 rad/s, the top of the tested speeds, the generator's mean lay 0.02 N·m above
    the calibrated 90 % band, where the laws' mean curves ran 2 % below the measured points.

The estimate (:func:`local_misfit`, :meth:`LocalMisfit.at`)
    At each data row ``i`` the fit's own Program (:func:`bayesfric.sizing.compute.predict`)
    gives the posterior mean of the mean function ``m_i`` and the noise variance ``σ_i²``; the
    relative residual is ``r_i = (y_i − m_i) / m_i`` (positive: the measured magnitude is larger
    than the law's), with sd ``s_i = σ_i / |m_i|``. At a point ``g`` the local misfit is the
    kernel-weighted mean ``r̄(g) = Σ w_i r_i / Σ w_i`` with Gaussian weights on the distance in
    tested ranges (``|x|`` for an input measured in both directions), bandwidth BANDWIDTH tested
    ranges, and ``se²(g) = Σ w_i² s_i² / (Σ w_i)²``; beyond the data the weights fall on the
    nearest rows, so the misfit there is the one at the nearest edge. As for the folds' miss,
    the rate is ``sqrt(max(0, r̄² − LAMBDA · se²))`` (LAMBDA of the calibration module), with
    the sign of ``r̄`` (:meth:`LocalMisfit.shift`). It enters the calibrated answer twice
    (:func:`bayesfric.sizing.answer._widened`): with its sign, as the mean of the discrepancy
    (the law's mean curve is moved by ``m · shift``: inside the data the smoothed residuals are
    the posterior mean of a Kennedy–O'Hagan discrepancy; beyond the data the nearest edge's bias
    is carried), and as a floor of the discrepancy's relative sd (the bias at the point may
    differ from the one measured by as much again). On simulated-truth seed data (robot_joint,
    reconstructed) a zero-mean floor alone left the generator's mean 0.02 N·m above the
    calibrated band at 3.9 and 4.2 rad/s, where the weighted laws ran 1–2 % below the data.

What it assumes (approximations)
    Residuals independent given the law (the fit's shared parameter error is ignored, which
    understates ``se``, so it leans toward widening); at most MAX_ROWS rows (a seeded random
    subset beyond that); the Gaussian discrepancy shared along a question, as in the
    calibration module. Laws read with a group offset are predicted for a new unit, so the
    residuals include the units' spread around the population curve.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import xarray as xr

from bayesfric.sizing.calibration import LAMBDA

__all__ = ["BANDWIDTH", "MAX_ROWS", "LocalMisfit", "local_misfit"]

#: Kernel bandwidth, in tested ranges of each input.
BANDWIDTH = 0.1
#: Most data rows the residuals are computed at (a seeded random subset beyond).
MAX_ROWS = 2000


@dataclass(frozen=True)
class LocalMisfit:
    """Relative residuals of one law at the data rows, in scaled input coordinates.

    ``coords``: input -> (rows,) values on the natural axis (``|x|`` where the input has both
    signs) divided by the tested width; ``scale``: input -> (absolute?, width) used for the
    query points; ``r``, ``s``: relative residual and its sd per row.
    """

    coords: Mapping[str, np.ndarray]
    scale: Mapping[str, tuple[bool, float]]
    r: np.ndarray
    s: np.ndarray
    size: np.ndarray | None = None  # |m| per row: the law's mean magnitude (the residuals' scale)

    def at(self, grid: Mapping[str, np.ndarray]) -> np.ndarray:
        """The misfit rate (relative sd) at the points ``grid`` (input -> SI values)."""
        return np.abs(self.shift(grid))

    def lack_of_fit(self) -> dict:
        """Input -> :class:`~bayesfric.compare.lackoffit.LackOfFit` of these residuals along it
        (an input with a single value or few is not tested: absent)."""
        from bayesfric.compare.lackoffit import lack_of_fit

        size = np.ones_like(self.r) if self.size is None else np.asarray(self.size, dtype=float)
        return {t.axis: t for t in lack_of_fit(self.r * size, self.s * size, self.coords, scale=float(size.mean()))}

    def shift(self, grid: Mapping[str, np.ndarray]) -> np.ndarray:
        """The signed misfit at the points ``grid``: ``sign(r̄) · sqrt(max(0, r̄² − LAMBDA se²))``,
        a relative bias of the law's mean curve (positive: the data run above the law)."""
        n = len(next(iter(grid.values())))
        u = np.zeros((n, self.r.size))
        for k, x in self.coords.items():
            absolute, width = self.scale[k]
            g = np.asarray(grid[k], dtype=float)
            g = np.clip((np.abs(g) if absolute else g) / width, x.min(), x.max())  # beyond: the nearest edge
            u += (g[:, None] - x[None, :]) ** 2
        w = np.exp(-0.5 * (u - u.min(axis=1, keepdims=True)) / BANDWIDTH**2)
        total = w.sum(axis=1)
        mean = (w @ self.r) / total
        se2 = (w**2 @ self.s**2) / total**2
        return np.sign(mean) * np.sqrt(np.maximum(0.0, mean**2 - LAMBDA * se2))


def local_misfit(fit: xr.DataTree, data: Mapping[str, np.ndarray], measured: np.ndarray,
                 seed: int = 0) -> LocalMisfit | None:
    """The law's relative residuals at the data (see the module); None when it has no finite ones.

    ``data``: input -> SI values per row, ``measured``: the response per row (SI).
    """
    from bayesfric.laws.variants import law_of_fit
    from bayesfric.sizing.compute import predict

    law = law_of_fit(fit.attrs)
    if law.trajectory or any(k not in data for k in law.operating_inputs):
        return None
    y = np.asarray(measured, dtype=float)
    rows = np.arange(y.size)
    if y.size > MAX_ROWS:
        rows = np.sort(np.random.default_rng(seed).choice(y.size, MAX_ROWS, replace=False))
    values = {k: np.asarray(data[k], dtype=float)[rows] for k in law.operating_inputs}
    draws = predict(fit, values, seed)
    m = draws.mu.mean(axis=(0, 1))
    noise = np.where(np.isfinite(draws.noise_var), draws.noise_var, np.nan)
    sd = np.sqrt(np.nanmean(noise.reshape(-1, m.size), axis=0))
    ok = np.isfinite(m) & (np.abs(m) > 0) & np.isfinite(sd) & np.isfinite(y[rows])
    if not ok.any():
        return None
    coords, scale = {}, {}
    for k, v in values.items():
        absolute = bool(v.min() < 0 < v.max())
        x = np.abs(v) if absolute else v
        width = float(x.max() - x.min())
        if width > 0:
            coords[k], scale[k] = x[ok] / width, (absolute, width)
    if not coords:
        return None
    return LocalMisfit(coords, scale, (y[rows][ok] - m[ok]) / m[ok], sd[ok] / np.abs(m[ok]), np.abs(m[ok]))
