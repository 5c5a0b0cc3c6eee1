"""Law family 'drum': friction of a conveyor drum motor (seed 003) and its coast-down dynamics.

Seed 003 models the bearings and O-ring seals of a drum motor and identifies their friction from
roll-out (coast-down) tests: a return pulley is spun up and left to decelerate under friction
alone. This module declares

* the O-ring law τ = k_o ω + τ_o0 (Eq. 6) as names only: it is Coulomb + viscous, so ``oring``
  and ``coastdown_oring_closed_form`` are thin aliases (τ_o0 = T_C, k_o = c_v), see
  :data:`ORING_ALIASES`;
* the rolling friction of a radially loaded ball bearing from per-ball normal forces (Eq. 1–5),
  which gives both the torque against radial load and its ripple with the ball-set angle;
* a smooth non-parametric torque–speed law, the Bayesian counterpart of the seed's look-up tables;
* coast-down laws J dω/dt = −T_f(ω) whose observations are speed trajectories ω(t), declared in
  :mod:`bayesfric.laws.coastdown` (imported here, its public names re-exported): closed forms for
  Coulomb + viscous and for Coulomb alone, and :func:`coastdown`, a factory that turns any
  registered velocity law into a coast-down law integrated with diffrax.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from bayesfric.laws.base import Constant, Param, law
from bayesfric.laws.coastdown import (  # the coast-down laws of this family (registered on import)
    DRUM_INERTIA,
    SEED,
    coastdown,
    coulomb_viscous_coastdown,
    integrate_coastdown,
)
from bayesfric.numerics import positive_power
from bayesfric.priors import Prior

#: Why these laws run on rotary (torque) data only (bayesfric.laws.variants).
_ROTARY = "the drum motor's rolling bearings and O-rings (seed 003): ball geometry, shaft speed"

__all__ = [
    "DRUM_INERTIA",
    "DRUM_BEARING",
    "SPLINE_KNOTS",
    "coastdown",
    "coulomb_viscous_coastdown",
    "integrate_coastdown",
    "seed_ball_normal_forces",
    "spline_knot_speeds",
    "pchip",
]

_GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"

# --- O-ring law (Eq. 6) ---------------------------------------------------------------------------
#: Seed 003's O-ring law τ = k_o ω + τ_o0 sign(ω) (Eq. 6) *is* Coulomb + viscous with τ_o0 = T_C
#: and k_o = c_v, so it is not declared again: its names are thin aliases (registered by
#: :mod:`bayesfric.laws` with :func:`bayesfric.laws.variants.alias`) of the one declaration.
ORING_NOTES = (f"{SEED}, Eq. 6 (O-ring friction τ = k_o ω + τ_o0): the seed's k_o is c_v and its τ_o0 is "
               "T_C. §4 reports ≈ 0.95 N·m (bearings + O-rings) and ≈ 0.1 N·m per 1000 rpm "
               "(9.5e-4 N·m·s/rad).")
ORING_ALIASES = {
    "oring": {"base": "coulomb_viscous"},
    "coastdown_oring_closed_form": {"base": "coastdown_coulomb_viscous_closed_form"},
}


# --- rolling friction of a radially loaded ball bearing (Eq. 1–5) ---------------------------------
#: Deep-groove ball bearing 6205 (ISO 15: d = 25 mm, D = 52 mm), 9 balls of 7.938 mm on a
#: 38.5 mm pitch circle; raceway radii r_in/out = 19.25 ∓ 3.97 mm. Assumed: the seed names no size.
DRUM_BEARING = {"n_balls": 9, "r_in": 0.01528, "r_out": 0.02222}
N_BALLS = Constant(float(DRUM_BEARING["n_balls"]), "1", "number of balls (6205, assumed)")
R_IN = Constant(DRUM_BEARING["r_in"], "m", "inner raceway radius (6205, assumed)")
R_OUT = Constant(DRUM_BEARING["r_out"], "m", "outer raceway radius (6205, assumed)")


def seed_ball_normal_forces(radial_force, angle, n_balls: int):
    """Per-ball normal forces of seed 003 Eq. 1–3 for a radial load.

    Ball i sits at φ_i = angle + 2πi/Z from the load direction. Balls with cos φ_i > 0 carry
    F_N^i = F̃ cos^(3/2) φ_i (Eq. 1), with F̃ = F_B / Σ sqrt(cos φ_i) (Eq. 3) so that the partial
    forces F_B^i = F̃ sqrt(cos φ_i) (Eq. 2) add up to F_B.

    This is the seed's own closure, kept as published. The textbook (Stribeck) equilibrium
    instead balances the radial projections, Σ F_N^i cos φ_i = F_B. Then Σ F_N^i differs by the
    factor Σ cos^(5/2)/Σ cos^(1/2) (≈ 0.60 for many balls), which a fitted k_R absorbs; the
    ripple shapes differ slightly.
    :mod:`bayesfric.laws.ball_loads` (combined loads, fixed ball positions) cannot be reused here
    because it has no ball-set angle and uses the textbook equilibrium.

    Parameters
    ----------
    radial_force : array_like
        Radial (belt) force F_B in N.
    angle : array_like
        Ball-set (cage) angle in rad, measured from the load direction to ball 0.
    n_balls : int
        Number of balls Z.

    Returns
    -------
    jax.Array
        Shape ``broadcast(radial_force, angle).shape + (n_balls,)``, normal forces in N.
    """
    radial_force, angle = jnp.broadcast_arrays(jnp.asarray(radial_force, float),
                                               jnp.asarray(angle, float))
    phi = angle[..., None] + 2.0 * jnp.pi * jnp.arange(n_balls) / n_balls
    cos = jnp.cos(phi)
    weight = positive_power(cos, 0.5)
    f_tilde = radial_force / jnp.sum(weight, axis=-1)
    return f_tilde[..., None] * positive_power(cos, 1.5)


@law(
    name="drum_ball_rolling",
    family="drum",
    rotary_only=_ROTARY,
    inputs=("radial_force", "angle"),
    response="torque",
    source=f"{SEED}, Eq. 1–4 (Hertz ball loads, rolling friction per ball), Eq. 5 (ball angle)",
    params={
        "k_R": Param(
            "1",
            Prior("LogNormal", loc=-6.5, scale=0.75),  # median 1.5e-3, 90 % in [4.4e-4, 5.1e-3]
            "rolling friction factor, equal on both rings (k_R,in = k_R,out)",
            "SKF rolling bearings catalogue, constant friction coefficient μ ≈ 0.0015 of "
            "deep-groove ball bearings (M = μ P d/2); seed 003 Eq. 4",
        ),
        "tau_0": Param(
            "N*m",
            Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
            "load-independent bearing torque (grease, seals; Modelica BearingFriction part)",
            f"{SEED} §3.1 and Fig. 7 (0.2–0.3 N·m without O-rings); {_GENERIC}",
        ),
    },
    constants={"n_balls": N_BALLS, "r_in": R_IN, "r_out": R_OUT},
    notes=(
        "Returns the magnitude of the friction torque (Eq. 4). Only r_in k_in + r_out k_out enters "
        "for undamaged rings, so one factor k_R serves both rings; separate ring factors are not "
        "identifiable. k_R needs a load sweep to separate from tau_0. The angle input is the "
        "ball-set angle; ring-relative ball angles of Eq. 5 (φ_cage = φ_in·r_in/(r_in + r_out) "
        "for a fixed outer ring) matter only for localised damage, which is not modelled."
    ),
)
def drum_ball_rolling(radial_force, angle, k_R, tau_0, n_balls, r_in, r_out):
    """Bearing torque from per-ball rolling friction: τ = τ_0 + Σ_i F_N^i k_R (r_in + r_out)."""
    normal = seed_ball_normal_forces(radial_force, angle, int(n_balls))
    return tau_0 + k_R * (r_in + r_out) * jnp.sum(normal, axis=-1)


# --- non-parametric torque–speed law (look-up-table counterpart) ----------------------------------
SPLINE_KNOTS = 8
SPLINE_MAX_SPEED = Constant(
    float(1000 * 2 * math.pi / 60), "rad/s",
    "speed of the last knot (1000 rpm; set to the data's top speed; constant torque beyond)",
)


def spline_knot_speeds(max_speed, n_knots: int = SPLINE_KNOTS):
    """Knot speeds ω_k = ω_max (k/(K−1))², k = 0..K−1 (uniform in sqrt(ω): dense at low speed)."""
    return max_speed * (jnp.arange(n_knots) / (n_knots - 1)) ** 2


def _safe_div(a, b):
    nonzero = b != 0
    return jnp.where(nonzero, a / jnp.where(nonzero, b, 1.0), 0.0)


def _pchip_end_slope(h0, h1, d0, d1):
    """Three-point end slope with the Fritsch–Carlson limits (as scipy's PchipInterpolator)."""
    m = _safe_div((2 * h0 + h1) * d0 - h0 * d1, h0 + h1)
    m = jnp.where(jnp.sign(m) != jnp.sign(d0), 0.0, m)
    return jnp.where((jnp.sign(d0) != jnp.sign(d1)) & (jnp.abs(m) > 3 * jnp.abs(d0)), 3 * d0, m)


def pchip(x, knots, values):
    """Monotone piecewise-cubic Hermite interpolation (Fritsch & Carlson 1980), JAX.

    Matches ``scipy.interpolate.PchipInterpolator`` inside the knot range; outside it the end
    values are held constant. C¹, differentiable in ``values``.

    Parameters
    ----------
    x : array_like
        Evaluation points.
    knots : array_like
        Strictly increasing knot positions, shape (K,), K ≥ 3.
    values : array_like
        Values at the knots, shape (K,).

    Returns
    -------
    jax.Array
        Interpolated values, shape of ``x``.
    """
    h = jnp.diff(knots)
    d = jnp.diff(values) / h
    w1, w2 = 2 * h[1:] + h[:-1], h[1:] + 2 * h[:-1]
    same_sign = d[:-1] * d[1:] > 0
    harmonic = _safe_div(w1 + w2, _safe_div(w1, d[:-1]) + _safe_div(w2, d[1:]))
    interior = jnp.where(same_sign, harmonic, 0.0)
    first = _pchip_end_slope(h[0], h[1], d[0], d[1])
    last = _pchip_end_slope(h[-1], h[-2], d[-1], d[-2])
    slopes = jnp.concatenate([first[None], interior, last[None]])
    xc = jnp.clip(jnp.asarray(x, float), knots[0], knots[-1])
    i = jnp.clip(jnp.searchsorted(knots, xc, side="right") - 1, 0, knots.shape[0] - 2)
    t = (xc - knots[i]) / h[i]
    h00, h10 = (1 + 2 * t) * (1 - t) ** 2, t * (1 - t) ** 2
    h01, h11 = t**2 * (3 - 2 * t), t**2 * (t - 1)
    left = h00 * values[i] + h10 * h[i] * slopes[i]
    return left + h01 * values[i + 1] + h11 * h[i] * slopes[i + 1]


@law(
    name="drum_torque_spline",
    family="drum",
    rotary_only=_ROTARY,
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, §3.2 and §4 (look-up tables of measured torque over speed)",
    params={
        "level": Param("N*m", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
                       "friction torque at the first knot (zero speed)",
                       f"{SEED} Fig. 7–8; {_GENERIC}"),
        "tau": Param("1", Prior("HalfNormal", scale=0.3),
                     "random-walk step scale of log torque between knots (smoothness)",
                     "smoothing prior: a step of 0.3 in log torque (±35 %) per knot is generous "
                     "for the smooth curves of seed 003 Fig. 7–8"),
        "z": Param("1", Prior("Normal", loc=0.0, scale=1.0),
                   "standardised random-walk increments (non-centred)",
                   "non-centred random walk (Papaspiliopoulos et al. 2007)",
                   shape=(SPLINE_KNOTS - 1,)),
    },
    constants={"max_speed": SPLINE_MAX_SPEED},
    notes=(
        "Knot torques T_k = level·exp(tau·cumsum(z)): a random walk in log torque, positive by "
        "construction; monotone-cubic (PCHIP, C¹) interpolation keeps the torque between "
        "neighbouring knot values and gives coast-down integrators a smooth right-hand side. "
        "Knots beyond the largest tested speed are set by the prior alone, and the law is held "
        "constant above max_speed (no extrapolation of trends). tau and the z "
        "increments trade off (only tau·z is seen by the data)."
    ),
)
def drum_torque_spline(velocity, level, tau, z, max_speed):
    """Monotone-cubic (PCHIP) torque over speed on K knots, log random-walk prior, odd in ω."""
    log_steps = jnp.concatenate([jnp.zeros(1), jnp.cumsum(tau * z)])
    knot_torque = level * jnp.exp(log_steps)
    return jnp.sign(velocity) * pchip(jnp.abs(velocity), spline_knot_speeds(max_speed), knot_torque)
