"""Rigid-ring Hertz ball loads of the four-point contact pitch bearing (laws.ball_loads)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bayesfric.laws.ball_loads import (
    PITCH_BEARING,
    BearingGeometry,
    ball_loads,
    contact_loads,
    sum_ball_loads,
)

GEOMETRY = PITCH_BEARING
RADIUS = GEOMETRY.pitch_diameter / 2
SIN, COS = math.sin(GEOMETRY.contact_angle), math.cos(GEOMETRY.contact_angle)
PSI = 2 * np.pi * np.arange(GEOMETRY.n_balls) / GEOMETRY.n_balls

# combined cases, including the awkward ones (one contact pair loaded plus a small moment)
CASES = [
    (6e6, 0.0, 0.0),
    (0.0, 1e6, 0.0),
    (0.0, 0.0, 1e6),
    (3e6, 5e5, 2e5),
    (-3e6, -5e5, -2e5),
    (1e3, 1e6, 0.0),
    (6e6, 1e4, 3e5),
    (2e5, -8e5, 4e5),
]


def resultants(contacts):
    """Axial force, moment and radial force the contact loads exert (numpy, not the solver)."""
    qa, qb = contacts[..., 0], contacts[..., 1]
    axial = ((qa - qb) * SIN).sum(axis=(-2, -1))
    moment = ((qa - qb) * SIN * RADIUS * np.cos(PSI)).sum(axis=(-2, -1))
    radial = ((qa + qb) * COS * np.cos(PSI)).sum(axis=(-2, -1))
    return axial, moment, radial


def test_geometry_states_its_sources():
    assert GEOMETRY.rows == 2 and GEOMETRY.n_balls == 120
    assert "assumed" in GEOMETRY.source and "seed 000" in GEOMETRY.source
    assert isinstance(GEOMETRY, BearingGeometry)


@pytest.mark.parametrize("moment,axial,radial", CASES)
def test_ball_loads_balance_the_applied_loads(moment, axial, radial):
    contacts = np.asarray(contact_loads(moment, axial, radial, GEOMETRY))
    assert contacts.shape == (GEOMETRY.rows, GEOMETRY.n_balls, 2)
    assert (contacts >= 0).all()
    got = resultants(contacts)
    size = math.sqrt(axial**2 + (moment / RADIUS) ** 2 + radial**2)
    for value, applied, lever in zip(got, (axial, moment, radial), (1.0, RADIUS, 1.0), strict=True):
        assert abs(value - applied) / lever <= 1e-6 * size


def test_balance_over_a_vectorised_random_load_array():
    rng = np.random.default_rng(3)
    moment, axial, radial = rng.normal(size=(3, 4, 25)) * np.array([6e6, 1e6, 5e5])[:, None, None]
    contacts = np.asarray(contact_loads(moment, axial, radial, GEOMETRY))
    assert contacts.shape == (4, 25, GEOMETRY.rows, GEOMETRY.n_balls, 2)
    size = np.sqrt(axial**2 + (moment / RADIUS) ** 2 + radial**2)
    a, m, r = resultants(contacts)
    assert np.max(np.abs(a - axial) / size) < 1e-6
    assert np.max(np.abs(m - moment) / RADIUS / size) < 1e-6
    assert np.max(np.abs(r - radial) / size) < 1e-6


def test_zero_load_gives_zero_ball_loads():
    assert np.all(np.asarray(ball_loads(0.0, 0.0, 0.0, GEOMETRY)) == 0.0)
    assert float(sum_ball_loads(0.0, 0.0, 0.0, GEOMETRY)) == 0.0


def test_moment_sign_flip_mirrors_the_load_zone():
    plus = np.asarray(ball_loads(4e6, 0.0, 0.0, GEOMETRY))
    minus = np.asarray(ball_loads(-4e6, 0.0, 0.0, GEOMETRY))
    half = GEOMETRY.n_balls // 2  # ball j at ψ maps onto ball j + Z/2 at ψ + π
    np.testing.assert_allclose(minus, np.roll(plus, half, axis=-1), rtol=1e-9, atol=1e-6)
    flipped = float(sum_ball_loads(-4e6, 0.0, 0.0))
    assert float(sum_ball_loads(4e6, 0.0, 0.0)) == pytest.approx(flipped, rel=1e-10)


def test_pure_axial_load_is_shared_equally():
    loads = np.asarray(ball_loads(0.0, 1.2e6, 0.0, GEOMETRY))
    # hand: Q = F_a / (rows · Z · sin α) = 1.2e6 / (2 · 120 · 0.70711) = 7071.07 N
    np.testing.assert_allclose(loads, 7071.0678, rtol=1e-6)


def test_pure_moment_sum_matches_the_cosine_distribution_by_hand():
    # Hand computation (module docstring): P1 = M Σ|cos ψ|^1.5 / (sin α · R · Σ|cos ψ|^2.5).
    # Continuous limit: mean|cos|^1.5 = Γ(1.25)/(√π Γ(1.75))
    #   = 0.906402/(1.772454·0.919063) = 0.556433,
    # mean|cos|^2.5 = Γ(1.75)/(√π Γ(2.25)) = 0.919063/(1.772454·1.133003) = 0.457654,
    # ratio 1.215838; for M = 6 MN·m: 1.215838 · 6e6 / (0.707107 · 1.05) = 9.8255e6 N.
    # The exact ball sum for Z = 120 (math below, not the solver) differs from the limit by < 1e-4.
    moment = 6e6
    cos = np.abs(np.cos(PSI))
    exact = moment * np.sum(cos**1.5) / (SIN * RADIUS * np.sum(cos**2.5))
    assert exact == pytest.approx(9.8255e6, rel=1e-4)
    assert float(sum_ball_loads(moment, 0.0, 0.0, GEOMETRY)) == pytest.approx(exact, rel=1e-7)


def test_sum_scales_linearly_with_pure_moment():
    moments = np.array([1e6, 2e6, 3e6, 6e6])
    sums = np.asarray(sum_ball_loads(moments, 0.0, 0.0, GEOMETRY))
    np.testing.assert_allclose(sums / moments, sums[0] / moments[0], rtol=1e-8)


def test_traced_and_concrete_paths_agree_and_jit():
    moments = jnp.linspace(0.0, 6e6, 5)
    concrete = np.asarray(sum_ball_loads(moments, 2e5, 1e5, GEOMETRY))
    traced = np.asarray(jax.jit(lambda m: sum_ball_loads(m, 2e5, 1e5, GEOMETRY))(moments))
    np.testing.assert_allclose(traced, concrete, rtol=1e-9)


def test_gradients_are_finite_and_match_finite_differences():
    def total(m):
        return jnp.sum(ball_loads(m, 2e5, 1e5, GEOMETRY))

    grad = jax.grad(total)
    for m in (0.0, 3e6):
        assert np.isfinite(float(grad(m)))
    # The Newton solve stops with ~1.5e-9 relative jitter in the loads (0.0075 N on 4.9 MN), which
    # a two-point difference of step 100 N·m turns into ~1e-4 of the derivative; a quadratic
    # least-squares fit over 41 points in ±2 kN·m averages it out (slope within 6e-7).
    offsets = np.linspace(-2e3, 2e3, 41)
    values = np.array([float(total(3e6 + dm)) for dm in offsets])
    slope = np.polyfit(offsets, values, 2)[1]
    assert float(grad(3e6)) == pytest.approx(slope, rel=1e-5)
    assert np.isfinite(float(jax.grad(lambda m: jnp.sum(ball_loads(m, 0.0, 0.0, GEOMETRY)))(0.0)))
