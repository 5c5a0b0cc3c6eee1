"""Lack of fit along service time: do the campaign levels bend away from their fitted trend?

Why
    A law with a trend (:meth:`Law.trend <bayesfric.laws.base.Law.trend>`, :mod:`bayesfric.trend`)
    gives each test campaign its own level about the trend. Where wear accelerates and the trend
    is linear, every campaign's level absorbs its own share of the curvature: the residuals of
    the data are flat, the leave-future-out folds one campaign ahead see a miss inside the
    scatter, and the misfit shows only in the campaign levels against the trend -- low in the
    middle of the tested span, high at both ends. Beyond the last campaign the trend then
    forecasts friction too low and the time to exceed too late (every replicate of the
    accelerating case of ``benchmarks/bench_trend_forecast.py``).

The test (:func:`curvature_test`)
    The deviations ``d_g`` of the ``G`` campaign levels from the fitted trend (posterior means,
    :func:`level_deviations`: on the parameter's unconstrained scale, a log for a positive
    parameter; :mod:`bayesfric.sizing.bend` uses the log of friction at the operating point) are
    regressed by ordinary least squares on ``1``, ``x`` and ``x² − mean(x²)``, with ``x`` the
    service coordinate centred and scaled to ``[−1, 1]``. The quadratic coefficient ``c`` over its
    standard error, the residual scatter of the ``G − 3`` degrees of freedom its noise, is a
    Student-t statistic. It is exact when the trend is linear in ``x`` on the scale tested (a
    ``loglinear`` trend on its log scale), the levels scatter independently with one sd and the
    deviations are the least-squares residuals of the levels about it: regressing the residuals
    again on ``1, x`` changes nothing (Frisch-Waugh), so ``t`` is the classical test of a
    quadratic term. The posterior means are close to that (each level is shrunk toward the trend
    by about the same factor when the campaigns have the same design, and ``t`` does not depend
    on the scale); a ``linear`` trend of a positive parameter is a log of a line (a slight
    curvature the trend itself carries, which the deviations no longer hold). Its false alarm on
    full fits is measured, not assumed (``benchmarks/bench_trend_forecast.py``, the linear case).

Which way, and the level
    Each direction is a one-sided test at :data:`ALPHA`: ``upward`` (``c > 0``, p of ``t`` under
    the null below ALPHA: the levels grow faster than the trend toward the ends of the span,
    wear accelerating -- beyond the data the trend forecasts too low, so a crossing comes
    *sooner* than forecast), ``downward`` (the levels saturate: a crossing later than
    forecast). The upward bend, the one that changes an answer, is reported in ALPHA of the data
    sets whose trend form is right; either bend in 2 ALPHA. A one-sided test is chosen over a
    two-sided one because the two directions mean different things to a sizing answer (an
    upward bend marks it not calibrated, a downward one errs safe) and with few campaigns the
    power is small either way (seven campaigns, 4 degrees of freedom: the quadratic term must
    be 2.13 standard errors to show at 5 %).

What it cannot see
    A curvature within the campaign scatter. Seven campaigns scattering 3 % about friction that
    grows as ``2 (1 + (t/6000 h)²)`` over 0–3000 h (a linear trend forecasts its 6000 h crossing
    thousands of hours late) stand 1.9 scatter sds away from the nearest linear trend: the test
    flags 48.5 % of such data sets (the noncentral t's power, and measured), and no test with a
    5 % false alarm flags more than 62 % (a z-test knowing the scatter exactly). Fewer than
    :data:`MIN_CAMPAIGNS` campaigns: no test (no degree of freedom left).

Example
-------
>>> t = np.array([0.0, 500, 1000, 1500, 2000, 2500, 3000])
>>> bend = curvature_test(t, 0.05 * ((t - 1500) / 1500) ** 2 + np.array([0, 1, -1, 0, 1, -1, 0]) * 1e-3)
>>> bend.direction, bend.df
('upward', 4)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = ["ALPHA", "MIN_CAMPAIGNS", "Bend", "curvature_test", "level_deviations", "trend_bends"]

#: One-sided level of each direction's test (see the module).
ALPHA = 0.05
#: Fewest campaigns a curvature is tested on (``G − 3`` degrees of freedom).
MIN_CAMPAIGNS = 4


@dataclass(frozen=True)
class Bend:
    """The curvature test of campaign levels against their trend (see the module).

    ``curvature``: the quadratic coefficient ``c`` on ``x ∈ [−1, 1]`` (on a log scale, about the
    relative excess of the levels at both ends of the span over the middle); ``se`` its standard
    error; ``t = c / se``; ``df = G − 3``; ``p_up``, ``p_down``: the one-sided p-values;
    ``campaigns``: ``G``; ``alpha``: each direction's level.
    """

    curvature: float
    se: float
    t: float
    df: int
    p_up: float
    p_down: float
    campaigns: int
    alpha: float = ALPHA

    @property
    def direction(self) -> str:
        """``"upward"``, ``"downward"`` or ``"none"`` (neither one-sided test below ``alpha``)."""
        if self.p_up < self.alpha:
            return "upward"
        if self.p_down < self.alpha:
            return "downward"
        return "none"

    def describe(self) -> str:
        """One clause: the statistic, its p-value in the direction it points, the campaigns.

        Examples
        --------
        >>> Bend(0.04, 0.01, 4.0, 4, 0.008, 0.992, 7).describe()
        'curvature t = 4.00, 4 degrees of freedom, one-sided p = 0.008, 7 campaigns'
        """
        p = self.p_up if self.t >= 0 else self.p_down
        return f"curvature t = {self.t:.2f}, {self.df} degrees of freedom, one-sided p = {p:.2g}, " \
               f"{self.campaigns} campaigns"


def curvature_test(coords: Sequence[float], deviations: Sequence[float], alpha: float = ALPHA) -> Bend | None:
    """The quadratic-term t-test of campaign deviations from their trend (see the module).

    Parameters
    ----------
    coords : sequence of float
        Each campaign's service coordinate (hours, cycles); at least three distinct.
    deviations : sequence of float
        Each campaign's level minus the trend there (one scale: unconstrained, or log friction).
    alpha : float
        One-sided level of each direction.

    Returns
    -------
    Bend or None
        None with fewer than :data:`MIN_CAMPAIGNS` finite campaigns or three distinct coordinates.

    Examples
    --------
    >>> t = np.arange(7) * 500.0
    >>> flat = curvature_test(t, [0.01, -0.02, 0.0, 0.015, -0.01, 0.02, -0.005])
    >>> flat.direction
    'none'
    >>> curvature_test(t[:3], [0.0, 0.1, 0.0]) is None
    True
    """
    t, d = np.asarray(coords, dtype=float), np.asarray(deviations, dtype=float)
    keep = np.isfinite(t) & np.isfinite(d)
    t, d = t[keep], d[keep]
    if t.size < MIN_CAMPAIGNS or np.unique(t).size < 3:
        return None
    half = 0.5 * (t.max() - t.min())
    x = (t - 0.5 * (t.max() + t.min())) / half
    design = np.column_stack([np.ones_like(x), x, x**2 - np.mean(x**2)])
    coef, *_ = np.linalg.lstsq(design, d, rcond=None)
    df = t.size - 3
    rss = float(np.sum((d - design @ coef) ** 2))
    se = math.sqrt(rss / df * float(np.linalg.inv(design.T @ design)[2, 2]))
    c = float(coef[2])
    if se > 0:
        stat = c / se
    else:  # the deviations lie on a parabola exactly
        stat = math.copysign(math.inf, c) if c != 0 else 0.0
    return Bend(c, se, stat, df, float(stats.t.sf(stat, df)), float(stats.t.cdf(stat, df)), int(t.size), alpha)


def level_deviations(fit, p: str) -> tuple[np.ndarray, np.ndarray]:
    """Each fitted campaign's coordinate and the posterior mean of its level's deviation from the
    trend, on parameter ``p``'s unconstrained scale (a log for a positive parameter).

    ``fit``: a fit (DataTree) of a law whose ``p`` follows a ``linear`` or ``loglinear`` trend.

    Examples
    --------
    >>> hours, d = level_deviations(fit, "T_C")                    # doctest: +SKIP
    """
    import jax.numpy as jnp
    import numpyro.distributions as dist

    from bayesfric.hierarchy import _flat
    from bayesfric.model import program_of_fit
    from bayesfric.trend import centre, coordinates, span, support

    program = program_of_fit(fit)
    law = program.law
    column, prior = law.trending[p], program.resolved[p]
    post = fit["posterior"].to_dataset()
    flat = _flat(post)
    coords = coordinates([str(v) for v in post[column].values])
    tau = jnp.asarray(coords / span(coords))
    mid = centre(prior, law.trend_form, jnp.asarray(flat[p])[:, None], jnp.asarray(flat[f"{p}_trend"])[:, None], tau)
    levels = dist.biject_to(support(prior)).inv(jnp.asarray(flat[f"{p}_{column}"]))
    return coords, np.asarray(jnp.mean(levels - mid, axis=0), dtype=float)


def trend_bends(fit, alpha: float = ALPHA) -> dict[str, Bend | None]:
    """The curvature test of every trending parameter of ``fit`` on its unconstrained scale
    (:func:`level_deviations`, :func:`curvature_test`); a random walk's parameters are left out
    (a walk has no trend form to bend from).

    Examples
    --------
    >>> trend_bends(fit)["T_C"].direction                          # doctest: +SKIP
    'upward'
    """
    from bayesfric.model import program_of_fit

    law = program_of_fit(fit).law
    if law.trend_form == "walk":
        return {}
    return {p: curvature_test(*level_deviations(fit, p), alpha=alpha) for p in law.trending}
