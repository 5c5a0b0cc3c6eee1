"""A friction law of my own: a plain function, its units and one prior; the rest is defaulted.

Parameters are read from the signature (``velocity`` is an input of the vocabulary; ``T_C``,
``dT_s``, ``v_s`` and ``c_v`` have no default, so they are sampled; ``v_eps`` has one, so it is a
constant). Priors not given are HalfNormal scaled to the data by the parameter's unit.
``bayesfric.law(..., register=True)`` lists it among the laws, so a study file names it once this
file is among its ``[study] modules``.
"""

import jax.numpy as jnp
from shapes import smooth_sign, stribeck_decay

import bayesfric


def smooth_stribeck(velocity, T_C, dT_s, v_s, c_v, v_eps=1e-3):
    """Smooth Stribeck curve: T = tanh(q̇/ε)·[T_C + ΔT_s·exp(−(q̇/q̇_s)²)] + c_v·q̇."""
    speed = jnp.abs(velocity)
    return smooth_sign(velocity, v_eps) * (T_C + dT_s * stribeck_decay(speed, v_s)) + c_v * velocity


smooth_stribeck = bayesfric.law(
    smooth_stribeck,
    units={"T_C": "N*m", "dT_s": "N*m", "v_s": "rad/s", "c_v": "N*m*s/rad", "v_eps": "rad/s"},
    priors={"v_s": bayesfric.Prior("LogNormal", loc=-3.0, scale=1.5, scaled_by={"velocity": 1})},
    source="my lab notebook, p. 12",
    register=True,
)
