"""How numbers and units are written in a report: one function for each.

:func:`fmt` writes a value rounded to its standard error (or to a few significant digits when
it has none), so no table shows more digits than the estimate carries ("± 0.0", "0.5001",
"5.505e-10" do not appear). :func:`unit` writes a pint unit string as an engineer reads it
(``"N*m"`` → ``N·m``, ``"degC"`` → ``°C``, ``"mm**2"`` → ``mm²``).

Rounding rule (as in the Particle Data Group's convention, simplified): the standard error keeps
**two** significant digits when its leading digit is 1 or 2 (so 0.14 stays 0.14, not 0.1, a 40 %
change) and **one** otherwise; the value is rounded to the same decimal place. A value that would
need more than :data:`MAX_PLAIN` digits before or :data:`MIN_PLAIN` zeros after the decimal point
is written as ``a × 10ⁿ`` (with its error in the same power).
"""

from __future__ import annotations

import math
import re

__all__ = ["fmt", "unit", "MAX_PLAIN", "MIN_PLAIN"]

#: Largest magnitude written without a power of ten.
MAX_PLAIN = 1e6
#: Smallest non-zero magnitude written without a power of ten.
MIN_PLAIN = 1e-3

_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _finite(x: object) -> bool:
    try:
        return math.isfinite(float(x))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False


def _error_digits(se: float) -> tuple[float, int]:
    """``se`` rounded to one or two significant digits, and the decimal place it ends at."""
    exponent = math.floor(math.log10(se))
    sig = 2 if se / 10.0**exponent < 2.95 else 1
    place = exponent - sig + 1
    rounded = round(se, -place)
    if rounded >= 10.0 ** (exponent + 1):  # 0.96 → 1.0: the error gained a digit; keep two
        exponent += 1
        place = exponent - 1
        rounded = round(se, -place)
    return rounded, place


def _plain(value: float, place: int) -> str:
    """``value`` rounded to the decimal ``place`` (10**place), without a power of ten; no "-0"."""
    text = f"{value:.{-place}f}" if place < 0 else f"{round(value, -place):.0f}"
    return text.lstrip("-") if float(text) == 0 else text


def _sig(value: float, digits: int) -> tuple[str, int]:
    """``value`` at ``digits`` significant digits, trailing zeros dropped, and its decimal place."""
    exponent = math.floor(math.log10(abs(value)))
    place = exponent - digits + 1
    text = _plain(value, place)
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return text, place


def _power(value: float, se: float | None, digits: int, pm: bool) -> str:
    """``a × 10ⁿ`` (``(a ± b) × 10ⁿ`` with an error shown)."""
    exponent = math.floor(math.log10(abs(value) if value != 0 else se))
    scale = 10.0**exponent
    head = fmt(value / scale, None if se is None else se / scale, digits=digits, pm=pm)
    power = f"10{str(exponent).translate(_SUPERSCRIPT)}"
    return f"({head}) × {power}" if se is not None and pm else f"{head} × {power}"


def fmt(value: float, se: float | None = None, *, digits: int = 3, pm: bool = True) -> str:
    """A number as the report writes it.

    Parameters
    ----------
    value : float
        The estimate. Not finite (NaN, missing): ``"–"``; ±inf: ``"+∞"``/``"−∞"``.
    se : float, optional
        Its standard error (or posterior sd). When finite and > 0 the value is rounded to the
        error's last significant digit (two significant digits when the error's leading digit
        is 1 or 2, one otherwise) and written ``"value ± se"``; without it, or when it is 0 or
        not finite, the value gets ``digits`` significant digits with trailing zeros dropped.
    digits : int
        Significant digits of a value without a usable error.
    pm : bool
        False: write only the value, rounded to the error's place (for a mean next to its sd, an
        interval's ends next to the posterior sd).

    Returns
    -------
    str
        E.g. ``fmt(12.345, 0.234) == "12.35 ± 0.23"``, ``fmt(12.345, 3.1) == "12 ± 3"``,
        ``fmt(0.50012) == "0.5"``, ``fmt(5.505e-10) == "5.51 × 10⁻¹⁰"``.
    """
    if not _finite(value):
        if isinstance(value, float | int) and math.isinf(value):
            return "+∞" if value > 0 else "−∞"
        return "–"
    value = float(value)
    has_se = se is not None and _finite(se) and float(se) > 0
    if not has_se:
        if value == 0:
            return "0"
        if not MIN_PLAIN <= abs(value) < MAX_PLAIN:
            return _power(value, None, digits, pm)
        return _sig(value, digits)[0]
    se = float(se)
    big = max(abs(value), se)
    if big >= MAX_PLAIN or big < MIN_PLAIN:
        return _power(value, se, digits, pm)
    rounded, place = _error_digits(se)
    text = _plain(value, place)
    return f"{text} ± {_plain(rounded, place)}" if pm else text


def unit(text: str | None) -> str:
    """A unit string (pint syntax, as declared by laws, quantities and data files) in report
    typography.

    ``*`` becomes a middle dot, powers become superscripts, degree symbols and micro are spelled
    out (``degC`` → ``°C``, ``deg/s`` → ``°/s``, ``um`` → ``µm``), pint's long names become
    symbols (``newton * meter`` → ``N·m``), and a dimensionless ``"1"`` becomes ``"–"``. The order
    of the factors is kept (``N*m`` stays N·m, not pint's m·N). Text that is not a unit (``nats
    per point``) comes back unchanged.
    """
    if text is None:
        return ""
    text = str(text).strip()
    if text in ("1", "", "dimensionless"):
        return "–" if text else ""
    if not _is_unit(text):
        return text
    out = re.sub(r"[A-Za-zµμ_]+", lambda m: _symbol(m.group(0)), text)
    out = re.sub(r"\s*(\*\*|\^)\s*(-?\d+)", lambda m: m.group(2).translate(_SUPERSCRIPT), out)
    out = re.sub(r"\s*\*\s*", "·", out)
    return re.sub(r"\s*/\s*", "/", out)


_SYMBOLS = {"degC": "°C", "degree_Celsius": "°C", "celsius": "°C", "degF": "°F", "degree_Fahrenheit": "°F",
            "deg": "°", "degree": "°", "degrees": "°", "um": "µm", "micrometer": "µm", "micron": "µm",
            "Nm": "N·m", "newton_metre": "N·m", "ohm": "Ω", "percent": "%", "delta_degC": "K"}


def _symbol(token: str) -> str:
    if token in _SYMBOLS:
        return _SYMBOLS[token]
    if len(token) <= 3:  # already a symbol (N, m, rad, kN, rpm, lbf, ozf ...)
        return token
    from bayesfric.quantities import ureg

    try:
        return f"{ureg.Unit(token):~}".replace("μ", "µ")
    except Exception:  # noqa: BLE001 -- pint raises several kinds; an unknown word is left as it is
        return token


def _is_unit(text: str) -> bool:
    from bayesfric.quantities import ureg

    try:
        ureg.Unit(text)
    except Exception:  # noqa: BLE001 -- not a unit string: shown as written
        return False
    return True
