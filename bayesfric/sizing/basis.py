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
* **A new run that the laws are blind to**: where the residual-structure check flagged a group
  column (:mod:`bayesfric.sizing.newrun`) and laws that model it can be used, only those are
  weighed (equal weights where none of them has a positive weight under the chosen weighting);
  the basis's ``new_run`` says so, and an answer says it first. Beyond the data, such a question
  is about a new run *and* an untested range: the matched blocked folds scored with new-run draws,
  each run's rows jointly (:mod:`bayesfric.compare.newgroup`), weigh the laws where the study has
  at least four runs; with two or three they cannot tell laws apart, and the blocked folds'
  weights stand in (:data:`NEW_RUN_FALLBACK`, said in the note).
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

__all__ = ["LOO", "NEW_GROUP", "NO_EXTRAPOLATION", "NEW_RUN_FALLBACK", "Basis", "choose_basis"]

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
    extrapolates here ("" when some law does); ``note``: the basis in words; ``new_run``: the
    new-run rule's statement (:class:`~bayesfric.sizing.newrun.NewRun`, "" when no group column
    was flagged), said before any number.
    """

    key: str
    weights: dict[str, float]
    schemes: tuple[Scheme, ...]
    uncovered: tuple[Scheme, ...]
    fallback_rate: float
    no_extrapolation: str
    note: str
    new_run: str = ""

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


#: What stands in where a blocked fold scored for a new run cannot weigh the laws (too few runs).
NEW_RUN_FALLBACK = ("for a new run beyond the data, the blocked fold scored with new-run draws cannot tell the laws "
                    "apart (fewer than 4 runs: bayesfric.compare.newgroup); the blocked fold's weights stand in "
                    "(how each law extrapolates the tested runs; a new run's own spread is in each law's band)")


def _new_run_weights(names, weights, matched, new_run) -> tuple[dict, str, str] | None:
    """(weights, key, note) of the matched blocked folds scored for a new level of a flagged group
    column (:mod:`bayesfric.compare.newgroup`); None where there are none (too few runs)."""
    if not matched or new_run is None or not new_run.mode:
        return None
    from bayesfric.compare.newgroup import label

    keys = [label(c, s.label) for s in matched for c in new_run.columns]
    chosen = _mean_weights(names, weights, keys)
    if chosen is None:
        return None
    return (chosen, "stacking " + " + ".join(f"'{k}'" for k in keys),
            "weights: stacking on the blocked fold(s) that extrapolate in this direction, each run's held-out rows "
            "scored jointly as a new run's (" + ", ".join(f"'{k}'" for k in keys) + ")")


def choose_basis(grid: Mapping[str, np.ndarray], data: Mapping[str, np.ndarray], schemes: Sequence[Scheme],
                 names: Sequence[str], weights: Mapping[str, Mapping[str, float]],
                 misses: Mapping[str, Mapping[str, Miss]],
                 penalties: Mapping[str, Mapping[str, float]], new_run=None) -> Basis:
    """The basis of one question (see the module).

    ``names``: the laws sizing may use; ``weights``: law -> {weighting key -> weight}
    (:data:`LOO`, :data:`NEW_GROUP` or a blocked label); ``misses``: law -> {blocked label -> Miss};
    ``penalties``: law -> {blocked label -> nats per held-out point}; ``new_run``: the new-run
    rule (:class:`~bayesfric.sizing.newrun.NewRun`; None: no group column flagged).
    """
    restricted = new_run is not None and new_run.mode == "aware"
    names = new_run.names(names) if restricted else list(names)
    matched, uncovered = matching(grid, data, schemes)
    by_label = {s.label: s for s in schemes if s.axis in data}
    rates = [per_range(m, by_label[k], data) for law in misses.values() for k, m in law.items() if k in by_label]
    fallback = max(rates) if rates else math.nan
    chosen = _mean_weights(names, weights, [s.label for s in matched]) if matched else None
    notes = []
    fresh = _new_run_weights(names, weights, matched, new_run)
    if fresh is not None:
        chosen, key, note = fresh
        notes.append(note)
    elif chosen is not None:
        key = "stacking " + " + ".join(f"'{s.label}'" for s in matched)
        notes.append(f"weights: stacking on the blocked fold(s) that extrapolate in this direction ({key[9:]})")
        if matched and new_run is not None and new_run.mode:
            notes.append(f"{NEW_RUN_FALLBACK} over {', '.join(names)}")
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
    if restricted and not chosen and names:
        key = "equal weights over the laws that model the flagged group"
        chosen = dict.fromkeys(names, 1.0 / len(names))
        notes.append(f"none of the laws that model the flagged group ({', '.join(names)}) has a positive weight "
                     f"there: {key}")
    if uncovered:
        sides = ", ".join(_side(s) for s in uncovered)
        widen = (f"widened by the largest miss any law showed on any blocked fold ({fallback:.2g} relative per "
                 "tested range squared)" if math.isfinite(fallback) else
                 "and no blocked fold measured any law's miss: the model-form error there is UNMEASURED")
        notes.insert(0, f"NO blocked fold tests {sides}: {widen}")
    return Basis(key, dict(chosen), tuple(matched), tuple(uncovered), fallback,
                 _no_extrapolation(names, penalties, matched), "; ".join(notes),
                 new_run.statement if new_run is not None else "")
