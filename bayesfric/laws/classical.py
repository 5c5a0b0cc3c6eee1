"""Velocity laws of joint friction from seed 004 (Stäubli RX90 joint friction).

Classical system-level laws (Eq. 1, 2, 4, 5) and the tribology-derived component laws: helical
gear pair (Eq. 35), pre-stressed roller bearing (Eq. 39) and the joint law (Eq. 41). All laws
are odd in velocity: they are written for |q̇| and multiplied by sign(q̇), so both directions of
motion work and the torque vanishes at exactly zero speed (where these sliding laws are not
defined; static friction at rest is outside their scope).

Orderings the physics implies are built into the parametrisation instead of being rejected:
the Stribeck laws sample the Coulomb level ``T_C`` and the static excess ``dT_s >= 0`` and
report ``T_s = T_C + dT_s`` as a derived quantity, so static >= Coulomb always holds.

Power-law viscous terms ``c · q̇^(1-δ)`` (Eq. 35, 41) have a unit that depends on δ; they are
written as ``c_v · (|q̇|/ω_ref)^(1-δ)`` with ω_ref = 1 rad/s, so ``c_v`` is the viscous torque at
1 rad/s in N·m and numerically equal to the paper's c^(v) in SI units.
"""

from __future__ import annotations

import jax.numpy as jnp

from bayesfric.laws.base import Constant, Derived, Param, law
from bayesfric.numerics import power_ratio
from bayesfric.priors import Prior

SEED = "seed 004 (Stäubli RX90 joint friction)"

# --- shared parameter declarations (one place each) -------------------------------------------
_TORQUE_LEVEL = Prior("HalfNormal", scale=1.0, scaled_by={"response": 1})
_VISCOUS = Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "velocity": -1})
# median 0.05 of the largest tested speed, 90 % within ~[0.004, 0.6] of it
_STRIBECK_VELOCITY = Prior("LogNormal", loc=-3.0, scale=1.5, scaled_by={"velocity": 1})
_GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"

T_C = Param("N*m", _TORQUE_LEVEL, "Coulomb friction torque", f"{SEED} Eq. 1; {_GENERIC}")
c_v_linear = Param("N*m*s/rad", _VISCOUS, "linear viscous coefficient", f"{SEED} Eq. 2; {_GENERIC}")
dT_s = Param(
    "N*m",
    Prior("HalfNormal", scale=0.5, scaled_by={"response": 1}),
    "static friction excess over Coulomb, T_s - T_C >= 0",
    f"{SEED} Eq. 3-4 (T_C < T_s); {_GENERIC}",
)
v_s = Param("rad/s", _STRIBECK_VELOCITY, "Stribeck velocity", f"{SEED} Eq. 4; {_GENERIC}")
delta_stribeck = Param(
    "1",
    Prior("LogNormal", loc=-0.36, scale=0.5),  # median 0.7, 90 % in [0.31, 1.6]
    "Stribeck shape exponent δ",
    f"{SEED} §2.1: δ = 0.5–1 for most material pairs (Bo & Pavelescu); 0.33 fitted for joint 1",
)
T_a0 = Param(
    "N*m", _TORQUE_LEVEL, "static asperity friction torque T^(a,0)", f"{SEED} Eq. 39-41; {_GENERIC}"
)
c_v_power = Param(
    "N*m",
    _TORQUE_LEVEL,
    "viscous torque at ω_ref = 1 rad/s (the paper's c^(v) in SI)",
    f"{SEED} Eq. 35, 41; {_GENERIC}",
)
delta_film = Param(
    "1",
    Prior("Beta", concentration1=2.0, concentration0=2.0),
    "film-height power δ in (0, 1); viscous torque grows as q̇^(1-δ)",
    f"{SEED} §3.2, Eq. 35 (sub-linear viscous growth, 0 < δ < 1)",
)
OMEGA_REF = Constant(1.0, "rad/s", "reference speed of the power-law viscous term")
T_s_derived = Derived(lambda T_C, dT_s: T_C + dT_s, "N*m", "static friction torque T_s")


def _stribeck_decay(speed, v_s, delta):
    return jnp.exp(-power_ratio(speed, v_s, delta))


@law(
    name="coulomb",
    family="classical",
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 1",
    params={"T_C": T_C},
)
def coulomb(velocity, T_C):
    """Coulomb friction: T = sign(q̇) T_C."""
    return jnp.sign(velocity) * T_C


@law(
    name="coulomb_viscous",
    family="classical",
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 2",
    params={"T_C": T_C, "c_v": c_v_linear},
)
def coulomb_viscous(velocity, T_C, c_v):
    """Coulomb + linear viscous friction: T = sign(q̇) T_C + c_v q̇."""
    return jnp.sign(velocity) * T_C + c_v * velocity


@law(
    name="stribeck",
    family="classical",
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 4 (Bo & Pavelescu)",
    params={"T_C": T_C, "dT_s": dT_s, "v_s": v_s, "delta": delta_stribeck},
    derived={"T_s": T_s_derived},
)
def stribeck(velocity, T_C, dT_s, v_s, delta):
    """Stribeck curve after Bo–Pavelescu: T = sign(q̇)[T_C + (T_s − T_C) exp(−(|q̇|/q̇_s)^δ)]."""
    speed = jnp.abs(velocity)
    return jnp.sign(velocity) * (T_C + dT_s * _stribeck_decay(speed, v_s, delta))


@law(
    name="armstrong_helouvry",
    family="classical",
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 5 (Armstrong-Hélouvry)",
    params={"T_C": T_C, "dT_s": dT_s, "v_s": v_s, "delta": delta_stribeck, "c_v": c_v_linear},
    derived={"T_s": T_s_derived},
)
def armstrong_helouvry(velocity, T_C, dT_s, v_s, delta, c_v):
    """Stribeck + linear viscous: T = sign(q̇)[T_C + (T_s − T_C) e^(−(|q̇|/q̇_s)^δ)] + c_v q̇."""
    speed = jnp.abs(velocity)
    return jnp.sign(velocity) * (T_C + dT_s * _stribeck_decay(speed, v_s, delta)) + c_v * velocity


@law(
    name="helical_gear",
    family="classical",
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 35 (helical gear pair)",
    params={"T_a0": T_a0, "v_s": v_s, "delta": delta_film, "c_v": c_v_power},
    constants={"omega_ref": OMEGA_REF},
)
def helical_gear(velocity, T_a0, v_s, delta, c_v, omega_ref):
    """Helical gear pair: T = sign(q̇)[T_a0 e^(−(|q̇|/q̇_s)^δ) + c_v (|q̇|/ω_ref)^(1−δ)], one δ."""
    speed = jnp.abs(velocity)
    asperity = T_a0 * _stribeck_decay(speed, v_s, delta)
    viscous = c_v * power_ratio(speed, omega_ref, 1.0 - delta)
    return jnp.sign(velocity) * (asperity + viscous)


@law(
    name="prestressed_roller_bearing",
    family="classical",
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 39 (pre-stressed roller bearing)",
    params={
        "T_a0": T_a0,
        "v_s": v_s,
        "delta": delta_stribeck,
        "T_l": Param(
            "N*m",
            _TORQUE_LEVEL,
            "limiting-shear-stress viscous torque T^(l,∞)",
            f"{SEED} Eq. 39-40b; {_GENERIC}",
        ),
        "v_l": Param(
            "rad/s",
            Prior("LogNormal", loc=-1.5, scale=1.5, scaled_by={"velocity": 1}),
            "speed scale q̇^(l) of the non-Newtonian viscous rise",
            f"{SEED} Eq. 40b; {_GENERIC}",
        ),
    },
)
def prestressed_roller_bearing(velocity, T_a0, v_s, delta, T_l, v_l):
    """Pre-stressed roller bearing: T = sign(q̇)[T_a0 e^(−(|q̇|/q̇_s)^δ) + T_l (1 − e^(−|q̇|/q̇_l))]."""
    speed = jnp.abs(velocity)
    asperity = T_a0 * _stribeck_decay(speed, v_s, delta)
    viscous = T_l * (1.0 - jnp.exp(-speed / v_l))
    return jnp.sign(velocity) * (asperity + viscous)


@law(
    name="joint_tribological",
    family="classical",
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 41 (joint friction law)",
    params={
        "T_a0": T_a0,
        "v_s": v_s,
        "delta_a": delta_stribeck,
        "c_v": c_v_power,
        "delta_v": delta_film,
    },
    constants={"omega_ref": OMEGA_REF},
)
def joint_tribological(velocity, T_a0, v_s, delta_a, c_v, delta_v, omega_ref):
    """Joint law: T = sign(q̇)[T_a0 e^(−(|q̇|/q̇_s)^δa) + c_v (|q̇|/ω_ref)^(1−δv)] (no Coulomb term)."""
    speed = jnp.abs(velocity)
    asperity = T_a0 * _stribeck_decay(speed, v_s, delta_a)
    viscous = c_v * power_ratio(speed, omega_ref, 1.0 - delta_v)
    return jnp.sign(velocity) * (asperity + viscous)
