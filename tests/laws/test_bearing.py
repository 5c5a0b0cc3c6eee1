"""Seed-000 pitch-bearing laws: hand-computed references, invariants and posterior recovery."""

import math

import numpy as np
import pytest

from bayesfric.inference import fit
from bayesfric.laws import get_law

# Pure-moment ball loads by hand (no solver): Q_i = Q_max |cos ψ_i|^1.5 on one contact pair, with
# M = rows·Q_max·sin α·R·Σ|cos ψ|^2.5 (bayesfric.laws.ball_loads docstring). Geometry defaults:
# D_M = 2.1 m (R = 1.05), Z = 120 per row, 2 rows, α = 45°, D_RE = 0.05 m.
D_M, R, Z, ROWS, SIN, D_RE = 2.1, 1.05, 120, 2, math.sin(math.pi / 4), 0.05
COS = np.abs(np.cos(2 * np.pi * np.arange(Z) / Z))


def contact_power_sum(moment, power):
    """Σ Q^power over all contacts for a pure moment, from the closed form above."""
    q_max = moment / (ROWS * SIN * R * np.sum(COS**2.5))
    return ROWS * q_max**power * np.sum(COS ** (1.5 * power))


def mean(name, velocity, moment, **params):
    law = get_law(name)
    inputs = {"velocity": np.atleast_1d(np.asarray(velocity, float)),
              "bending_moment": np.atleast_1d(np.asarray(moment, float))}
    return np.asarray(law.mean({k: inputs[k] for k in law.inputs}, params))


PALMGREN = dict(f0=2.0, f1=7e-4)
SKF = dict(R1=4.78e-7, S1=1.2e-2, mu_bl=0.15, K_S1=3e6 / 2000.0**2.25)  # seal torque 3000 N·m
WANG = dict(kappa=0.01, T_roll=500.0, tau_lim=8e7, omega_lim=0.05)


def test_hand_sum_matches_the_continuous_limit():
    # P1 at 6 MN·m: 1.215838·6e6/(0.707107·1.05) = 9.8255e6 N (Γ-function limit, test_ball_loads)
    assert contact_power_sum(6e6, 1.0) == pytest.approx(9.8255e6, rel=1e-4)


def test_palmgren_reference():
    # ω = 0.08 rad/s: n = 0.08·30/π = 0.7639 r/min, νn = 150·0.7639 = 114.6 < 2000 (low branch).
    # T0 = 16·f0·D_M³ = 16·2·9.261 = 296.352 N·m; P1(6 MN·m) = 9.82496e6 N;
    # T1 = 7e-4·9.82496e6·2.1 = 14442.7 N·m; total 14739.0 N·m.
    t0 = 16 * 2.0 * D_M**3
    expected = t0 + 7e-4 * contact_power_sum(6e6, 1.0) * D_M
    assert t0 == pytest.approx(296.352)
    assert expected == pytest.approx(14739.0, abs=0.5)
    got = mean("palmgren", [0.08, 0.08, -0.08], [0.0, 6e6, 6e6], **PALMGREN)
    np.testing.assert_allclose(got, [t0, expected, -expected], rtol=1e-7)


def test_palmgren_high_speed_branch_reference():
    # ω = 2 rad/s: n = 19.0986 r/min, νn = 2864.79 >= 2000; (νn)^(2/3) = e^(2/3·7.96024) = 201.71;
    # T0 = 0.1·2·201.71·9.261 = 373.61 N·m (paper: 1e-7 f0 (νn)^(2/3) d_m³ N·mm, d_m in mm).
    nu_n = 150.0 * 2.0 * 30 / math.pi
    t0 = 0.1 * 2.0 * nu_n ** (2 / 3) * D_M**3
    assert t0 == pytest.approx(373.61, abs=0.01)
    assert float(mean("palmgren", 2.0, 0.0, **PALMGREN)[0]) == pytest.approx(t0, rel=1e-10)


def test_palmgren_low_speed_branch_is_speed_independent():
    speeds = np.array([0.01, 0.05, 0.1, 0.5, 1.3])  # all with νn < 2000 at ν = 150 mm²/s
    got = mean("palmgren", speeds, np.full(5, 3e6), **PALMGREN)
    np.testing.assert_allclose(got, got[0], rtol=1e-12)


def test_rothe_erde_reference_and_zero_at_zero_load():
    # μ/2·4.4·M = 0.002·4.4·6e6 = 52800 N·m
    assert float(mean("rothe_erde", None, 6e6, mu=0.004)[0]) == pytest.approx(52800.0)
    assert float(mean("rothe_erde", None, 0.0, mu=0.004)[0]) == 0.0
    # with F_a = 1e5 N, F_r = 5e4 N: + 0.002·(1e5·2.1 + 3.81·5e4·2.1) = 0.002·610050 = 1220.1
    law = get_law("rothe_erde")
    got = law.mean({"bending_moment": np.array([6e6])}, {"mu": 0.004}, {"F_a": 1e5, "F_r": 5e4})
    assert float(got[0]) == pytest.approx(54020.1)
    # the offset variant adds T0
    offset = mean("rothe_erde_offset", None, 6e6, mu=0.004, T0=3000.0)
    assert float(offset[0]) == pytest.approx(55800.0)


def test_skf_reference():
    # ω = 0.08 rad/s -> n = 0.763944 r/min; d_m = 2100, d = 1900, D = 2300 mm; ν = 150 mm²/s.
    n, nu, dm = 0.08 * 30 / math.pi, 150.0, 2100.0
    axial = SIN * contact_power_sum(6e6, 1.0)  # 0.707107·9.82496e6 = 6.94730e6 N
    f_g = 1.40e-12 * dm**4 * n**2  # 15.9 N
    phi_ish = 1 / (1 + 1.84e-9 * (n * dm) ** 1.28 * nu**0.64)
    phi_rs = math.exp(-6e-8 * nu * n * 4200.0 * math.sqrt(3.1 / 800.0))
    m_rr = phi_ish * phi_rs * 4.78e-7 * dm**1.97 * (f_g + 2.42 * axial) ** 0.54 * (nu * n) ** 0.6
    phi_bl = math.exp(-2.6e-8 * (n * nu) ** 1.4 * dm)
    g_sl = 1.2e-2 * dm**0.26 * (f_g ** (4 / 3) + 0.9 * axial ** (4 / 3))
    m_sl = (phi_bl * 0.15 + (1 - phi_bl) * 0.05) * g_sl
    expected = 1e-3 * (m_rr + m_sl) + 3000.0
    # numbers: M_rr ≈ 2.69e5 N·mm, φ_bl ≈ 0.94, M_sl ≈ 1.52e7 N·mm -> ≈ 18495 N·m in total
    assert expected == pytest.approx(18495, rel=2e-3)
    got = mean("skf_2014", [0.08, 0.08], [0.0, 6e6], **SKF)
    assert float(got[1]) == pytest.approx(expected, rel=1e-7)
    # zero load: seal term plus the tiny centrifugal-load terms (0.128 N·m rolling, 5e-4 sliding)
    rolling0 = phi_ish * phi_rs * 4.78e-7 * dm**1.97 * f_g**0.54 * (nu * n) ** 0.6
    sliding0 = (phi_bl * 0.15 + (1 - phi_bl) * 0.05) * 1.2e-2 * dm**0.26 * f_g ** (4 / 3)
    zero = 3000.0 + 1e-3 * (rolling0 + sliding0)
    assert float(got[0]) == pytest.approx(zero, rel=1e-7)


def test_wang_reference():
    # ω = 0.1 rad/s, M = 6 MN·m; R_x = 0.025 m, E* = 1.14e11 Pa, 480 contacts, Q_ref = 1e4 N
    speed, r_x, e_star = 0.1, 0.025, 1.14e11
    width = (3 * r_x / (4 * e_star)) ** (1 / 3)  # b = width·Q^(1/3)
    m_def = 3 / 16 * 0.01 * (D_M / D_RE) * width * contact_power_sum(6e6, 4 / 3)
    m_roll = 500.0 * speed**0.66 * contact_power_sum(6e6, 0.47) / (480 * 1e4**0.47)
    spin = math.pi * r_x / (2 * e_star) * (D_M / D_RE) * SIN
    m_slide = 8e7 * math.tanh(speed / 0.05) * spin * contact_power_sum(6e6, 1.0)
    # numbers: m_def ≈ 1596 N·m, m_roll ≈ 98 N·m, m_slide ≈ 7752 N·m; total ≈ 9446 N·m
    got = mean("wang_reduced", [speed, speed, 1e-9], [6e6, 0.0, 6e6], **WANG)
    assert m_def + m_roll + m_slide == pytest.approx(9446, rel=1e-3)
    assert float(got[0]) == pytest.approx(m_def + m_roll + m_slide, rel=1e-7)
    assert float(got[1]) == 0.0  # no load-independent term
    assert float(got[2]) == pytest.approx(m_def, rel=1e-5)  # at rest only deformation remains


@pytest.mark.parametrize("name,params", [("palmgren", PALMGREN), ("skf_2014", SKF),
                                         ("wang_reduced", WANG), ("rothe_erde", dict(mu=0.004)),
                                         ("rothe_erde_offset", dict(mu=0.004, T0=1000.0))])
def test_non_negative_and_monotone_in_load(name, params):
    moments = np.linspace(0.0, 8e6, 9)
    for speed in (0.02, 0.1, 0.5):
        torque = mean(name, np.full(9, speed), moments, **params)
        assert np.all(torque >= 0)
        assert np.all(np.diff(torque) > 0)


def test_wang_speed_dependence_is_increasing():
    speeds = np.array([0.01, 0.05, 0.1, 0.3])
    torque = mean("wang_reduced", speeds, np.full(4, 5e6), **WANG)
    assert np.all(np.diff(torque) > 0)


# --- posterior recovery (NUTS) -----------------------------------------------------------------
MOMENTS = np.arange(7) * 1e6  # 0–6 MN·m in 1 MN·m steps, as seed 000
SPEEDS = np.array([0.052, 0.079, 0.105])  # 3, 4.5, 6 °/s
REPEATS = 20

RECOVERY = [
    ("palmgren", PALMGREN, SPEEDS),
    ("rothe_erde", dict(mu=0.0045), SPEEDS),
    ("rothe_erde_offset", dict(mu=0.0045, T0=4000.0), SPEEDS),
    ("skf_2014", SKF, SPEEDS),
    ("wang_reduced", WANG, np.array([0.02, 0.05, 0.105, 0.3])),  # wider speeds: see law notes
]


@pytest.mark.slow
@pytest.mark.parametrize("name,truth,speeds", RECOVERY, ids=[r[0] for r in RECOVERY])
def test_posterior_recovers_the_true_parameters(simulator, name, truth, speeds):
    law = get_law(name)
    moment, speed = (g.ravel() for g in np.meshgrid(MOMENTS, speeds, indexing="ij"))
    moment, speed = np.repeat(moment, REPEATS), np.repeat(speed, REPEATS)
    design = {"velocity": speed, "bending_moment": moment}
    clean = np.asarray(law.mean({k: design[k] for k in law.inputs}, truth))
    sigma = 0.03 * float(clean.max())
    ds = simulator(law, {k: design[k] for k in law.inputs}, truth, sigma=sigma, seed=11)
    dt = fit(law, ds, draws=400, tune=400, chains=2, seed=3)
    post = dt.posterior
    for pname, value in truth.items():
        draws = np.asarray(post[pname]).ravel()
        low, high = np.quantile(draws, [0.05, 0.95])
        assert low <= value <= high, f"{name}.{pname}: {value} outside 90 % [{low:.4g}, {high:.4g}]"
