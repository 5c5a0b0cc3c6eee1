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

__all__ = ["OFFSET", "GROWTH", "LAMBDA", "Scheme", "Miss", "Pieces", "pieces", "measure_miss", "natural", "matching",
           "relative_sd", "discrepancy", "per_range", "widen"]

#: Extrapolation distance (tested ranges) the miss is taken to have at the envelope's edge (0.2
#: under-covered points near the edge on simulated data: 68 % at 0.26 tested ranges).
OFFSET = 0.4
#: Power of the miss's growth with distance (2: a missing curvature term, see the module).
GROWTH = 2.0
#: Share of the sampling variance ``se²`` subtracted from ``β̂²`` (see the module).
LAMBDA = 0.5



def _scale(d, width: float) -> np.ndarray:
    """The scale ``u = width (d + OFFSET)`` of a point at distance ``d`` (tested ranges) beyond a
    tested range ``width`` wide."""
    return width * (np.asarray(d, dtype=float) + OFFSET)


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

    ``rate`` (κ ≥ 0): relative miss per (input unit)^growth; ``beta``, ``se``: the GLS slope and
    its standard error; ``n``: held-out points used; ``reach``: the largest held-out distance
    (tested ranges of the fold's training data). ``growth``: the power of distance the miss
    grows with (GROWTH, fixed, from one cut; estimated from nested cuts by
    :mod:`tests.sizing_growth`), ``growth_se`` its standard error (0: fixed), ``pivot``
    the scale (input units) at which the rate was measured best, ``cuts`` how many blocked
    folds along the axis measured it.
    """

    scheme: str
    rate: float
    beta: float
    se: float
    n: int
    reach: float
    growth: float = GROWTH
    growth_se: float = 0.0
    pivot: float = 1.0
    cuts: int = 1
    width_power: float = math.nan
    width_power_se: float = 0.0
    width_pivot: float = 1.0
    growth_cov: float = 0.0

    def _powers(self, u, width: float) -> tuple[np.ndarray, np.ndarray]:
        """Mean and variance of ``ln((L/w_0)^q ((d + OFFSET)/t_0)^p)`` (nested cuts)."""
        a, b = math.log(width / self.width_pivot), np.log(np.asarray(u, dtype=float) / width / self.pivot)
        loc = self.width_power * a + self.growth * b
        return loc, self.width_power_se**2 * a**2 + self.growth_se**2 * b**2 + 2 * self.growth_cov * a * b

    def scale(self, u, width: float | None = None) -> np.ndarray:
        """The root mean square of the growth factor at scale ``u = L (d + OFFSET)`` (input units;
        ``width``: the full data's tested width ``L``): one cut, ``u^GROWTH``; nested cuts,
        ``(L/w_0)^q ((d + OFFSET)/t_0)^p`` over the powers' posterior."""
        u = np.asarray(u, dtype=float)
        if self.cuts < 2 or width is None:
            return u**self.growth * np.exp(self.growth_se**2 * np.log(u / self.pivot) ** 2)
        loc, var = self._powers(u, width)
        return np.exp(loc + var)

    def relative(self, u, rate: float | None = None, width: float | None = None) -> np.ndarray:
        """Root mean square of the relative discrepancy at scale ``u`` (:meth:`band`); with
        ``rate``, that rate times :meth:`scale` (a miss of that size)."""
        if rate is not None:
            return rate * self.scale(u, width)
        mean, sd = self.band(u, width)
        return np.sqrt(mean**2 + sd**2)

    def band(self, u, width: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Signed relative mean and relative sd of the law's discrepancy at scale ``u`` (``width``:
        the full data's tested width ``L``, ``u = L (d + OFFSET)``).

        One cut (growth fixed): mean 0, sd ``κ · scale(u)``. Nested cuts
        (:mod:`tests.sizing_growth`): the rate's empirical-Bayes posterior (prior ``N(0, κ²)``,
        measured ``β̂ ± se``: mean ``f β̂``, variance ``f se²``, ``f = κ² / (κ² + se²)``; 0 when
        κ = 0) times ``(L/w_0)^q ((d + OFFSET)/t_0)^p`` over the powers' Gaussian posterior
        (log-normal moments).
        """
        u = np.asarray(u, dtype=float)
        if self.cuts < 2 or width is None:
            return np.zeros_like(u), self.rate * self.scale(u)
        f = self.rate**2 / (self.rate**2 + self.se**2) if self.rate > 0 else 0.0
        loc, var = self._powers(u, width)
        mean = f * self.beta * np.exp(loc + 0.5 * var)
        second = (f**2 * self.beta**2 + f * self.se**2) * np.exp(2 * loc + 2 * var)
        return mean, np.sqrt(np.maximum(second - mean**2, 0.0))

    def to_json(self) -> dict:
        return {"scheme": self.scheme, "rate": self.rate, "beta": self.beta, "se": self.se, "n": self.n,
                "reach": self.reach, "growth": self.growth, "growth_se": self.growth_se, "pivot": self.pivot,
                "cuts": self.cuts}

    @classmethod
    def from_json(cls, record: Mapping) -> Miss:
        extra = {k: float(record[k]) for k in ("growth", "growth_se", "pivot") if k in record}
        return cls(str(record["scheme"]), float(record["rate"]), float(record["beta"]), float(record["se"]),
                   int(record["n"]), float(record["reach"]), cuts=int(record.get("cuts", 1)), **extra)


@dataclass(frozen=True)
class Pieces:
    """What one blocked fold measured of one law: per kept held-out point the miss ``e``, the
    magnitude of the fold's mean ``m``, the scale ``u = w (d + OFFSET)`` (input units, ``w`` the
    fold's training width) and distance ``d``, and the misses' covariance ``cov``."""

    e: np.ndarray
    m: np.ndarray
    u: np.ndarray
    d: np.ndarray
    cov: np.ndarray
    w: float = 1.0

    def gls(self, growth: float) -> tuple[float, float, float]:
        """``(β̂, se, residual quadratic form)`` of ``e = β · m u^growth + η``, ``η ~ N(0, cov)``."""
        g = self.m * self.u**growth
        solve_g = np.linalg.solve(self.cov, g)
        info = float(g @ solve_g)
        if not info > 0:
            return math.nan, math.nan, math.nan
        beta = float(self.e @ solve_g) / info
        r = self.e - beta * g
        return beta, 1.0 / math.sqrt(info), float(r @ np.linalg.solve(self.cov, r))


def pieces(cv, ds: xr.Dataset, scheme: Scheme) -> Pieces | None:
    """The misses of a law on one blocked fold (see the module), or None when nothing was kept."""
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
    same_fold = kept.fold[finite][:, None] == kept.fold[finite][None, :]
    cov = np.where(same_fold, np.cov(mu, rowvar=False).reshape(index.size, index.size), 0.0)
    cov += np.diag(kept.noise_var[finite])
    cov += np.eye(index.size) * 1e-12 * float(np.trace(cov)) / index.size
    return Pieces(y[index] - m, np.abs(m), (hi - lo) * (d + OFFSET), d, cov, hi - lo)


def measure_miss(cv, ds: xr.Dataset, scheme: Scheme) -> Miss | None:
    """The miss of a law on one blocked scheme, growing with the fixed power GROWTH (see the
    module), or None when nothing was kept. ``cv`` is the law's
    :class:`bayesfric.compare.CVResult` of the scheme (with its held-out predictive), ``ds`` the
    study's data. Nested cuts along one axis: :func:`tests.sizing_growth.measure_misses`."""
    p = pieces(cv, ds, scheme)
    if p is None:
        return None
    beta, se, _ = p.gls(GROWTH)
    if not math.isfinite(beta):
        return None
    return Miss(scheme.label, math.sqrt(max(0.0, beta**2 - LAMBDA * se**2)), beta, se, int(p.e.size),
                float(np.max(p.d)) if p.d.size else 0.0)


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
    """A miss in unit-free terms: its relative sd one tested range of the full data beyond it
    along the scheme's axis, over ``(1 + OFFSET)^GROWTH`` (with the fixed growth, the rate per
    (tested range)^GROWTH): comparable across laws, schemes and inputs (the fallback is their
    maximum)."""
    lo, hi = scheme.tested(data[scheme.axis])
    return float(miss.relative((hi - lo) * (1.0 + OFFSET), width=hi - lo)) / (1.0 + OFFSET) ** GROWTH


def _family(s: Scheme) -> tuple:
    return s.axis, s.direction, s.use_abs


def relative_sd(grid: Mapping[str, np.ndarray], data: Mapping[str, np.ndarray], misses: Mapping[str, Miss],
                schemes: Sequence[Scheme], matched: Sequence[Scheme], fallback: float,
                uncovered: Sequence[Scheme]) -> np.ndarray:
    """Relative sd of a law's discrepancy at every point (:func:`discrepancy`, its sd)."""
    return discrepancy(grid, data, misses, schemes, matched, fallback, uncovered)[0]


def discrepancy(grid: Mapping[str, np.ndarray], data: Mapping[str, np.ndarray], misses: Mapping[str, Miss],
                schemes: Sequence[Scheme], matched: Sequence[Scheme], fallback: float,
                uncovered: Sequence[Scheme]) -> tuple[np.ndarray, np.ndarray]:
    """Relative sd and signed relative mean of a law's discrepancy at every point (see the module).

    Along the matched schemes the miss is ``Miss.band(L_j (d_j + OFFSET))`` (mean 0 and sd
    ``κ_j (L_j (d_j + OFFSET))^GROWTH`` from one cut); schemes along different axes or directions
    add their means and variances, nested cuts along one axis and direction (one error, measured
    more than once) give the one of largest mean square. A matched scheme without a measured miss
    for this law (its fold failed the gate) and every uncovered side (:func:`matching`, where a
    point lies beyond it) take the unit-free ``fallback`` (:func:`per_range`: the largest miss
    any law showed on any scheme) as ``fallback · (d + OFFSET)^GROWTH``. No point, inside the
    envelope included, gets a root mean square less than the largest the law showed at the edge
    of any scheme's envelope (``Miss.relative(L_j OFFSET)``): a form error seen at the edge is
    there inside too.
    """
    n = len(next(iter(grid.values())))
    edge = 0.0
    for s in schemes:
        if s.label in misses and s.axis in data:
            lo, hi = s.tested(data[s.axis])
            mean, sd = misses[s.label].band((hi - lo) * OFFSET, hi - lo)
            edge = max(edge, float(np.hypot(mean, sd)))
    family: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
    for s in matched:
        lo, hi = s.tested(data[s.axis])
        d = s.distance(grid[s.axis], lo, hi)
        if s.label in misses:
            mean, sd = misses[s.label].band(_scale(d, hi - lo), hi - lo)
        else:
            mean, sd = np.zeros(n), fallback * _scale(d, 1.0) ** GROWTH
        old_mean, old_sd = family.get(_family(s), (np.zeros(n), np.zeros(n)))
        larger = mean**2 + sd**2 >= old_mean**2 + old_sd**2
        family[_family(s)] = (np.where(larger, mean, old_mean), np.where(larger, sd, old_sd))
    shift = sum((m for m, _ in family.values()), np.zeros(n))
    var = sum((sd**2 for _, sd in family.values()), np.zeros(n))
    for s in uncovered:
        d = s.distance(grid[s.axis], *s.tested(data[s.axis]))
        var += np.where(d > 0, (fallback * _scale(d, 1.0) ** GROWTH) ** 2, 0.0)
    floor = np.maximum(edge**2 - shift**2, 0.0)  # the edge's miss, as a root mean square
    return np.sqrt(np.maximum(var, floor)), shift


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
