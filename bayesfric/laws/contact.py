"""Sliding-contact laws that scale with the normal force (tribometers).

A tribometer presses two bodies together with a normal force ``F_N`` (the vocabulary's
``normal_force``, in N) and measures the friction force. Amontons–Coulomb friction is
proportional to it, ``F = µ F_N sign(ẋ)``, so the law's coefficient is the dimensionless
coefficient of friction µ, comparable across loads and rigs, instead of a force level valid at
one load. The normal force is an input of its own, not a ``preload``: a bearing's preload is the
axial load of a bearing pair, and Dahl's preload-scaled variants read it against their 89 N
reference (:mod:`bayesfric.laws.hysteresis`); a normal force never switches that on.

Other laws use the normal force the same way: a law declared with ``normal_force`` among its
inputs reads it like any operating quantity (``simple_law`` finds it by its parameter name), and
``add = ["viscous", "offset"]`` composes the usual extra terms.

The law is declared on translational quantities (``linear_velocity``, response ``force``): a
tribometer slides; there is no rotary form.
"""

from __future__ import annotations

import jax.numpy as jnp

from bayesfric.laws.base import Param, law
from bayesfric.priors import Prior

SOURCE = "Amontons (1699), Coulomb (1785): friction proportional to the normal load"

#: µ: the friction force at the largest tested normal load is of the order of the largest
#: measured friction force (data-scaled, :mod:`bayesfric.priors`): HalfNormal(1) × R / F_N,max.
mu = Param("1", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "normal_force": -1}),
           "coefficient of (kinetic) friction µ = F / F_N",
           f"{SOURCE}; generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)")


@law(
    name="amontons",
    family="contact",
    inputs=("linear_velocity", "normal_force"),
    response="force",
    source=SOURCE,
    params={"mu": mu},
)
def amontons(linear_velocity, normal_force, mu):
    """Amontons–Coulomb friction: F = µ F_N sign(ẋ)."""
    return jnp.sign(linear_velocity) * mu * normal_force
