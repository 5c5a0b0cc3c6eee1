"""Model-form allowance for forecasts over service time, measured on leave-future-out folds.

Why
    A trend law's posterior carries the uncertainty of its trend and of the scatter between
    campaigns *given the trend's form*. Forecast beyond the last tested campaign, the form is the
    larger risk: wear that accelerates while the candidate trend is linear is forecast late, and
    the time to exceed then lies after the truth in nearly every replicate (measured,
    ``benchmarks/bench_trend_forecast.py``). Leave-future-out folds (train on the campaigns
    before the ``k``-th, score the ``k``-th, :func:`bayesfric.compare.forecast_masks`) are the
    one place where the data show how far a trend's forecast misses; this module turns that miss
    into an allowance, as the blocked folds' misses calibrate a sizing answer
    (:mod:`bayesfric.sizing.calibration`).

The miss (:func:`forecast_miss`)
    At each row ``i`` of a forecast campaign the fold posterior gives draws of the mean function
    (its level drawn from the trend and the scatter between campaigns: the forecast of a new
    campaign); ``m_i`` is their mean and ``e_i = y_i − m_i`` the miss. As for a blocked fold
    (:class:`bayesfric.sizing.calibration.Pieces`), the miss is a relative error growing with
    the square of the forecast's reach::

        e_i = β · |m_i| · u_i^GROWTH + η_i,   u_i = (t_i − t_last,i) + OFFSET · (t_last,i − t_0)

    in the service coordinate's unit: ``t_i`` the campaign's service time, ``t_last,i`` the last
    campaign its fold trained on, ``t_0`` the first campaign (each fold has its own trained
    span, unlike a blocked scheme's shared cut). ``η`` has the fold posterior's covariance of the
    mean function plus the noise variance, so a miss within the forecast's own band (trend and
    scatter uncertainty included) is not counted as form error. The rate ``κ`` is the
    calibration module's positive-part estimate (LAMBDA). GROWTH = 2: a trend that lacks a
    curvature (accelerating or saturating wear) misses by that curvature times the reach squared.

The allowance (:func:`allowance`, :func:`widen_curves`)
    At service time ``t`` after the fit's last campaign ``t_last`` (first ``t_0``) the friction
    curve of each posterior draw gets a Gaussian relative discrepancy of sd
    ``κ ((t − t_last) + OFFSET (t_last − t_0))^GROWTH``, one standard normal per draw shared
    along service time (a form error is systematic, not scatter), as
    :func:`bayesfric.sizing.calibration.widen` does along an operating input.

What it assumes (approximations)
    That the misses of the few forecast folds (two on ``drum_campaigns``) carry over to a reach
    of several campaigns with the assumed growth; Gaussian; one rate per law. The miss is
    measured on the response the law predicts (for a coast-down, the speed over time) and
    applied, relative, to the friction at the operating point. Coverage with and without it is
    measured in ``benchmarks/bench_trend_forecast.py``.

Example
-------
>>> miss = forecast_miss(cv, ds, "hours")                                    # doctest: +SKIP
>>> rel_sd = allowance(miss, np.array([6000.0, 9000.0]), first=0.0, last=6000.0)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import xarray as xr

from bayesfric.compare.heldout import HeldOut
from bayesfric.sizing.calibration import GROWTH, LAMBDA, OFFSET, Miss, Pieces

__all__ = ["forecast_pieces", "forecast_miss", "study_misses", "allowance", "widen_curves", "service_of_rows"]


def service_of_rows(ds: xr.Dataset, column: str) -> np.ndarray:
    """Each row's service coordinate (hours, cycles) as numbers, from the campaign column."""
    return np.asarray([float(v) for v in np.asarray(ds[column].values).astype(str).reshape(-1)])


def forecast_pieces(kept: HeldOut, service: np.ndarray, y: np.ndarray) -> Pieces | None:
    """The misses of one law's forecast folds (see the module), or None when nothing was kept.

    ``kept``: the folds' held-out predictive; ``service``: every row's service coordinate;
    ``y``: the response. A kept row's fold trained on the campaigns before the row's own.

    Examples
    --------
    >>> kept = HeldOut(np.array([2, 3]), np.array([0, 0]), np.array([[1.0, 1.0], [1.2, 1.2]]),
    ...                np.array([0.01, 0.01]))
    >>> p = forecast_pieces(kept, np.array([0.0, 1.0, 2.0, 2.0]), np.array([1.0, 1.0, 1.3, 1.3]))
    >>> p.u.tolist()   # reach 1 plus OFFSET times the trained span 1
    [1.4, 1.4]
    """
    if kept is None or kept.mu.size == 0:
        return None
    finite = np.isfinite(kept.noise_var)
    index, mu = kept.index[finite], kept.mu[:, finite]
    if index.size == 0:
        return None
    t0 = float(service.min())
    t = service[index]
    last = np.array([service[service < ti].max(initial=t0) for ti in t])
    span = last - t0
    u = (t - last) + OFFSET * span
    if not np.all(u > 0):
        return None
    m = mu.mean(axis=0)
    same_fold = kept.fold[finite][:, None] == kept.fold[finite][None, :]
    cov = np.where(same_fold, np.cov(mu, rowvar=False).reshape(index.size, index.size), 0.0)
    cov += np.diag(kept.noise_var[finite])
    cov += np.eye(index.size) * 1e-12 * float(np.trace(cov)) / index.size
    d = np.where(span > 0, (t - last) / np.where(span > 0, span, 1.0), np.inf)
    return Pieces(y[index] - m, np.abs(m), u, d, cov, float(np.max(span)))


def forecast_miss(cv, ds: xr.Dataset, column: str) -> Miss | None:
    """How far one law's forecasts missed on its leave-future-out folds, as a rate growing with
    the reach squared (see the module); None when the folds kept nothing or failed the gate.

    ``cv``: the law's :class:`bayesfric.compare.CVResult` on the forecast scheme, with its
    held-out predictive; ``ds``: the study's data; ``column``: the service coordinate.
    """
    if cv is None or not getattr(cv, "reliable", False):
        return None
    p = forecast_pieces(getattr(cv, "predictive", None), service_of_rows(ds, column),
                        np.asarray(ds[ds.attrs["response"]].values, dtype=float))
    if p is None:
        return None
    beta, se, _ = p.gls(GROWTH)
    if not math.isfinite(beta):
        return None
    return Miss(str(getattr(cv, "scheme", "forecast")), math.sqrt(max(0.0, beta**2 - LAMBDA * se**2)), beta, se,
                int(p.e.size), float(np.max(p.d)))


def study_misses(cvs: Mapping[str, Mapping[str, Any]], labels: Sequence[str], ds: xr.Dataset,
                 column: str) -> dict[str, tuple[Miss | None, str]]:
    """Each law's forecast miss on the study's leave-future-out scheme (the first of ``labels``),
    with why none was measured where none was.

    ``cvs``: law -> scheme label -> its :class:`bayesfric.compare.CVResult` (with the held-out
    predictive); ``ds``: the study's data; ``column``: the service coordinate.
    """
    out: dict[str, tuple[Miss | None, str]] = {}
    for law, by_scheme in cvs.items():
        cv = next((by_scheme[k] for k in labels if k in by_scheme), None)
        if cv is None:
            out[law] = (None, "the study has no leave-future-out folds of this law ([compare] forecast)")
        elif not cv.reliable:
            out[law] = (None, "its leave-future-out folds failed the diagnostics gate")
        else:
            miss = forecast_miss(cv, ds, column)
            out[law] = (miss, "" if miss is not None else "its leave-future-out folds kept no forecast to measure")
    return out


def allowance(miss: Miss | None, times: np.ndarray, *, first: float, last: float) -> np.ndarray:
    """Relative sd of the form discrepancy at service ``times`` for a fit whose campaigns span
    ``first`` … ``last`` (see the module); zeros without a miss.

    Examples
    --------
    >>> m = Miss("f", rate=1e-6, beta=1e-6, se=0.0, n=10, reach=0.2)
    >>> allowance(m, np.array([1000.0, 2000.0]), first=0.0, last=1000.0).round(3).tolist()
    [0.16, 1.96]
    """
    times = np.asarray(times, dtype=float)
    if miss is None or miss.rate <= 0:
        return np.zeros_like(times)
    u = np.maximum(times - last, 0.0) + OFFSET * (last - first)
    return miss.rate * u**GROWTH


def widen_curves(curves: np.ndarray, rel_sd: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Friction curves ``(draw, service)`` with the discrepancy added: one standard normal per
    draw shared along service time, times ``rel_sd · |curve|``."""
    z = rng.normal(size=(curves.shape[0], 1))
    return curves + np.abs(curves) * rel_sd[None, :] * z
