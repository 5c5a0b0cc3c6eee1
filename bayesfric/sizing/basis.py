"""Which weights and which measured misses answer a sizing question: the basis, chosen once per
question from the direction its points lie in (:mod:`bayesfric.sizing.calibration`).

* Some point lies beyond the data along an input, and blocked schemes extrapolate in that
  direction: the laws are mixed by the stacking weights of those schemes (their mean when
  several match), and each law is widened by the miss it showed on them.
* Some point lies beyond the data in a direction no scheme tests (a cold start against a
  warm-side fold): LOO stacking weights, widened along that input by the largest miss any law
  showed on any scheme, and the answer says so first.
* Every point inside the data: LOO stacking weights, no widening; for an answer about a NEW
  group (run, series, unit) of laws with group terms, the stacking weights of leave-one-group-out
  instead (:data:`NEW_GROUP`: how well each law predicted a whole group it had not seen, the
  question asked), also where LOO weights stand in for a direction no scheme tests.
* **No law extrapolates**: on a matched scheme every law loses more than
  :data:`NO_EXTRAPOLATION` nats per held-out point against its LOO score (the extrapolation
  penalty); the answer says so first and quotes only calibrated numbers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bayesfric.sizing.calibration import Miss, Scheme, matching, per_range

__all__ = ["LOO", "NEW_GROUP", "NO_EXTRAPOLATION", "Basis", "choose_basis"]

#: Weighting key of PSIS-LOO stacking (blocked schemes are keyed by their label).
LOO = "LOO"
#: Weighting key of leave-one-group-out stacking, answering for a new group (:func:`bayesfric.sizing.sources`).
NEW_GROUP = "new group"
#: Extrapolation penalty (nats per held-out point) above which a law is taken not to extrapolate.
NO_EXTRAPOLATION = 2.0


@dataclass(frozen=True)
class Basis:
    """The weights and misses one question is answered from, and why.

    ``weights``: law -> weight (renormalised later over the laws used); ``schemes``: matched
    blocked schemes; ``uncovered``: sides beyond the data no scheme tests; ``fallback_rate``: the
    largest measured miss rate, unit-free
    (:func:`~bayesfric.sizing.calibration.per_range`; NaN: none measured); ``no_extrapolation``: why no law
    extrapolates here ("" when some law does); ``note``: the basis in words.
    """

    key: str
    weights: dict[str, float]
    schemes: tuple[Scheme, ...]
    uncovered: tuple[Scheme, ...]
    fallback_rate: float
    no_extrapolation: str
    note: str

    @property
    def calibrated(self) -> bool:
        """True when a miss was measured (else no model-form error can be added)."""
        return math.isfinite(self.fallback_rate)


def _side(s: Scheme) -> str:
    name = f"|{s.axis}|" if s.use_abs else s.axis
    return f"{name} {'above' if s.direction == 'upper' else 'below'} the data"


def _mean_weights(names: Sequence[str], weights: Mapping[str, Mapping[str, float]], keys: Sequence[str]):
    rows = []
    for key in keys:
        w = np.array([weights.get(n, {}).get(key, math.nan) for n in names], dtype=float)
        if np.isfinite(w).any() and np.nansum(w) > 0:
            rows.append(np.nan_to_num(w) / np.nansum(w))
    return dict(zip(names, np.mean(rows, axis=0), strict=True)) if rows else None


def _no_extrapolation(names, penalties: Mapping[str, Mapping[str, float]], schemes: Sequence[Scheme]) -> str:
    for s in schemes:
        values = {n: penalties.get(n, {}).get(s.label, math.nan) for n in names}
        known = {n: v for n, v in values.items() if math.isfinite(v)}
        if known and len(known) == len(values) and min(known.values()) > NO_EXTRAPOLATION:
            best = min(known, key=known.get)
            return (f"no law extrapolates along '{s.label}': every law loses more than {NO_EXTRAPOLATION:g} nats per "
                    f"held-out point beyond its training envelope (the least, {best}, {known[best]:.3g})")
    return ""


def choose_basis(grid: Mapping[str, np.ndarray], data: Mapping[str, np.ndarray], schemes: Sequence[Scheme],
                 names: Sequence[str], weights: Mapping[str, Mapping[str, float]],
                 misses: Mapping[str, Mapping[str, Miss]],
                 penalties: Mapping[str, Mapping[str, float]]) -> Basis:
    """The basis of one question (see the module).

    ``names``: the laws sizing may use; ``weights``: law -> {weighting key -> weight}
    (:data:`LOO`, :data:`NEW_GROUP` or a blocked label); ``misses``: law -> {blocked label -> Miss};
    ``penalties``: law -> {blocked label -> nats per held-out point}.
    """
    matched, uncovered = matching(grid, data, schemes)
    by_label = {s.label: s for s in schemes if s.axis in data}
    rates = [per_range(m, by_label[k], data) for law in misses.values() for k, m in law.items() if k in by_label]
    fallback = max(rates) if rates else math.nan
    chosen = _mean_weights(names, weights, [s.label for s in matched]) if matched else None
    notes = []
    if chosen is not None:
        key = "stacking " + " + ".join(f"'{s.label}'" for s in matched)
        notes.append(f"weights: stacking on the blocked fold(s) that extrapolate in this direction ({key[9:]})")
    else:
        grouped = _mean_weights(names, weights, [NEW_GROUP])
        key = "stacking leave-one-group-out" if grouped is not None else f"stacking {LOO}"
        what = ("leave-one-group-out stacking weights (how well each law predicted a whole group it had not "
                "seen: the answer is for a new group)" if grouped is not None else "LOO stacking weights")
        chosen = grouped or _mean_weights(names, weights, [LOO]) or ({names[0]: 1.0} if len(names) == 1 else {})
        if matched or uncovered:
            notes.append(f"no blocked fold with usable weights extrapolates in this direction: {what}")
        else:
            notes.append(f"every point lies inside the tested envelope: {what}")
    if uncovered:
        sides = ", ".join(_side(s) for s in uncovered)
        widen = (f"widened by the largest miss any law showed on any blocked fold ({fallback:.2g} relative per "
                 "tested range squared)" if math.isfinite(fallback) else
                 "and no blocked fold measured any law's miss: the model-form error there is UNMEASURED")
        notes.insert(0, f"NO blocked fold tests {sides}: {widen}")
    return Basis(key, dict(chosen), tuple(matched), tuple(uncovered), fallback,
                 _no_extrapolation(names, penalties, matched), "; ".join(notes))
