"""Inputs computed from other inputs: an acceleration differentiated from velocity and time.

A drive's log often has position or velocity and time but no acceleration, which the ``inertia``
term reads (:mod:`bayesfric.laws.terms`). The sidecar may ask for it::

    [derive.linear_acceleration]     # or [derive.acceleration] (from velocity, rad/s -> rad/s²)
    method = "savgol"                # the only method: Savitzky–Golay derivative
    window = 11                      # samples, odd, > order (default 7)
    order = 3                        # polynomial order, 1..10 (default 3)

The filter is :func:`scipy.signal.savgol_filter` with ``deriv=1``, ``delta`` the sampling
interval and ``mode="interp"`` (the first and last ``window // 2`` samples of a trajectory take
the derivative of the polynomial fitted to its first/last ``window`` samples). Why order 3 by
default: in a symmetric window an even order gives the first derivative of the order below it,
and order 1 (or 2) is biased by the curvature (0.5 % of the peak on a sine at 100 samples per
period with window 7, against 3e-6 at order 3: ``tests/test_drive_dynamics.py``). It is applied to
each ordered trajectory separately (the ``[dataset] trajectory`` group; without one, the whole
file is one trajectory), never across a boundary. Rules, each a one-line :class:`DataError`
naming ``[derive.<name>]``: the data have the velocity input it differentiates and a ``time``
input; no column already declares the quantity; time strictly increases within a trajectory and
is evenly sampled there (every step within 1 % of the trajectory's median step); every
trajectory has at least ``window`` rows. What was derived and how is written into the
coordinate's ``derived`` attribute and the data set's ``attrs["derived"]``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bayesfric.datasets.errors import DataError
from bayesfric.quantities import QUANTITIES

__all__ = ["DERIVABLE", "DERIVE_KEYS", "SPACING_RTOL", "check_derive", "derive_inputs", "savgol_derivative"]

#: Quantity that may be derived -> the input it is the time derivative of.
DERIVABLE = {"acceleration": "velocity", "linear_acceleration": "linear_velocity"}
#: Keys of a ``[derive.<name>]`` table: type and default.
DERIVE_KEYS: dict[str, tuple[type, object]] = {"method": (str, "savgol"), "window": (int, 7), "order": (int, 3)}
#: Largest relative deviation of a sampling step from the trajectory's median step.
SPACING_RTOL = 0.01


def check_derive(path: Path, table: object) -> None:
    """Check the ``[derive]`` table of a sidecar (everything that needs no data).

    Raises
    ------
    DataError
        One line naming ``path`` and ``[derive.<name>] <key>``.
    """
    if not isinstance(table, dict):
        raise DataError(f"{path}: derive must be a table ([derive.<quantity>])")
    for name, spec in table.items():
        where = f"{path}: [derive.{name}]"
        if name not in DERIVABLE:
            raise DataError(f"{where}: cannot derive {name!r}; derivable: {', '.join(DERIVABLE)}")
        if not isinstance(spec, dict):
            raise DataError(f"{where}: must be a table of {', '.join(DERIVE_KEYS)}")
        for key, value in spec.items():
            if key not in DERIVE_KEYS:
                raise DataError(f"{where}: unknown key {key!r}; known keys: {', '.join(DERIVE_KEYS)}")
            kind = DERIVE_KEYS[key][0]
            if not isinstance(value, kind) or isinstance(value, bool):
                raise DataError(f"{where} {key}: must be {'an integer' if kind is int else 'a string'}, got {value!r}")
        method, window, order = _settings(spec)
        if method != "savgol":
            raise DataError(f"{where} method: {method!r} is not a method; the one method is 'savgol'")
        if order < 1 or order > 10:
            raise DataError(f"{where} order: {order} must lie in 1..10 (a first derivative needs order >= 1)")
        if window % 2 == 0 or window <= order or window > 10_001:
            raise DataError(f"{where} window: {window} must be odd, greater than order ({order}) and at most 10001")


def _settings(spec: dict) -> tuple[str, int, int]:
    return tuple(spec.get(k, default) for k, (_, default) in DERIVE_KEYS.items())  # type: ignore[return-value]


def savgol_derivative(time: np.ndarray, values: np.ndarray, window: int, order: int) -> np.ndarray:
    """d(values)/d(time) of one evenly sampled trajectory by a Savitzky–Golay filter.

    Parameters
    ----------
    time, values : numpy.ndarray
        One trajectory, time strictly increasing and evenly spaced (checked by the caller).
    window, order : int
        Window length (odd, samples) and polynomial order of the filter.

    Returns
    -------
    numpy.ndarray
        The derivative at every sample (``mode="interp"`` at the ends).
    """
    step = float(np.median(np.diff(time)))
    from scipy.signal import savgol_filter  # here: scipy.signal imports scipy.stats, which `fit` defers

    return savgol_filter(values, window, order, deriv=1, delta=step, mode="interp")


def _blocks(n: int, labels: np.ndarray | None) -> list[tuple[int, int]]:
    """(start, stop) of each contiguous trajectory (one block without labels)."""
    if labels is None:
        return [(0, n)]
    cuts = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    edges = [0, *cuts.tolist(), n]
    return list(zip(edges[:-1], edges[1:], strict=True))


def _derive_one(where: str, coords: dict, source: str, spec: dict, labels: np.ndarray | None) -> np.ndarray:
    """The derivative of ``source`` over time, trajectory by trajectory; problems name ``where``."""
    _, window, order = _settings(spec)
    time, values = coords["time"][1], coords[source][1]
    out = np.empty_like(values, dtype=float)
    for start, stop in _blocks(len(values), labels):
        name = f"trajectory {labels[start].item()!r}" if labels is not None else "the file (one trajectory)"
        if stop - start < window:
            raise DataError(f"{where} window: {name} has {stop - start} rows, fewer than the window ({window})")
        steps = np.diff(time[start:stop])
        if np.any(steps <= 0):
            row = start + int(np.argmax(steps <= 0)) + 2
            raise DataError(f"{where}: time does not increase at row {row} of {name}; a derivative needs ordered "
                            "time (declare [dataset] trajectory to separate trajectories)")
        median = float(np.median(steps))
        worst = int(np.argmax(np.abs(steps - median)))
        if abs(steps[worst] - median) > SPACING_RTOL * median:
            raise DataError(f"{where}: {name} is not evenly sampled (step {steps[worst]:.6g} s at row "
                            f"{start + worst + 2} against the median {median:.6g} s, more than {SPACING_RTOL:.0%} "
                            "apart); resample it or give the acceleration as a column")
        out[start:stop] = savgol_derivative(time[start:stop], values[start:stop], window, order)
    return out


def derive_inputs(meta_path: Path, table: dict, coords: dict, trajectory: str | None) -> tuple[dict, str]:
    """The derived input coordinates of a data set and a sentence saying how they were made.

    Parameters
    ----------
    meta_path : Path
        The sidecar (named in errors).
    table : dict
        Its ``[derive]`` table, checked by :func:`check_derive`.
    coords : dict
        The loader's coordinates ``name -> (dim, values in SI, attrs)``.
    trajectory : str or None
        The group coordinate that delimits trajectories (contiguity already checked).

    Raises
    ------
    DataError
        A missing velocity or time input, a quantity already given as a column, uneven or
        unordered sampling, a trajectory shorter than the window.
    """
    labels = np.asarray(coords[trajectory][1]) if trajectory else None
    new, texts = {}, []
    for name, spec in table.items():
        where, source = f"{meta_path}: [derive.{name}]", DERIVABLE[name]
        if name in coords:
            raise DataError(f"{where}: the data already have a {name!r} column ({coords[name][2]['column']!r}); "
                            "derive it or read it, not both")
        missing = [q for q in (source, "time") if q not in coords or coords[q][2].get("role") != "input"]
        if missing:
            have = [k for k, v in coords.items() if v[2].get("role") == "input"]
            raise DataError(f"{where}: needs the input(s) {', '.join(map(repr, missing))} to differentiate "
                            f"(inputs present: {', '.join(have) or 'none'})")
        values = _derive_one(where, coords, source, spec, labels)
        method, window, order = _settings(spec)
        text = (f"{name} = d({source})/d(time) by a Savitzky–Golay filter (scipy.signal.savgol_filter, "
                f"window {window} samples, order {order}, mode 'interp'), per "
                + (f"trajectory {trajectory!r}" if trajectory else "file (one trajectory)"))
        unit = QUANTITIES[name].unit
        new[name] = (coords[source][0], values, {"role": "input", "column": f"{name} (derived)", "quantity": name,
                                                 "units": unit, "original_unit": unit, "derived": text})
        texts.append(text)
    return new, "; ".join(texts)
