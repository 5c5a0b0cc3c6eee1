"""Thermal family (seed 002): hand-computed references, invariants, Vogel prior derivation, recovery.

Recovery criterion (slow tests): simulate on the seed's design (14 speeds 100–1400 rpm × 6
lubricant temperatures 19–38 °C), fit with NUTS (draws=400, tune=400, chains=2, one seed) and
require every true scalar parameter inside its 90 % equal-tailed interval. The 15-coefficient
polynomial surface is collinear by construction, so there the criterion is: ≥ 12 of 15
coefficients inside their 90 % intervals (binomial 15 × 0.9: P(< 12) ≈ 6 % for a calibrated
posterior) and the true surface inside the 90 % interval of the fitted mean at ≥ 80 % of the
design points.
"""

import math

import jax
import numpy as np
import pytest
from scipy.optimize import brentq

from bayesfric.inference import fit
from bayesfric.laws import get_law
from bayesfric.laws.thermal import OMEGA_REF, OMEGA_SCALE, RPM, vogel_viscosity
from bayesfric.priors import DataScale

KELVIN = 273.15


def ev(name, v, temperature=None, **p):
    law = get_law(name)
    inputs = {"velocity": np.asarray(v, float)}
    if "temperature" in law.inputs:
        inputs["temperature"] = np.asarray(temperature, float)
    return np.asarray(law.mean(inputs, p))


# --- hand-computed references -------------------------------------------------------------------
def test_quadratic_viscous_reference():
    # 38 °C: s = (38 − 28.5)/10 = 0.95; f1 = 0.02 − 0.003·0.95 + 0.001·0.9025 = 0.0180525
    got = ev("thermal_viscous_quadratic", 10.0, 38.0 + KELVIN, f1_ref=0.02, f1_lin=-0.003, f1_quad=0.001)
    assert float(got) == pytest.approx(0.180525, rel=1e-12)
    # at T_ref only f1_ref acts: 0.02 · (−5) = −0.1
    got = ev("thermal_viscous_quadratic", -5.0, 28.5 + KELVIN, f1_ref=0.02, f1_lin=-0.003, f1_quad=0.001)
    assert float(got) == pytest.approx(-0.1, rel=1e-12)


def test_poly_surface_reference():
    c = np.zeros((3, 5))
    c[0, 0], c[1, 0], c[2, 1], c[1, 4] = 0.1, 0.5, 0.2, 0.3
    # u = 0.5, s = (38.5 − 28.5)/10 = 1: 0.1 + 0.5·0.5 + 0.2·0.25·1 + 0.3·0.5·1 = 0.55
    omega = 0.5 * OMEGA_SCALE.value
    got = ev("thermal_poly_surface", [omega, -omega], [38.5 + KELVIN] * 2, c=c)
    np.testing.assert_allclose(got, [0.55, -0.55], rtol=1e-12)
    assert OMEGA_SCALE.value == pytest.approx(1400 * 2 * math.pi / 60)  # 146.608 rad/s


def test_vogel_power_reference():
    p = dict(c0=0.5, c=2.0, a=1.0, b=0.5, B=1000.0, C=180.0)
    # at ω_ref and T_ref both ratios are 1: 0.5 + 2 = 2.5
    assert float(ev("thermal_vogel_power", OMEGA_REF.value, 28.5 + KELVIN, **p)) == pytest.approx(2.5)
    # 2 ω_ref, 38.5 °C = 311.65 K: B/(T−C) − B/(T_ref−C) = 1000/131.65 − 1000/121.65
    #   = 7.595898 − 8.220304 = −0.624406; (η/η_ref)^0.5 = e^(−0.312203) = 0.731833
    #   torque = 0.5 + 2 · 2 · 0.731833 = 3.427332
    got = ev("thermal_vogel_power", [2 * OMEGA_REF.value, -2 * OMEGA_REF.value], [311.65, 311.65], **p)
    np.testing.assert_allclose(got, [3.427332, -3.427332], rtol=1e-6)
    assert OMEGA_REF.value == pytest.approx(1000 * RPM)


def test_mass2_viscous_reference():
    assert float(ev("thermal_mass2_viscous", -50.0, f2=0.003)) == pytest.approx(-0.15)


# --- invariants ---------------------------------------------------------------------------------
def _prior_draws(law, n=2000, seed=0):
    scale = DataScale(response=3.0, inputs={"velocity": 150.0, "temperature": 311.0})
    keys = jax.random.split(jax.random.PRNGKey(seed), len(law.params))
    return {name: np.asarray(p.prior.to_numpyro(scale).sample(k, (n,) + p.shape))
            for k, (name, p) in zip(keys, law.params.items(), strict=True)}


def test_vogel_viscosity_falls_with_temperature_for_every_prior_draw():
    draws = _prior_draws(get_law("thermal_vogel_power"))
    temperature = np.linspace(-20.0, 120.0, 141) + KELVIN  # gearbox operating range and beyond
    eta = np.asarray(vogel_viscosity(temperature[None, :], 1.0, draws["B"][:, None], draws["C"][:, None]))
    assert np.all(np.isfinite(eta)) and np.all(eta > 0)
    assert np.all(np.diff(eta, axis=1) < 0)


def test_vogel_law_falls_with_temperature_and_rises_with_speed():
    law = get_law("thermal_vogel_power")
    draws = _prior_draws(law, n=200)
    speed, temp = np.meshgrid(np.linspace(100, 1400, 14) * RPM, np.linspace(19, 38, 20) + KELVIN,
                              indexing="ij")
    out = np.stack([np.asarray(law.mean({"velocity": speed, "temperature": temp},
                                        {k: v[i] for k, v in draws.items()})) for i in range(200)])
    assert np.all(np.diff(out, axis=2) < 0)  # hotter oil, less torque
    assert np.all(np.diff(out, axis=1) > 0)  # faster, more torque


def test_quadratic_law_is_linear_in_speed():
    p = dict(f1_ref=0.02, f1_lin=-0.003, f1_quad=0.001)
    t = np.array([295.0, 305.0, 310.0])
    np.testing.assert_allclose(ev("thermal_viscous_quadratic", 2 * np.array([3.0, 40.0, 90.0]), t, **p),
                               2 * ev("thermal_viscous_quadratic", [3.0, 40.0, 90.0], t, **p), rtol=1e-12)


STACHOWIAK_TABLE_2_3 = {  # dynamic viscosity in mPa·s at 30, 60, 100 °C
    "heavy machine oil a": (153, 34, 9.1), "heavy machine oil b": (250, 50.5, 12.6),
    "cylinder oil": (810, 135, 26.8), "heavy machine oil c": (122, 26.3, 7.3),
    "heavy machine oil d": (171, 31, 7.5), "heavy machine oil e": (165, 30.0, 6.8),
    "heavy machine oil f": (310, 44.2, 9.4),
}
ISO_VG_DATASHEET = [  # (ν40, ν100) mm²/s: VG 100/220/680 at VI ≈ 95/95/90 and ≈ 150–160 (approx.)
    (100, 11.2), (220, 19.0), (680, 39.2), (100, 14.5), (220, 25.5), (680, 65.0),
]


def _vogel_through(temps_c, values):
    """(B, C) of ln η = ln A + B/(T − C) through three points."""
    t = np.asarray(temps_c, float) + KELVIN
    y = np.log(values)
    ratio = (y[0] - y[1]) / (y[1] - y[2])

    def mismatch(c):
        return (1 / (t[0] - c) - 1 / (t[1] - c)) / (1 / (t[1] - c) - 1 / (t[2] - c)) - ratio

    c = brentq(mismatch, -3000.0, t[0] - 1.0)
    return (y[0] - y[1]) / (1 / (t[0] - c) - 1 / (t[1] - c)), c


def _walther_then_vogel(nu40, nu100):
    """ASTM D341 line through (40 °C, ν40), (100 °C, ν100), then Vogel through 0/40/100 °C."""
    t = np.array([40.0, 100.0]) + KELVIN
    y = np.log10(np.log10(np.array([nu40, nu100]) + 0.7))
    m = (y[0] - y[1]) / (np.log10(t[1]) - np.log10(t[0]))
    a = y[0] + m * np.log10(t[0])
    temps = np.array([0.0, 40.0, 100.0])
    nu = 10 ** (10 ** (a - m * np.log10(temps + KELVIN))) - 0.7
    return _vogel_through(temps, nu)


def test_vogel_prior_derivation():
    """Reruns the derivation in thermal_vogel_power's docstring and checks the priors cover it."""
    fits = [_vogel_through((30, 60, 100), v) for v in STACHOWIAK_TABLE_2_3.values()]
    fits += [_walther_then_vogel(*pair) for pair in ISO_VG_DATASHEET]
    b_values, c_values = np.array(fits).T
    assert 880 < b_values.min() and b_values.max() < 1670  # B ∈ [885, 1661] K
    assert 134 < c_values.min() and c_values.max() < 201  # C ∈ [135, 200] K
    law = get_law("thermal_vogel_power")
    draws = _prior_draws(law, n=20000, seed=1)
    b_lo, b_hi = np.quantile(draws["B"], [0.02, 0.98])
    c_lo, c_hi = np.quantile(draws["C"], [0.02, 0.98])
    assert b_lo < b_values.min() and b_values.max() < b_hi
    assert c_lo < c_values.min() and c_values.max() < c_hi


# --- posterior recovery on the seed's design ------------------------------------------------------
SPEED, TEMPERATURE = (g.ravel() for g in np.meshgrid(np.arange(100, 1500, 100) * RPM,
                                                      np.linspace(19.0, 38.0, 6) + KELVIN,
                                                      indexing="ij"))
TRUTHS = {
    # f1 ≈ 0.02 N·m·s/rad (≈ 3 N·m at 1400 rpm), −12 % per 10 K, mild curvature
    "thermal_viscous_quadratic": dict(f1_ref=0.02, f1_lin=-0.0024, f1_quad=0.0006),
    "thermal_vogel_power": dict(c0=0.4, c=2.0, a=1.0, b=0.3, B=1200.0, C=170.0),
    "thermal_mass2_viscous": dict(f2=0.006),
}


def _interval(dt, name):
    draws = np.asarray(dt["posterior"][name].values)
    draws = draws.reshape((-1,) + draws.shape[2:])
    return np.quantile(draws, 0.05, axis=0), np.quantile(draws, 0.95, axis=0), draws


def _simulate(simulator, law, truth, seed=5):
    inputs = {k: {"velocity": SPEED, "temperature": TEMPERATURE}[k] for k in law.inputs}
    clean = np.asarray(law.mean(inputs, truth))
    return simulator(law, inputs, truth, sigma=0.01 * float(np.abs(clean).max()), seed=seed), inputs


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TRUTHS))
def test_posterior_recovery(simulator, name):
    law = get_law(name)
    ds, _ = _simulate(simulator, law, TRUTHS[name])
    dt = fit(law, ds, draws=400, tune=400, chains=2, seed=2)
    for pname, value in TRUTHS[name].items():
        low, high, _ = _interval(dt, pname)
        assert low <= value <= high, f"{name}.{pname}: {value} outside 90 % [{low:.4g}, {high:.4g}]"


@pytest.mark.slow
def test_poly_surface_recovery(simulator):
    law = get_law("thermal_poly_surface")
    c = np.array([[0.30, -0.05, 0.02, 0.01, -0.01],
                  [2.50, -0.30, 0.08, -0.02, 0.01],
                  [0.40, -0.04, 0.02, 0.01, 0.00]])
    ds, inputs = _simulate(simulator, law, {"c": c})
    dt = fit(law, ds, draws=400, tune=400, chains=2, seed=2)
    low, high, draws = _interval(dt, "c")
    inside = (low <= c) & (c <= high)
    assert inside.sum() >= 12, f"only {inside.sum()}/15 coefficients inside their 90 % intervals"
    surfaces = np.asarray(jax.vmap(lambda ci: law.mean(inputs, {"c": ci}))(draws[::4]))
    truth = np.asarray(law.mean(inputs, {"c": c}))
    lo, hi = np.quantile(surfaces, [0.05, 0.95], axis=0)
    assert np.mean((lo <= truth) & (truth <= hi)) >= 0.8
