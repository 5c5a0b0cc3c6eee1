"""Model-form error for extrapolated answers: the miss that blocked folds measured, scaled to the
distance of a sizing point beyond the tested envelope.

Why
    A law's posterior carries parameter and noise uncertainty *given the law*. Beyond the tested
    envelope the law's form is the larger risk, and no candidate is ever exactly the true law of
    a real rig. A blocked extrapolation fold (train inside part of the envelope, score beyond it)
    is the one place where the data show how far a law's mean curve misses outside what it was
    trained on; this module turns that into a band.

The miss of one law on one blocked scheme (:func:`measure_miss`)
    At each held-out point ``i`` the fold posterior gives draws of the mean function (thinned,
    :mod:`bayesfric.compare.heldout`); ``m_i`` is their mean and ``e_i = y_i − m_i`` the miss.
    The miss is modelled as a relative error that grows with the distance beyond the envelope
    the fold was trained on, measured in the input's own units::

        e_i = β · g_i + η_i,   g_i = |m_i| · (L · (d_i + OFFSET))^GROWTH,   η ~ N(0, Σ)

    ``d_i``: tested ranges beyond the fold's training data along the scheme's axis (on ``|x|``
    where the input has both signs), ``L``: the width of that training range, OFFSET: the miss
    a law already has at the envelope's edge. GROWTH = 2 because the generic form error of a
    smooth law is a missing curvature: extrapolating a fit that lacks a term ``k x²`` (or any
    smooth curvature) misses by ``k (L (d + c))²`` to first order. Measuring the distance in the
    input's units (``L d``) rather than in tested ranges makes the fold's miss carry over to the
    full fit, whose tested range is wider (on simulated data, tested ranges under-covered a
    quadratic drag term by a factor of two). ``Σ``: the fold posterior's covariance of the mean
    function across the held-out points plus the observation noise variance (the fold's own
    parameter error is shared by all its held-out points; ignoring that correlation overstates
    what the points say). ``β̂`` is the generalised-least-squares slope, ``se² = 1/(gᵀ Σ⁻¹ g)``.

    The rate used is ``κ = sqrt(max(0, β̂² − LAMBDA · se²))`` with LAMBDA = 0.5: between the plug-in
    ``β̂²`` (LAMBDA = 0), which widens every answer by noise when the law is right (the median
    width rose to 2.7× the within-model band on simulated data), and the unbiased positive-part moment estimate
    ``β̂² − se²`` (LAMBDA = 1, as DerSimonian & Laird 1986 estimate a between-study variance),
    which sets κ = 0 whenever the miss is within one standard error and so misses the mild form
    errors sizing must not under-state. Half the sampling variance is subtracted: a deliberate
    lean toward covering, because under-sizing a drive costs more than over-sizing it.
    The figures behind this choice are in ``tests/test_sizing_calibration.py`` and the README.

The band (:func:`relative_sd`, :func:`widen`)
    At a sizing point at distance ``d`` beyond the *full* data's tested range (width ``L``) along
    a matched scheme's axis, the law's mean curve gets a Gaussian discrepancy of relative sd
    ``κ (L (d + OFFSET))^GROWTH``, and no point (inside the envelope included) less than the
    largest miss the law showed at the edge of any scheme's envelope. One standard-normal draw
    per posterior draw is shared by every point of a question (a form error is systematic along
    the curve, not scatter). The calibrated answer is the within-model predictive with that
    discrepancy added to each draw; quantiles, required capacity and ``P(exceed)`` are computed
    from those draws exactly as the within-model ones. This is the discrepancy term of Kennedy &
    O'Hagan (2001, *J. R. Stat. Soc. B* 63:425) with its scale learned from blocked
    cross-validation (Roberts et al. 2017, *Ecography* 40:913, on blocked CV for extrapolation),
    in the spirit of normalised split-conformal prediction (Lei et al. 2018, *JASA* 113:1094),
    whose score is scaled by a local difficulty, here the distance. It is an approximation:
    Gaussian, one rate per law and scheme, the growth law assumed.

What it assumes, and where it fails (measured, ``tests/test_sizing_calibration.py``)
    That the miss the fold shows carries over to the full fit at the sizing point's distance
    with the assumed growth. It holds when the form error shows in the held-out points. A form
    error hidden in the noise of the held-out points (a fold of ten points that cannot tell the
    law's miss from its own parameter error) is often estimated as zero, and the calibrated
    coverage then stays below nominal: the figures per case are in the README's sizing section.
    Where the law is the true form, κ is usually 0 and the band is the within-model one.

Inside the data
    The folds measure a miss beyond an envelope; a law's misfit at the data themselves (a curve
    biased near the edge of the tested range) is measured on the full fit's residuals by
    :mod:`bayesfric.sizing.misfit`; it moves the law's curve by that bias (signed) and floors
    the relative sd at each point (:func:`bayesfric.sizing.answer._widened`).

Direction
    A point is weighed and widened only by schemes that extrapolate in its direction along an
    input where it lies outside the data (:func:`matching`). Where it lies outside along an input
    no scheme tests in that direction, the answer falls back to LOO weights and is widened by the
    largest miss any law showed on any scheme (:func:`widen`), and says so.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

__all__ = ["OFFSET", "GROWTH", "LAMBDA", "Scheme", "Miss", "measure_miss", "natural", "matching", "relative_sd",
           "per_range", "widen"]

#: Extrapolation distance (tested ranges) the miss is taken to have at the envelope's edge (0.2
#: under-covered points near the edge on simulated data: 68 % at 0.26 tested ranges).
OFFSET = 0.4
#: Power of the miss's growth with distance (2: a missing curvature term, see the module).
GROWTH = 2.0
#: Share of the sampling variance ``se²`` subtracted from ``β̂²`` (see the module).
LAMBDA = 0.5



def _reach(d, width: float):
    """The miss's scale at distance ``d`` (tested ranges) beyond a tested range ``width`` wide."""
    return (width * (np.asarray(d, dtype=float) + OFFSET)) ** GROWTH


@dataclass(frozen=True)
class Scheme:
    """A blocked extrapolation scheme: label, input axis, side it scores, and whether on ``|x|``."""

    label: str
    axis: str
    direction: str  # "upper" | "lower"
    use_abs: bool = False

    def values(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        return np.abs(x) if self.use_abs else x

    def distance(self, x, lo: float, hi: float) -> np.ndarray:
        """Tested ranges beyond ``[lo, hi]`` on this scheme's side (0 inside or on the other side)."""
        v = self.values(x)
        width = hi - lo
        beyond = v - hi if self.direction == "upper" else lo - v
        if width <= 0:
            return np.where(beyond > 0, np.inf, 0.0)
        return np.maximum(beyond, 0.0) / width

    def tested(self, data_values) -> tuple[float, float]:
        v = self.values(data_values)
        return float(np.min(v)), float(np.max(v))

    def to_json(self) -> dict:
        return {"label": self.label, "axis": self.axis, "direction": self.direction, "use_abs": self.use_abs}


@dataclass(frozen=True)
class Miss:
    """How far one law's mean curve missed beyond the envelope of one blocked fold.

    ``rate`` (κ ≥ 0): relative miss per (input unit)^GROWTH; ``beta``, ``se``: the GLS slope and
    its standard error; ``n``: held-out points used; ``reach``: the largest held-out distance
    (tested ranges of the fold's training data).
    """

    scheme: str
    rate: float
    beta: float
    se: float
    n: int
    reach: float

    def to_json(self) -> dict:
        return {"scheme": self.scheme, "rate": self.rate, "beta": self.beta, "se": self.se, "n": self.n,
                "reach": self.reach}

    @classmethod
    def from_json(cls, record: Mapping) -> Miss:
        return cls(str(record["scheme"]), float(record["rate"]), float(record["beta"]), float(record["se"]),
                   int(record["n"]), float(record["reach"]))


def measure_miss(cv, ds: xr.Dataset, scheme: Scheme) -> Miss | None:
    """The miss of a law on a blocked scheme (see the module), or None when nothing was kept.

    ``cv`` is the law's :class:`bayesfric.compare.CVResult` of the scheme (with its held-out
    predictive), ``ds`` the study's data.
    """
    kept = getattr(cv, "predictive", None)
    if kept is None or kept.mu.size == 0 or not cv.reliable:
        return None
    x = np.asarray(ds[scheme.axis].values, dtype=float)
    y = np.asarray(ds[ds.attrs["response"]].values, dtype=float)
    lo, hi = scheme.tested(x[~cv.heldout])
    finite = np.isfinite(kept.noise_var)
    index, mu = kept.index[finite], kept.mu[:, finite]
    if index.size == 0:
        return None
    d = scheme.distance(x[index], lo, hi)
    m = mu.mean(axis=0)
    e = y[index] - m
    g = np.abs(m) * _reach(d, hi - lo)
    same_fold = kept.fold[finite][:, None] == kept.fold[finite][None, :]
    cov = np.where(same_fold, np.cov(mu, rowvar=False).reshape(index.size, index.size), 0.0)
    cov += np.diag(kept.noise_var[finite])
    cov += np.eye(index.size) * 1e-12 * float(np.trace(cov)) / index.size
    solve_g = np.linalg.solve(cov, g)
    info = float(g @ solve_g)
    if not info > 0:
        return None
    beta = float(e @ solve_g) / info
    se = 1.0 / math.sqrt(info)
    return Miss(scheme.label, math.sqrt(max(0.0, beta**2 - LAMBDA * se**2)), beta, se, int(index.size),
                float(np.max(d)) if d.size else 0.0)


def natural(axis: str, data_values, direction: str = "upper") -> Scheme:
    """The scale an input is judged on: ``|x|`` where the data have both signs (friction is odd
    in velocity, so −6 rad/s lies as far beyond ±4 rad/s as +6 rad/s), else ``x``."""
    v = np.asarray(data_values, dtype=float)
    return Scheme("", axis, direction, bool((v < 0).any() and (v > 0).any()))


def matching(grid: Mapping[str, np.ndarray], data: Mapping[str, np.ndarray],
             schemes: Sequence[Scheme]) -> tuple[list[Scheme], list[Scheme]]:
    """The schemes that extrapolate in the direction of the question's points, and the sides
    (unlabelled :class:`Scheme` on the input's natural scale, :func:`natural`) along which some
    point lies outside the data with no scheme testing that direction.

    ``grid``: input -> SI values at every point; ``data``: input -> the data's SI values.
    """
    matched, uncovered = [], []
    for k, x in grid.items():
        if k not in data:
            continue
        mine = [s for s in schemes if s.axis == k and np.any(s.distance(x, *s.tested(data[k])) > 0)]
        matched += [s for s in mine if s not in matched]
        for side in ("upper", "lower"):
            nat = natural(k, data[k], side)
            outside = np.any(nat.distance(x, *nat.tested(data[k])) > 0)
            if outside and not any(s.direction == side for s in mine):
                uncovered.append(nat)
    return matched, uncovered


def per_range(miss: Miss, scheme: Scheme, data: Mapping[str, np.ndarray]) -> float:
    """A miss rate in unit-free terms, per (tested range of the full data)^GROWTH along the
    scheme's axis: comparable across laws, schemes and inputs (the fallback is their maximum)."""
    lo, hi = scheme.tested(data[scheme.axis])
    return miss.rate * float(hi - lo) ** GROWTH


def relative_sd(grid: Mapping[str, np.ndarray], data: Mapping[str, np.ndarray], misses: Mapping[str, Miss],
                schemes: Sequence[Scheme], matched: Sequence[Scheme], fallback: float,
                uncovered: Sequence[Scheme]) -> np.ndarray:
    """Relative sd of a law's discrepancy at every point (see the module).

    Along the matched schemes the miss grows as ``κ_j (L_j (d_j + OFFSET))^GROWTH`` (their
    variances add); a matched scheme without a measured miss for this law (its fold failed the
    gate) and every uncovered side (:func:`matching`, where a point lies beyond it) take the
    unit-free ``fallback`` (:func:`per_range`: the largest miss any law showed on any scheme)
    as ``fallback · (d + OFFSET)^GROWTH``. No point, inside the envelope included, gets less
    than the largest miss the law showed at the edge of any scheme's envelope
    (``κ_j (L_j OFFSET)^GROWTH``): a form error seen at the edge is there inside too.
    """
    n = len(next(iter(grid.values())))
    edge = max([per_range(misses[s.label], s, data) * OFFSET**GROWTH for s in schemes
                if s.label in misses and s.axis in data], default=0.0)
    var = np.zeros(n)
    for s in matched:
        lo, hi = s.tested(data[s.axis])
        d = s.distance(grid[s.axis], lo, hi)
        rate = misses[s.label].rate * _reach(d, hi - lo) if s.label in misses else fallback * _reach(d, 1.0)
        var += rate**2
    for s in uncovered:
        d = s.distance(grid[s.axis], *s.tested(data[s.axis]))
        var += np.where(d > 0, (fallback * _reach(d, 1.0)) ** 2, 0.0)
    return np.sqrt(np.maximum(var, edge**2))


def widen(mu: np.ndarray, y: np.ndarray, rel_sd: np.ndarray, rng: np.random.Generator,
          shift: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """Add the discrepancy to predictive draws ``(chain, draw, n)``: one standard normal per draw,
    shared by the points, times ``rel_sd · |mu|``, plus the relative mean ``shift · mu`` where
    given (a bias measured at the data, :mod:`bayesfric.sizing.misfit`).
    Returns ``(mu, y, discrepancy variance)``."""
    z = rng.normal(size=mu.shape[:-1] + (1,))
    scale = rel_sd * np.abs(mu)
    delta = scale * z if shift is None else scale * z + np.asarray(shift) * mu
    return mu + delta, y + delta, scale**2
