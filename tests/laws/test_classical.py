"""Hand-computed reference values and invariants of the seed-004 laws."""

import math

import numpy as np
import pytest

from bayesfric.laws import get_law


def ev(name, v, **p):
    return float(np.asarray(get_law(name).mean({"velocity": np.asarray(v, float)}, p)))


def test_coulomb():
    assert ev("coulomb", 0.3, T_C=2.5) == 2.5
    assert ev("coulomb", -0.3, T_C=2.5) == -2.5


def test_coulomb_viscous():
    # 2 + 0.5 * 3 = 3.5
    assert ev("coulomb_viscous", 3.0, T_C=2.0, c_v=0.5) == pytest.approx(3.5)


def test_stribeck_reference():
    # T_C=2, T_s=3, v_s=0.05, δ=1 at 0.1 rad/s: 2 + 1·e^(−2) = 2.1353352832366128
    assert ev("stribeck", 0.1, T_C=2.0, dT_s=1.0, v_s=0.05, delta=1.0) == pytest.approx(2.1353352832366128)
    # δ = 2 at 0.1: 2 + e^(−4) = 2.018315638888734
    assert ev("stribeck", 0.1, T_C=2.0, dT_s=1.0, v_s=0.05, delta=2.0) == pytest.approx(2.018315638888734)


def test_armstrong_helouvry_reference():
    # seed 004's δ=0.33, q̇_s=0.024: at 0.5 rad/s, 10 + 4·exp(−(0.5/0.024)^0.33) + 2·0.5
    expected = 10 + 4 * math.exp(-((0.5 / 0.024) ** 0.33)) + 1.0
    assert ev("armstrong_helouvry", 0.5, T_C=10.0, dT_s=4.0, v_s=0.024, delta=0.33, c_v=2.0) == pytest.approx(expected)
    # (0.5/0.024)^0.33 = e^(0.33·3.0366) = 2.7240; 4·e^(−2.7240) = 0.2625; total 11.2625
    assert expected == pytest.approx(11.2625, abs=1e-4)


def test_joint_law_reference():
    # T_a0=5, q̇_s=0.05, δa=0.5, c_v=3 (N·m at 1 rad/s), δv=0.6 at 4 rad/s:
    # 5·exp(−sqrt(80)) + 3·4^0.4 = 5·1.3038e-4 + 3·1.7411011 = 5.2239552
    expected = 5 * math.exp(-math.sqrt(80.0)) + 3 * 4**0.4
    got = ev("joint_tribological", 4.0, T_a0=5.0, v_s=0.05, delta_a=0.5, c_v=3.0, delta_v=0.6)
    assert got == pytest.approx(expected) and got == pytest.approx(5.22395, abs=1e-5)


def test_roller_bearing_reference_and_limits():
    p = dict(T_a0=4.0, v_s=0.05, delta=1.0, T_l=1.5, v_l=0.5)
    # at 0.5 rad/s: 4·e^(−10) + 1.5·(1 − e^(−1)) = 1.5·0.6321205588 + 1.816e-4
    assert ev("prestressed_roller_bearing", 0.5, **p) == pytest.approx(4 * math.exp(-10) + 1.5 * (1 - math.exp(-1)))
    assert ev("prestressed_roller_bearing", 1e-9, **p) == pytest.approx(4.0, rel=1e-6)  # static = T_a0
    assert ev("prestressed_roller_bearing", 100.0, **p) == pytest.approx(1.5, rel=1e-9)  # T_l,∞


def test_helical_gear_reference():
    # one δ for both terms: T_a0=2, q̇_s=0.1, δ=0.5, c_v=1.2 at 0.9 rad/s
    expected = 2 * math.exp(-math.sqrt(9.0)) + 1.2 * 0.9**0.5
    assert ev("helical_gear", 0.9, T_a0=2.0, v_s=0.1, delta=0.5, c_v=1.2) == pytest.approx(expected)


def test_static_at_least_coulomb_by_construction():
    law = get_law("stribeck")
    derived = law.derived_values({"T_C": 2.0, "dT_s": 0.0, "v_s": 0.1, "delta": 1.0})
    assert derived["T_s"] == 2.0  # dT_s ≥ 0 is the prior's support, so T_s ≥ T_C always


def test_stribeck_dip_monotone_decay():
    v = np.geomspace(1e-4, 1.0, 50)
    t = np.asarray(get_law("stribeck").mean({"velocity": v}, dict(T_C=1.0, dT_s=0.5, v_s=0.05, delta=0.8)))
    assert np.all(np.diff(t) <= 0) and t[0] <= 1.5 and t[-1] >= 1.0
