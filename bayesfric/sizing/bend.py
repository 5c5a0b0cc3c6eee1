"""Does a time to exceed rest on a trend the campaigns bend away from? The statement it leads with.

A time to exceed (:mod:`bayesfric.sizing.exceed`) extrapolates the fitted trend past the last
tested campaign. Its interval assumes the trend's form: where the campaign levels grow faster than
the trend (accelerating wear against a linear trend), the true crossing comes *sooner* than the
interval says, in nearly every data set (``benchmarks/bench_trend_forecast.py``), and neither
the data's residuals nor the leave-future-out folds show it (each campaign's level absorbs its
share of the curvature).

The check (:func:`point_bend`)
    At the operating point asked, each fitted campaign's friction (posterior mean of
    ``log |friction|`` with the campaign's own level) against the fitted trend's there (the
    typical campaign at that service time), tested for curvature along service time by
    :func:`bayesfric.compare.trendfit.curvature_test` (a t-test of a quadratic term, the
    campaign scatter its noise, ``G − 3`` degrees of freedom; each direction one-sided at 5 %).
    On friction at the point, every trending parameter enters in the direction that matters to
    the question: ``upward`` means friction there grew faster than the trend. A random walk is
    not tested (it has no trend form; its forecast widens with the time since the last campaign).

The statement (:func:`law_attrs`, :func:`lead`)
    A law whose levels bend upward gets ``shape_calibrated = 0`` and a ``statement`` in the
    words of the question (which way the levels bend, that the interval assumes the trend form
    and the measured allowance so the crossing may come earlier, what would settle it). A
    downward bend gets one clause (the crossing may come later: the interval errs safe). A model
    average leads with the statement only where every law carrying at least :data:`CARRY` of the
    weight bends that way.

Example
-------
>>> from bayesfric.compare.trendfit import Bend
>>> attrs = law_attrs(Bend(0.04, 0.01, 4.0, 4, 0.008, 0.992, 7), "linear")
>>> attrs["bend"], attrs["shape_calibrated"]
('upward', 0)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from bayesfric.compare.trendfit import Bend, curvature_test

__all__ = ["CARRY", "point_bend", "law_attrs", "statement", "lead"]

#: Weight from which a law carries a model average (as :mod:`bayesfric.sizing.answer`'s statement).
CARRY = 0.2


def point_bend(coords: np.ndarray, campaign_log: np.ndarray, trend_log: np.ndarray | None) -> Bend | None:
    """The curvature test of the campaigns' friction at the point against the trend's.

    ``campaign_log``: each campaign's posterior mean of ``log |friction|``; ``trend_log``: the
    typical campaign's at the same service times (None: a walk, not tested).

    Examples
    --------
    >>> t = np.arange(7) * 500.0
    >>> point_bend(t, 0.03 * ((t - 1500) / 1500) ** 2, np.zeros(7)).direction
    'upward'
    """
    if trend_log is None:
        return None
    return curvature_test(coords, np.asarray(campaign_log, dtype=float) - np.asarray(trend_log, dtype=float))


def _settle(form: str) -> str:
    if "linear" in form.split(" / "):
        return 'a trend form with that curvature (trend_form = "loglinear")'
    return "a trend form that bends more than the log-linear one (none is built in)"


def statement(direction: str, form: str, evidence: str, laws: str = "") -> str:
    """The sentence a time to exceed leads with, for an ``upward`` or ``downward`` bend ("" else).

    ``form``: the trend form the interval assumes; ``evidence``: the test's clause(s);
    ``laws``: for a model average, the laws carrying its weight.

    Examples
    --------
    >>> statement("downward", "linear", "curvature t = -3.1")[:60]
    'The campaign levels bend downward (friction grew slower than'
    """
    who = f"In every law carrying the average's weight ({laws}), t" if laws else "T"
    if direction == "upward":
        return (f"{who}he campaign levels bend upward: friction at this point grew faster across the tested "
                f"campaigns than the fitted {form} trend ({evidence}). The interval of the time to exceed assumes "
                f"the {form} trend (and the measured model-form allowance), so the true crossing may come EARLIER "
                f"than it says: the interval is not calibrated for this shape. What would settle it: "
                f"{_settle(form)}, or a test campaign nearer the horizon.")
    if direction == "downward":
        return (f"{who}he campaign levels bend downward (friction grew slower than the fitted {form} trend, "
                f"{evidence}): the crossing may come later than the interval says, which errs safe.")
    return ""


def law_attrs(bend: Bend | None, form: str) -> dict[str, Any]:
    """One law's attrs: ``bend`` (upward, downward, none, not tested), ``bend_test`` (the test, or
    why none), ``shape_calibrated`` (0 for an upward bend, else 1) and ``statement``.

    Examples
    --------
    >>> law_attrs(None, "walk")["bend"]
    'not tested'
    """
    if bend is None:
        why = ("a random walk has no trend form to bend from" if form == "walk" else
               "fewer than 4 campaigns: no degree of freedom left for a curvature")
        return {"bend": "not tested", "bend_test": why, "shape_calibrated": 1, "statement": ""}
    return {"bend": bend.direction, "bend_test": bend.describe(), "shape_calibrated": int(bend.direction != "upward"),
            "statement": statement(bend.direction, form, bend.describe())}


def lead(results: Mapping[str, Any], weights: Mapping[str, float]) -> dict[str, Any]:
    """A model average's ``bend``, ``bend_test`` (each carrying law's), ``shape_calibrated`` and
    ``statement``: a bend only where every law carrying at least :data:`CARRY` of the weight (each
    result's attrs from :func:`law_attrs`) bends the same way.

    Examples
    --------
    >>> up = {"bend": "upward", "form": "linear", "bend_test": "t = 3"}
    >>> lead({"a": up, "b": {"bend": "none"}}, {"a": 0.9, "b": 0.1})["shape_calibrated"]
    0
    """
    total = sum(max(float(w), 0.0) for w in weights.values()) or 1.0
    carrying = [n for n in results if float(weights.get(n, 0.0)) / total >= CARRY]
    attrs = {n: dict(getattr(results[n], "attrs", results[n])) for n in carrying}
    bends = {str(a.get("bend", "not tested")) for a in attrs.values()}
    evidence = "; ".join(f"{n}: {a.get('bend', 'not tested')}, {a.get('bend_test', '')}" for n, a in attrs.items())
    if len(bends) != 1 or not bends <= {"upward", "downward"}:
        return {"bend": "mixed" if len(bends) > 1 else next(iter(bends), "none"), "bend_test": evidence,
                "shape_calibrated": 1, "statement": ""}
    direction = bends.pop()
    forms = sorted({str(a.get("form", "")) for a in attrs.values()})
    laws = ", ".join(f"{n} {float(weights[n]) / total:.2f}" for n in carrying)
    return {"bend": direction, "bend_test": evidence, "shape_calibrated": int(direction != "upward"),
            "statement": statement(direction, " / ".join(forms), evidence, laws)}
