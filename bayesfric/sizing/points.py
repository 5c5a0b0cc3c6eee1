"""Sizing questions: operating values with units, ranges, and their checks against the data.

A value is a number and a pint unit of the quantity it names, ``"8 MN*m"``, ``"1.04 rpm"``,
``"5 degC"`` (``°`` and ``·`` are accepted for ``deg`` and ``*``); a *range* is two numbers and one
unit, ``"0.5..6 rad/s"`` (smaller first), sized at :data:`RANGE_POINTS` evenly spaced points, both
ends included. Values are converted to SI and checked against the quantity's physical bound
(on the bound within the conversion's rounding: -459.67 degF is 0 K) and against the largest
magnitude an operating value has, :data:`bayesfric.quantities.SCALE_RANGE` (1e12 in SI); the unit
the user wrote is kept for display. A capacity is a magnitude: it must be positive.

Every problem is a :class:`SizingError` carrying the key it concerns and a one-line problem;
callers prefix the location (``studies/x.toml: sizing[0].at.velocity: ...`` or ``--at velocity: ...``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from bayesfric.errors import UserError
from bayesfric.quantities import QUANTITIES, SCALE_RANGE, UnitError, conversion, rounding_slack

__all__ = [
    "RANGE_POINTS", "CLI_KEYS", "SizingError", "Value", "SizingQuestion", "parse_value", "parse_capacity",
    "parse_at", "make_question", "check_question", "value_text",
]

#: Points at which a range is sized (evenly spaced, both ends included).
RANGE_POINTS = 25

_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"
_VALUE = re.compile(rf"\s*({_NUMBER})\s*(.*?)\s*")
_RANGE = re.compile(rf"\s*({_NUMBER})\s*\.\.\s*({_NUMBER})\s*(.*?)\s*")
_EXAMPLES = {"torque": "40 kN*m", "force": "2 kN", "angle": "90 deg", "velocity": "1.04 rpm",
             "bending_moment": "8 MN*m", "temperature": "5 degC"}


class SizingError(UserError):
    """A bad sizing question: ``key`` (what it concerns, may be empty) and a one-line ``problem``."""

    def __init__(self, key: str, problem: str):
        super().__init__(problem, key)


@dataclass(frozen=True)
class Value:
    """A value (or range) of one quantity: SI bounds, and the text and unit the user wrote."""

    quantity: str
    lo: float
    hi: float
    text: str
    unit: str
    scale: float  # si = scale * written + offset
    offset: float

    @property
    def is_range(self) -> bool:
        return self.hi > self.lo

    def points(self) -> np.ndarray:
        """SI values at which the value is sized: one, or :data:`RANGE_POINTS` across a range."""
        return np.linspace(self.lo, self.hi, RANGE_POINTS) if self.is_range else np.array([self.lo])

    def display(self, si):
        """SI value(s) in the unit the user wrote."""
        return (np.asarray(si, dtype=float) - self.offset) / self.scale


def _example(quantity: str) -> str:
    return _EXAMPLES.get(quantity, f"1 {QUANTITIES[quantity].unit}" if quantity in QUANTITIES else "1 N*m")


def parse_value(text: object, quantity: str, key: str = "", allow_range: bool = True) -> Value:
    """Parse ``"<number> <unit>"`` (or ``"<lo>..<hi> <unit>"``) as a value of ``quantity``.

    Raises
    ------
    SizingError
        Not a string, no number, no unit, an unknown unit or one of another dimension, a range
        where none is allowed, an empty or reversed range, a non-finite value, one outside the
        quantity's physical bound or one above :data:`bayesfric.quantities.SCALE_RANGE` in magnitude.
    """
    key = key or quantity
    if quantity not in QUANTITIES:
        raise SizingError(key, f"{quantity!r} is not an operating quantity ({', '.join(QUANTITIES)})")
    example = _example(quantity)
    if not isinstance(text, str) or not text.strip():
        shown = repr(text) if not isinstance(text, str) else "an empty string"
        raise SizingError(key, f"give the value with its unit as a string, e.g. \"{example}\", got {shown}")
    match = _RANGE.fullmatch(text) if allow_range else None
    if match:
        numbers, unit = (float(match.group(1)), float(match.group(2))), match.group(3)
    elif (match := _VALUE.fullmatch(text)) and not text.strip().startswith("..") and ".." not in text:
        numbers, unit = (float(match.group(1)),), match.group(2)
    elif ".." in text and not allow_range:
        raise SizingError(key, f"a single value is needed here, not a range: {text!r}")
    else:
        form = f"\"{example}\"" + (" or a range \"<low>..<high> <unit>\"" if allow_range else "")
        raise SizingError(key, f"cannot read {text!r}: expected a number and a unit, e.g. {form}")
    if not unit:
        raise SizingError(key, f"{text!r} has no unit; write it with one, e.g. \"{example}\"")
    try:
        scale, offset = conversion(unit, quantity)
    except UnitError as exc:
        raise SizingError(key, f"{text!r}: {exc}") from None
    with np.errstate(over="ignore", invalid="ignore"):
        si = [scale * x + offset for x in numbers]
    if not all(math.isfinite(x) for x in si):
        raise SizingError(key, f"{text!r} is not a finite value")
    bad = QUANTITIES[quantity].violations(np.asarray(si), rounding_slack(numbers, scale, offset))
    if bad.any():
        raise SizingError(key, f"{text!r} is outside the physical bound of {quantity} "
                               f"({QUANTITIES[quantity].bound_text()})")
    if max(abs(x) for x in si) > SCALE_RANGE[1]:  # beyond it the unit is wrong, and laws overflow
        raise SizingError(key, f"{text!r} is {max(abs(x) for x in si):.3g} {QUANTITIES[quantity].unit} in SI, above "
                               f"the {SCALE_RANGE[1]:g} that any operating value stays below; check the unit")
    if len(si) == 2 and not si[1] > si[0]:
        raise SizingError(key, f"range {text!r} must go from the smaller to the larger value")
    return Value(quantity, si[0], si[-1], text.strip(), unit, scale, offset)


def value_text(value: object, key: str, quantity: str) -> str:
    """A value given in Python as ``"2 rad/s"``, ``(2, "rad/s")`` or a range ``(0.5, 6, "rad/s")``
    -> its text (what :func:`parse_value` reads). A bare number has no unit: a :class:`SizingError`
    naming ``key`` and showing both forms with the unit of ``quantity``."""
    if isinstance(value, str):
        return value
    unit = QUANTITIES[quantity].unit if quantity in QUANTITIES else "N*m"
    if _is_number(value):
        raise SizingError(key, f"{value!r} has no unit; give it as ({value!r}, \"{unit}\") or \"{value} {unit}\"")
    if isinstance(value, tuple | list) and len(value) in (2, 3) and isinstance(value[-1], str) \
            and all(_is_number(x) for x in value[:-1]):
        numbers = [str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else repr(float(x)) for x in value[:-1]]
        return f"{'..'.join(numbers)} {value[-1]}"
    raise SizingError(key, f"expected \"<number> <unit>\", (number, \"{unit}\") or (low, high, \"{unit}\"), "
                           f"got {value!r}")


def _is_number(x: object) -> bool:
    return isinstance(x, int | float | np.integer | np.floating) and not isinstance(x, bool | np.bool_)


def parse_capacity(text: object, response: str | None = None, key: str = "capacity") -> Value:
    """The available drive capacity: a positive torque or force (the data's ``response`` once known).

    Friction is sized by its magnitude, so a capacity is a magnitude too: zero or negative is an
    error, not a question whose answer is "always exceeded".
    """
    value = parse_value(text, response, key, allow_range=False) if response is not None else _torque_or_force(text, key)
    if not value.lo > 0:
        raise SizingError(key, f"{value.text!r}: a capacity is the magnitude a drive delivers, so it must be "
                               "positive")
    return value


def _torque_or_force(text: object, key: str) -> Value:
    problems = []
    for quantity in ("torque", "force"):
        try:
            return parse_value(text, quantity, key, allow_range=False)
        except SizingError as exc:
            problems.append(exc.problem)
    if isinstance(text, str) and text.strip() and "dimension" in problems[0]:
        raise SizingError(key, f"{text!r} is neither a torque (N*m) nor a force (N)")
    raise SizingError(key, problems[0])


def parse_at(text: str, option: str = "--at") -> dict[str, str]:
    """``"bending_moment=8 MN*m, velocity=1.04 rpm"`` -> {input: value text}."""
    out: dict[str, str] = {}
    if not isinstance(text, str) or not text.strip():
        raise SizingError(option, 'give the point as "INPUT=VALUE UNIT, ...", e.g. "velocity=2 rad/s"')
    for item in text.split(","):
        if "=" not in item:
            raise SizingError(option, f"{item.strip()!r}: expected INPUT=VALUE UNIT, e.g. \"velocity=2 rad/s\"")
        name, value = (s.strip() for s in item.split("=", 1))
        if not name:
            raise SizingError(option, f"{item.strip()!r}: the input name is missing before '='")
        if name in out:
            raise SizingError(option, f"input {name!r} is given twice")
        out[name] = value
    return out


@dataclass(frozen=True)
class SizingQuestion:
    """One sizing question (a ``[[sizing]]`` entry, or ``size FIT.nc --at ...``).

    ``at`` maps every input to its :class:`Value` (at most one range); ``capacity`` is the
    available drive torque or force; ``energy_rotation`` the angle of one rotation whose friction
    energy is asked (torque responses only); ``horizon`` the latest service time of a *time to
    exceed* question (the capacity, at one point, for laws with a trend: :mod:`bayesfric.sizing.exceed`).
    """

    label: str
    at: dict[str, Value]
    confidence: float
    capacity_text: str | None = None
    energy_rotation: Value | None = None
    capacity: Value | None = None  # parsed against the data's response by check_question
    horizon: str | None = None  # a time-to-exceed question: the latest service time ("20000 h")

    @property
    def axis(self) -> str | None:
        """The input given as a range, if any."""
        return next((k for k, v in self.at.items() if v.is_range), None)

    def grid(self) -> dict[str, np.ndarray]:
        """SI value of every input at every point of the question (ranges expanded)."""
        axis = self.axis
        n = len(self.at[axis].points()) if axis else 1
        return {k: v.points() if k == axis else np.full(n, v.lo) for k, v in self.at.items()}

    def describe(self) -> str:
        return ", ".join(f"{k} = {v.text}" for k, v in self.at.items())


#: How errors name the keys of a question: study-file keys (``sizing[i].at.velocity``) or CLI options.
CLI_KEYS = {"at": "--at", "confidence": "--confidence", "capacity": "--capacity", "horizon": "--horizon",
            "energy_rotation": "--energy-rotation"}


def _key(keys: Mapping[str, str] | None, name: str, sub: str | None = None) -> str:
    base = (keys or {}).get(name, name)
    if sub is None:
        return base
    return f"{base} {sub}" if base.startswith("--") else f"{base}.{sub}"


def make_question(at: Mapping[str, object], confidence: float, *, label: str = "", capacity: object = None,
                  energy_rotation: object = None, keys: Mapping[str, str] | None = None,
                  horizon: object = None) -> SizingQuestion:
    """Parse a question's values (data-independent checks). ``keys`` renames the keys errors name
    (:data:`CLI_KEYS` for the command line); by default they are the study file's."""
    if not at:
        raise SizingError(_key(keys, "at"), "name at least one operating input and its value")
    values = {}
    for name, text in at.items():
        if name not in QUANTITIES:
            raise SizingError(_key(keys, "at", name), f"{name!r} is not an operating quantity "
                                                      f"({', '.join(QUANTITIES)})")
        values[name] = parse_value(text, name, _key(keys, "at", name))
    ranges = [k for k, v in values.items() if v.is_range]
    if len(ranges) > 1:
        raise SizingError(_key(keys, "at"), f"at most one input may be a range (the fan figure's axis), got "
                                            f"{', '.join(ranges)}")
    if not 0 < confidence < 1:
        raise SizingError(_key(keys, "confidence"), f"must be in (0, 1), got {confidence:g}")
    if capacity is not None:
        parse_capacity(capacity, key=_key(keys, "capacity"))
    rotation = None
    if energy_rotation is not None:
        rotation = parse_value(energy_rotation, "angle", _key(keys, "energy_rotation"), allow_range=False)
        if not rotation.lo > 0:
            raise SizingError(_key(keys, "energy_rotation"), f"must be a positive angle, got {rotation.text!r}")
    label = label or ", ".join(f"{k} {v.text}" for k, v in values.items())
    if horizon is not None:
        _check_horizon(horizon, capacity, ranges, keys)
    return SizingQuestion(label, values, float(confidence), capacity, rotation,
                          horizon=None if horizon is None else str(horizon))


def _check_horizon(horizon: object, capacity: object, ranges: list[str], keys: Mapping[str, str] | None) -> None:
    """A time-to-exceed question: a service time, a capacity to exceed, one operating point."""
    try:
        parse_horizon(horizon)
    except SizingError as exc:
        raise SizingError(_key(keys, "horizon"), exc.problem) from None
    if capacity is None:
        raise SizingError(_key(keys, "capacity"), "a horizon asks when friction exceeds the capacity: give it")
    if ranges:
        raise SizingError(_key(keys, "at"), f"a horizon asks about one operating point, not a range of {ranges[0]}")


def check_question(question: SizingQuestion, inputs: Iterable[str], required: Iterable[str], response: str,
                   keys: Mapping[str, str] | None = None, inputs_of: str = "the data") -> SizingQuestion:
    """Checks against the data: every input named is one of ``inputs``; every one of ``required``
    (what the candidate laws read) is given; the capacity is of the ``response`` quantity; an
    energy needs a torque response. Returns the question with its capacity parsed."""
    inputs, required = list(inputs), list(required)
    for name in question.at:
        if name not in inputs:
            raise SizingError(_key(keys, "at", name), f"{name!r} is not an input of {inputs_of} "
                                                  f"(inputs: {', '.join(inputs)})")
    missing = [r for r in required if r not in question.at]
    if missing:
        raise SizingError(_key(keys, "at"), f"give a value for every input the laws read: missing {', '.join(missing)} "
                                  f"(inputs read: {', '.join(required)})")
    capacity = None
    if question.capacity_text is not None:
        capacity = parse_capacity(question.capacity_text, response, key=_key(keys, "capacity"))
    if question.energy_rotation is not None and response != "torque":
        raise SizingError(_key(keys, "energy_rotation"),
                          f"the energy of a rotation needs a torque response, the data has {response}")
    return SizingQuestion(question.label, question.at, question.confidence, question.capacity_text,
                          question.energy_rotation, capacity, question.horizon)


#: Dimensions a service coordinate may have (pint's): a service time, a distance run, a count of cycles.
SERVICE_DIMENSIONS = {"[time]": "a service time", "[length]": "a distance", "": "a count (cycles, revolutions)"}


def _service_dimension(written: str, horizon: object) -> str:
    """The dimension of the unit ``written`` in a horizon, one of :data:`SERVICE_DIMENSIONS`."""
    from bayesfric.quantities import ureg

    try:
        dims = str(ureg.Quantity(1.0, written).dimensionality)
    except Exception:  # pint's errors: undefined unit, bad syntax
        raise SizingError("horizon", f"{horizon!r}: unknown unit {written!r}") from None
    dims = "" if dims == "dimensionless" else dims
    if dims not in SERVICE_DIMENSIONS:
        raise SizingError("horizon", f"{horizon!r}: {written!r} is of dimension {dims}, not a service time, distance "
                          "or count of cycles (e.g. \"20000 h\")")
    return dims


def parse_horizon(horizon: object, unit: str | None = None) -> float:
    """The horizon as a number in the service coordinate's ``unit``.

    A number is taken in that unit; a text ``"20000 h"`` is converted to it. ``unit`` None: the
    service coordinate is not known yet (the question alone is checked: a written unit must be of
    a service time, a distance or a count); ``""``: it declares no unit, so a written unit cannot
    be converted and is refused.

    Raises
    ------
    SizingError
        Not a positive number; a unit of another dimension (``"20000 rpm"``); a unit that cannot
        be converted to ``unit`` or where the service coordinate declares none.

    Examples
    --------
    >>> parse_horizon("72000000 s", "h")
    20000.0
    >>> parse_horizon(500, "h")
    500.0
    """
    written = ""
    if isinstance(horizon, int | float) and not isinstance(horizon, bool):
        value = float(horizon)
    else:
        match = re.fullmatch(r"\s*([-+0-9.eE]+)\s*(.*?)\s*", str(horizon))
        try:
            value, written = float(match.group(1)), match.group(2)
        except (AttributeError, ValueError):
            raise SizingError("horizon", f"cannot read {horizon!r}: give a service time, e.g. \"20000 h\"") from None
    if not np.isfinite(value) or value <= 0:
        raise SizingError("horizon", f"must be a positive service time, got {horizon!r}")
    if not written or written == unit:
        return value
    _service_dimension(written, horizon)
    if unit is None:
        return value
    if not unit:
        raise SizingError("horizon", f"{horizon!r}: the service coordinate declares no unit to convert {written!r} "
                          "into; give the horizon as a plain number in its unit, or declare the column's unit")
    from bayesfric.quantities import ureg

    try:
        return float(ureg.Quantity(value, written).to(unit).magnitude)
    except Exception:  # pint's errors: another dimension than the coordinate's
        raise SizingError("horizon", f"{horizon!r} cannot be expressed in {unit!r}, the unit of the service "
                          "coordinate") from None
