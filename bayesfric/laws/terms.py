"""Additive terms a study may ``add`` to a law: offset, viscous, and the drive terms inertia and gravity.

``offset`` is a constant response offset (sensor zero, a load, cable drag; not friction) with
prior ``Normal(0, 0.5) × response``; ``viscous`` is ``c_v · q̇`` with the viscous coefficient of
:mod:`bayesfric.laws.classical`. The drive-dynamics terms follow.

A drive's measured torque (force) is not friction alone: it is the inertial load, the gravity
load and friction together, and identification in practice fits them together (seed 004 §1:
friction models are used "in inertia parameter identification experiments", which fit the rigid
body's inertial parameters and the friction coefficients from the same joint torques). These
terms are parts for :mod:`bayesfric.laws.variants` (``add = ["inertia", "gravity"]``), declared
on rotary quantities like every law and run on force data through the same motion mapping:

``inertia``
    ``T = J · q̈`` with the moment of inertia ``J`` in kg·m² (rotary, input ``acceleration``);
    on force data ``F = M · ẍ`` with the mass ``M`` in kg (input ``linear_acceleration``). The
    acceleration is a data column, or is derived from velocity and time by the sidecar
    (:mod:`bayesfric.datasets.derive`).
``gravity``
    ``T = G_c cos q + G_s sin q`` for a revolute joint whose angle ``q`` (input ``angle``) is
    measured from a fixed reference: the one-joint form of the gravity torque ``m g l cos(q + φ)``
    written linearly in its two coefficients, as the inertial-parameter identification of robot
    arms writes it (the "base parameters" ``m l cos φ`` and ``m l sin φ`` times g); the amplitude
    ``G = √(G_c² + G_s²) = m g l`` is reported as a derived quantity. Rotary only: on a
    translational axis gravity is a constant load (``m g`` on a vertical axis, 0 on a horizontal
    one), which is the ``offset`` term.

Priors follow the data-scaling rule of :mod:`bayesfric.priors`: ``J`` (``M``) is
``HalfNormal(1) × response / acceleration`` -- the inertial load at the largest tested
acceleration is of the order of the largest measured response -- and ``G_c``, ``G_s`` are
``Normal(0, 0.5) × response``, as the offset is.
"""

from __future__ import annotations

import jax.numpy as jnp

from bayesfric.laws.base import Derived, Law, Param, declare
from bayesfric.priors import Prior

__all__ = ["all_terms", "drive_terms", "GENERIC"]

GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"
_IDENT = "inertial-parameter identification of robot joints (seed 004 §1)"
_GRAVITY_PRIOR = Prior("Normal", loc=0.0, scale=0.5, scaled_by={"response": 1})


def _offset(offset):
    """Constant additive offset: T = T_0 (sensor zero, gravity or cable drag; not friction)."""
    return offset


def _viscous(velocity, c_v):
    """Linear viscous term: T = c_v q̇."""
    return c_v * velocity


def _inertia(acceleration, J):
    """Inertial load of the drive: T = J q̈ (F = M ẍ on a translational axis)."""
    return J * acceleration


def _gravity(angle, G_c, G_s):
    """Gravity load of a revolute joint: T = G_c cos q + G_s sin q (amplitude m g l)."""
    return G_c * jnp.cos(angle) + G_s * jnp.sin(angle)


def drive_terms() -> dict[str, Law]:
    """The terms ``inertia`` and ``gravity`` (module docstring), declared and validated."""
    inertia = Param("kg*m**2", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "acceleration": -1}),
                    "moment of inertia of the drive reduced to the measured axis (mass M on a translational axis)",
                    f"{_IDENT}; {GENERIC}")
    g_c = Param("N*m", _GRAVITY_PRIOR, "gravity torque coefficient of cos(angle): m g l cos φ", f"{_IDENT}; {GENERIC}")
    g_s = Param("N*m", _GRAVITY_PRIOR, "gravity torque coefficient of sin(angle): m g l sin φ", f"{_IDENT}; {GENERIC}")
    amplitude = Derived(lambda G_c, G_s: jnp.hypot(G_c, G_s), "N*m", "gravity torque amplitude m g l")
    return {
        "inertia": declare(_inertia, name="inertia", family="term", inputs=("acceleration",), response="torque",
                           source=_IDENT, params={"J": inertia}, sign_definite=False),
        "gravity": declare(_gravity, name="gravity", family="term", inputs=("angle",), response="torque",
                           source=_IDENT, params={"G_c": g_c, "G_s": g_s}, derived={"G": amplitude},
                           sign_definite=False,
                           rotary_only="on a translational axis gravity is a constant load (m g on a vertical "
                                       "axis): add 'offset' instead"),
    }


def all_terms() -> dict[str, Law]:
    """Every additive term by name: ``offset``, ``viscous``, ``inertia``, ``gravity``."""
    from bayesfric.laws.classical import c_v_linear  # one declaration of the viscous coefficient

    offset = Param("N*m", Prior("Normal", loc=0.0, scale=0.5, scaled_by={"response": 1}),
                   "constant additive offset of the response (not friction: sensor zero, gravity, cables)", GENERIC)
    return {
        "offset": declare(_offset, name="offset", family="term", inputs=(), response="torque", source="bayesfric",
                          params={"offset": offset}, sign_definite=False),
        "viscous": declare(_viscous, name="viscous", family="term", inputs=("velocity",), response="torque",
                           source=c_v_linear.source, params={"c_v": c_v_linear}),
    } | drive_terms()
