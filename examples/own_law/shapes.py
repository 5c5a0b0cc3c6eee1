"""Helper of my_laws.py: shapes shared by several laws (an edit here recomputes their fits)."""

import jax.numpy as jnp


def smooth_sign(velocity, v_eps):
    """sign(q̇), smoothed over |q̇| ≲ v_eps (no jump at rest)."""
    return jnp.tanh(velocity / v_eps)


def stribeck_decay(speed, v_s):
    """exp(-(|q̇|/q̇_s)²): the Gaussian Stribeck decay."""
    return jnp.exp(-((speed / v_s) ** 2))
