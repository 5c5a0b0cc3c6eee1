"""How far a sizing point lies beyond the tested data: its extrapolation distance, per direction.

The distance is counted in tested ranges (the width of the data along the input) beyond the
farthest tested value, and 0 inside. Friction is judged on ``|x|`` where the data have both signs
(−6 rad/s lies as far beyond data reaching ±4 rad/s as +6 rad/s does), but each point against
the data **on its own side of zero**: the edge it is measured from is the farthest (and nearest)
``|x|`` tested in its direction. Data that reach +0.5 rad/s but only −0.13 rad/s put −0.35 rad/s
(0.35 − 0.13) / 0.49 tested ranges beyond them, not inside; an asymmetric law (its parameters per
direction, ``asymmetric``) is likewise answered at −0.35 from what its negative side saw. The unit
stays the width of ``|x|`` over both sides, so a one-speed side is not infinitely far.
"""

from __future__ import annotations

import numpy as np

__all__ = ["point_distance"]


def _beyond(v: np.ndarray, lo: float, hi: float, width: float) -> np.ndarray:
    """Tested ranges (``width``) outside ``[lo, hi]`` on either side, 0 inside."""
    out = np.maximum(v - hi, 0.0) + np.maximum(lo - v, 0.0)
    if width <= 0:
        return np.where(out > 0, np.inf, 0.0)
    return out / width


def point_distance(x, data_values) -> np.ndarray:
    """Extrapolation distance of each point ``x`` from the tested ``data_values`` (module notes).

    Parameters
    ----------
    x : array_like
        The points' SI values along one input.
    data_values : array_like
        The data's SI values along that input.

    Returns
    -------
    numpy.ndarray
        Tested ranges beyond the data, 0 inside; where the data have both signs, each point is
        measured on ``|x|`` against the data of its own sign (a point at 0 against the nearer side).

    Examples
    --------
    >>> data = np.array([-0.13, -0.05, 0.01, 0.2, 0.5])
    >>> point_distance([0.35, -0.35, 0.8], data).round(3).tolist()
    [0.0, 0.449, 0.612]
    >>> point_distance([3.0, 0.5], np.array([1.0, 2.0])).tolist()  # one sign: on x itself
    [1.0, 0.5]
    """
    x = np.asarray(x, dtype=float)
    v = np.asarray(data_values, dtype=float)
    if not ((v < 0).any() and (v > 0).any()):
        return _beyond(x, float(np.min(v)), float(np.max(v)), float(np.max(v) - np.min(v)))
    speed = np.abs(v)
    width = float(np.max(speed) - np.min(speed))
    sides = {}
    for sign, mine in ((1, v >= 0), (-1, v <= 0)):
        s = speed[mine]
        sides[sign] = _beyond(np.abs(x), float(np.min(s)), float(np.max(s)), width)
    return np.where(x > 0, sides[1], np.where(x < 0, sides[-1], np.minimum(sides[1], sides[-1])))
