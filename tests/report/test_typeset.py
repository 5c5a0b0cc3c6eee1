"""Numbers rounded to their standard error and units in report typography (hand-computed cases)."""

import math

import pytest

from bayesfric.report.typeset import fmt, unit


@pytest.mark.parametrize(("value", "se", "text"), [
    (12.345, 0.234, "12.35 ± 0.23"),  # se leads with 2: two significant digits, value to 0.01
    (12.345, 0.56, "12.3 ± 0.6"),  # leads with 5: one digit
    (12.345, 3.1, "12 ± 3"),
    (-1234.5, 47.0, "-1230 ± 50"),  # error at the tens: value to the tens
    (-1234.4, 25.0, "-1234 ± 25"),
    (0.5, 0.096, "0.50 ± 0.10"),  # 0.096 rounds up to 0.10: a leading 1, two digits
    (7.0, 0.96, "7.0 ± 1.0"),
    (0.12345, 0.0149, "0.123 ± 0.015"),
    (-0.004, 0.3, "0.0 ± 0.3"),  # no "-0.0"
    (0.0, 0.02, "0.000 ± 0.020"),
    (1.5e-10, 2e-11, "(1.50 ± 0.20) × 10⁻¹⁰"),  # small: a power of ten, the error in it
    (2.5e7, 1.2e6, "(2.50 ± 0.12) × 10⁷"),
])
def test_value_rounded_to_its_error(value, se, text):
    assert fmt(value, se) == text


@pytest.mark.parametrize(("value", "text"), [
    (0.50012, "0.5"),  # the sizing distance that read "0.5001 tested ranges"
    (5.505e-10, "5.5 × 10⁻¹⁰"),  # not 5.505e-10 (the float 5.505 is 5.50499…)
    (1.0, "1"), (100.0, "100"), (123456.0, "123000"), (0.001234, "0.00123"), (-0.0, "0"), (0.0, "0"),
    (math.nan, "–"), (None, "–"), (math.inf, "+∞"), (-math.inf, "−∞"),
])
def test_value_without_error_keeps_three_significant_digits(value, text):
    assert fmt(value) == text


def test_no_error_or_zero_error_is_not_written():
    assert fmt(3.0, 0.0) == "3" and fmt(3.14159, math.nan) == "3.14" and "±" not in fmt(2.5, None)
    assert fmt(0.541, digits=2) == "0.54"


def test_value_only_at_the_errors_place():
    assert fmt(12.345, 0.234, pm=False) == "12.35"  # a mean next to its sd, an interval's ends
    assert fmt(5.0123, 0.0456, pm=False) == "5.01"
    assert fmt(1.5e-10, 2e-11, pm=False) == "1.50 × 10⁻¹⁰"


@pytest.mark.parametrize(("text", "shown"), [
    ("N*m", "N·m"), ("degC", "°C"), ("degree_Celsius", "°C"), ("rad/s", "rad/s"), ("N*m*s/rad", "N·m·s/rad"),
    ("mm**2", "mm²"), ("N*m*s**2/rad**2", "N·m·s²/rad²"), ("in*ozf", "in·ozf"), ("um", "µm"), ("um/s", "µm/s"),
    ("deg", "°"), ("deg/s", "°/s"), ("MN*m", "MN·m"), ("kN * m", "kN·m"), ("newton * meter", "N·m"),
    ("Nm", "N·m"), ("1", "–"), ("K", "K"), ("rpm", "rpm"), ("1/K", "1/K"),
    ("nats per held-out point", "nats per held-out point"),  # not a unit: as written
    ("", ""), (None, ""),
])
def test_units_in_report_typography(text, shown):
    assert unit(text) == shown
