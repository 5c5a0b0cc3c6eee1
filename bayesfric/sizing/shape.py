"""An answer beyond the data says first when the data bend away from every law it rests on, along
an operating input (the service-time counterpart, for a time to exceed: :mod:`bayesfric.sizing.bend`).

The calibrated band adds the miss the blocked folds measured, grown with the distance beyond the
data as a missing curvature grows (:mod:`bayesfric.sizing.calibration`). Where the data
themselves curve upward against every law carrying weight -- friction growing faster than any
candidate's form -- how fast that gap keeps growing beyond the data is not in the data: a cubic
and a saturating continuation fit the same tested range. The band may then fall short, and the
drive be under-sized. No band is widened here; the answer says it, before its numbers:

* the test (:class:`bayesfric.compare.lackoffit.LackOfFit`): each law's relative residuals at the
  data (:mod:`bayesfric.sizing.misfit`) regressed on the question's axis with a ``u²`` term, its
  one-sided t-test of an upward bend at :data:`~bayesfric.compare.lackoffit.STATEMENT_ALPHA`;
* the rule (:func:`bend`): along an axis the question extrapolates (some point beyond the data),
  every law with at least :data:`SHARE` of the average's weight bends upward (or, said in the
  warnings only, every one bends downward: the band then errs on the safe side);
* the statement (:attr:`Bend.statement`) in the words of the question: which way the data bend
  and by how much, that the band beyond the data assumes the measured growth and is NOT
  calibrated for that shape, and what would settle it.

A law without residuals at the data (a stateful law sized at its steady state, a fit without its
data) cannot be judged: the statement is then not made, and :attr:`Bend.unjudged` names it.
Calibration of the rule (how often a 90 % band misses the truth and nothing was said; how often
it is said when a weighted law is the truth) is measured on the exact-posterior battery of
``tests/test_sizing_calibration.py``: figures in ``docs/sizing.md``.

Examples
--------
>>> bend({"velocity": np.array([0.5])}, {"coulomb_viscous": 1.0}, {}).statement
''
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from bayesfric.compare.lackoffit import STATEMENT_ALPHA, LackOfFit

__all__ = ["SHARE", "Bend", "bend", "fits_bend"]

#: Laws with at least this weight in an average are the ones its statement is about.
SHARE = 0.2


@dataclass(frozen=True)
class Bend:
    """Which way the data bend against the weighted laws along one axis (see the module)."""

    axis: str = ""
    direction: str = ""  # "upward" | "downward" | ""
    tests: Mapping[str, LackOfFit] | None = None
    unjudged: tuple[str, ...] = ()

    @property
    def upward(self) -> bool:
        return self.direction == "upward"

    @property
    def statement(self) -> str:
        """What the answer says first (upward), or among its warnings (downward); ``""``: nothing."""
        if not self.direction:
            return ""
        laws = "; ".join(f"{name}: {t.curvature:+.1%} of its friction over the tested range, t = {t.t:.1f}"
                         for name, t in (self.tests or {}).items())
        if self.direction == "downward":
            return (f"the data bend DOWNWARD along {self.axis} against every weighted law ({laws}): friction grows "
                    "more slowly than these laws, so beyond the data they likely over-predict it and the band errs "
                    "on the safe side (a saturating law would size closer)")
        return (f"THE DATA BEND UPWARD along {self.axis} against every weighted law ({laws}): friction grows faster "
                "than these laws, so beyond the data they under-predict it by more than the data show. The "
                "calibrated band assumes the miss grows as the blocked folds measured it (quadratically with the "
                "distance) and is NOT calibrated for a curvature the laws lack; what would settle it: a law with "
                f"that curvature (a quadratic or power-law term in {self.axis}) or data nearer the asked point")


def bend(distance: Mapping[str, np.ndarray], weights: Mapping[str, float],
         tests: Mapping[str, Mapping[str, LackOfFit] | None], alpha: float = STATEMENT_ALPHA) -> Bend:
    """The bend of the data against the laws an answer rests on (see the module).

    Parameters
    ----------
    distance : mapping
        Input -> each point's distance beyond the data (tested ranges); an axis with a positive
        distance is one the question extrapolates along.
    weights : mapping
        Law -> its weight in the average (a single law: 1).
    tests : mapping
        Law -> its lack-of-fit tests by input (:meth:`bayesfric.sizing.misfit.LocalMisfit.lack_of_fit`);
        None where the law has no residuals at the data.
    alpha : float
        One-sided level of the bend test.
    """
    laws = [name for name, w in weights.items() if w >= SHARE]
    if not laws:
        return Bend()
    unjudged = tuple(name for name in laws if tests.get(name) is None)
    for axis, d in distance.items():
        if not np.any(np.asarray(d) > 0) or unjudged:
            continue
        found = {name: tests[name].get(axis) for name in laws}
        if any(t is None for t in found.values()):
            continue
        for direction, holds in (("upward", lambda t: t.convex(alpha)), ("downward", lambda t: t.concave(alpha))):
            if all(holds(t) for t in found.values()):
                return Bend(axis, direction, found, unjudged)
    return Bend(unjudged=unjudged)


def fits_bend(fits: Mapping, weights: Mapping[str, float], grid: Mapping[str, np.ndarray], seed: int = 0) -> Bend:
    """:func:`bend` for answers at the points ``grid`` (input -> SI values) from fits alone, each
    judged on its own data (``constant_data`` and ``observed_data``): what ``predict`` and
    ``score`` say beyond the fitted envelope. ``weights``: law -> weight (one fit: 1)."""
    from bayesfric.sizing.distance import point_distance
    from bayesfric.sizing.misfit import local_misfit

    tests, data = {}, {}
    for name in weights:
        fit = fits[name]
        held, observed = fit["constant_data"], fit["observed_data"].to_dataset()
        inputs = {k: np.asarray(held[k].values, dtype=float) for k in grid if k in held}
        data = data or inputs
        measured = next(iter(observed.data_vars.values()), None) if observed.data_vars else None
        misfit = local_misfit(fit, inputs, np.asarray(measured.values, dtype=float), seed) \
            if measured is not None and inputs else None
        tests[name] = misfit.lack_of_fit() if misfit is not None else None
    distance = {k: point_distance(np.asarray(g, dtype=float), data[k]) for k, g in grid.items() if k in data}
    return bend(distance, weights, tests)
