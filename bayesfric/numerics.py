"""Powers with a real exponent, written as ``exp(p · log a)``: the one way the laws raise to a power.

On CPUs, XLA evaluates a float64 ``a ** p`` with a real exponent through a scalar ``pow`` per
element, and its gradient needs another ``pow`` and a ``log``; ``exp(p · log a)`` is one
vectorised ``exp`` and ``log``. Value and gradient of ``(c + x) ** p`` over the 111 robot_joint
speeds cost 2.8 µs against 0.66 µs as ``exp(p · log(c + x))``, and where the base is data
divided by a parameter, ``exp(p · (log x − log s))`` lets XLA fold ``log x`` into a constant
(data are constants of the compiled sampler): ``(|v| / s) ** p`` 2.8 µs against 0.28 µs. A fit
spends nearly all its sampling time in the log density's gradient: robot_joint's
joint_tribological took 5.5 µs per evaluation with ``**`` and 1.6 µs with these functions
(``benchmarks/bench_gradient.py``, medians of 3).

An exponent known when the program is traced (a Python number: a declared constant, a fixed
parameter, a literal such as 1.5) that is a multiple of 1/2 is computed exactly from ``sqrt``
and multiplications instead (``a ** 1.5`` as ``sqrt(a) ** 3``): 0.20 µs against 0.82 µs through
exp/log and 1.4 µs as ``pow``; an exponent of 0 or 1 then costs nothing, as ``pow`` with that
constant does after XLA's simplification.

Accuracy: the relative error of ``exp(p · log a)`` is about ``|p · log a|`` units in the last
place (``1e-13`` at ``|p · log a| = 500``), against ``pow``'s correctly rounded result; far
below any noise a friction measurement has.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

__all__ = ["positive_power", "power_ratio"]


def positive_power(a, p):
    """``a ** p`` for ``a > 0`` and 0 for ``a <= 0``, with finite gradients everywhere.

    Parameters
    ----------
    a : array_like
        Base; entries ``<= 0`` give 0 (and a zero gradient).
    p : array_like
        Exponent, broadcast against ``a``.

    Returns
    -------
    jax.Array
        ``exp(p · log a)`` where ``a > 0``, else 0.
    """
    positive = a > 0
    safe = jnp.where(positive, a, 1.0)
    halves = _static_halves(p)
    if halves is None:
        return jnp.where(positive, jnp.exp(p * jnp.log(safe)), 0.0)
    return jnp.where(positive, _half_integer_power(safe, halves), 0.0)


def power_ratio(x, scale, p):
    """``(x / scale) ** p`` for ``x > 0`` and 0 for ``x <= 0``; ``scale`` must be positive.

    Computed as ``exp(p · (log x − log scale))``, so that with ``x`` data and ``scale`` a
    parameter, ``log x`` is a constant of the compiled program (see the module notes).

    Parameters
    ----------
    x : array_like
        Numerator, e.g. a speed ``|q̇|`` (entries ``<= 0`` give 0 and a zero gradient).
    scale : array_like
        Positive reference, e.g. a Stribeck velocity.
    p : array_like
        Exponent.

    Returns
    -------
    jax.Array
    """
    if _static_halves(p) is not None:
        return positive_power(x / scale, p)
    positive = x > 0
    log_x = jnp.log(jnp.where(positive, x, 1.0))
    return jnp.where(positive, jnp.exp(p * (log_x - jnp.log(scale))), 0.0)


def _static_halves(p) -> int | None:
    """``2p`` when ``p`` is a Python or NumPy number that is a multiple of 1/2 (|p| <= 8), else None."""
    if not isinstance(p, (int, float, np.integer, np.floating)):
        return None  # traced (a sampled parameter) or an array
    twice = 2.0 * float(p)
    return int(twice) if twice.is_integer() and abs(twice) <= 16 else None


def _half_integer_power(a, halves: int):
    """``a ** (halves / 2)`` for ``a > 0`` from ``sqrt`` and integer powers (multiplications)."""
    if halves % 2 == 0:
        return a ** (halves // 2) if halves else jnp.ones_like(a)
    return jnp.sqrt(a) ** halves
