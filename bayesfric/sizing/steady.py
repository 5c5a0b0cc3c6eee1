"""Which law sizing evaluates: a steady law as it is, a trajectory (stateful) law by its steady
state at constant speed (:func:`bayesfric.laws.steady_state`), with the answer labelled so.

A stateful law's friction depends on the path, so at an operating point it has one value only
once the transient has settled: that steady value is what a drive must overcome in continuous
motion, and what sizing answers. Start-up (break-away) and reversal transients are not in it;
every answer from a steady state says so (:data:`~bayesfric.laws.steady.STEADY_NOTE`). A
coast-down law predicts speed; its steady state is its friction torque, and the fit's noise
(on speed) does not carry over: that answer has parameter uncertainty only.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from bayesfric.laws.base import Law
from bayesfric.laws.steady import STEADY_NOTE, steady_state
from bayesfric.sizing.points import SizingError

__all__ = ["STEADY_NOTE", "NO_NOISE_NOTE", "sizing_law", "steady_note", "tested_values", "steady_line"]

#: Added to the note of a steady state whose response is not the fitted one (a coast-down's torque).
NO_NOISE_NOTE = ("the fit's observation noise is on {fitted}, not {response}: this answer carries parameter "
                 "uncertainty only")


def sizing_law(law: Law) -> Law:
    """The law sizing evaluates for a fit of ``law``: ``law`` itself, or a trajectory law's steady state.

    Raises
    ------
    SizingError
        ``law`` is a trajectory (stateful) law that declares no steady state.

    Examples
    --------
    >>> from bayesfric.laws import get_law
    >>> sizing_law(get_law("dahl")).inputs
    ('velocity', 'preload')
    """
    steady = steady_state(law)
    if steady is None:
        raise SizingError("", f"law {law.name!r} is a trajectory (stateful) law: its friction depends on the path, "
                              "and it declares no steady state at constant speed (law(steady=...)), so it cannot "
                              "be sized at an operating point")
    return steady


def steady_note(fitted: Law, sized: Law) -> str:
    """How an answer from ``sized`` (:func:`sizing_law` of ``fitted``) is labelled: ``""`` for a
    steady law, else :data:`STEADY_NOTE` (and :data:`NO_NOISE_NOTE` where the response differs).

    Examples
    --------
    >>> from bayesfric.laws import get_law
    >>> steady_note(get_law("coulomb"), get_law("coulomb"))
    ''
    """
    if sized is fitted:
        return ""
    if sized.response != fitted.response:
        return f"{STEADY_NOTE}; {NO_NOISE_NOTE.format(fitted=fitted.response, response=sized.response)}"
    return STEADY_NOTE


def tested_values(data: Mapping[str, np.ndarray], response: str, measured: np.ndarray | None,
                  inputs: list[str]) -> dict[str, np.ndarray]:
    """The tested values of every input in ``inputs``: ``data``'s, and a coast-down's measured speed
    (its response) for a steady state that reads the velocity the data hold as response.

    Examples
    --------
    >>> tested_values({"time": np.ones(2)}, "velocity", np.array([3.0, 1.0]), ["velocity"])
    {'time': array([1., 1.]), 'velocity': array([3., 1.])}
    """
    out = dict(data)
    if response in inputs and response not in out and measured is not None:
        out[response] = np.asarray(measured, dtype=float)
    return out


def steady_line(answers, weights: Mapping[str, float] | None = None, naming: bool = True) -> str:
    """The sentence a report gives the laws among ``answers`` (:class:`~bayesfric.sizing.compute.LawAnswer`)
    that answer from a steady state (only those with a weight in ``weights``, when given): their
    names (``naming``) and notes; ``""`` when none does.

    Examples
    --------
    >>> from types import SimpleNamespace as A
    >>> steady_line([A(name="lugre", steady="steady state"), A(name="coulomb", steady="")])
    'Lugre (stateful): answered from its steady state.'
    """
    steady = [a for a in answers if a.steady and (weights is None or weights.get(a.name, 0.0) > 0)]
    if not steady:
        return ""
    notes = "; ".join(dict.fromkeys(a.steady for a in steady))
    if not naming:
        return notes
    text = f"{', '.join(a.name for a in steady)} (stateful): answered from its {notes}."
    return text[0].upper() + text[1:]
