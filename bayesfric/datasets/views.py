"""Views of a loaded dataset that the model needs: law inputs, response, scales, selections."""

from __future__ import annotations

import numpy as np
import xarray as xr

from bayesfric.datasets.loader import DataError
from bayesfric.datasets.rows import select, thin, trajectory_starts
from bayesfric.laws.base import TRAJECTORY_START, Law
from bayesfric.priors import DataScale
from bayesfric.quantities import DERIVED_POSITIONS, QUANTITIES

__all__ = ["law_inputs", "restart_problem", "response_values", "response_se", "data_scale", "select", "thin",
           "trajectory_starts", "travel"]


def law_inputs(ds: xr.Dataset, law: Law) -> dict[str, np.ndarray]:
    """The arrays a law reads, by input name, in canonical SI units.

    Raises
    ------
    DataError
        An input the law reads is missing, or a stateful law would run across a restart of data
        without a trajectory column (:func:`restart_problem`).
    """
    out = {}
    for name in law.inputs:
        if name == TRAJECTORY_START:
            out[name] = trajectory_starts(ds)
        elif name in ds.coords:
            out[name] = np.asarray(ds[name].values, dtype=float)
        else:
            have = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
            meaning = f" ({QUANTITIES[name].meaning})" if name in QUANTITIES else ""
            raise DataError(
                f"dataset {ds.attrs.get('name', '?')!r} has no input {name!r}{meaning} needed by law "
                f"{law.name!r} (inputs present: {', '.join(have) or 'none'})"
            )
    if problem := restart_problem(ds, law):
        raise DataError(problem)
    return out


#: A step of a position input counts as a jump (a restart) when it is this many times the median
#: step and at least :data:`JUMP_SHARE` of the position's range.
JUMP_STEPS = 5.0
JUMP_SHARE = 0.25


def restart_problem(ds: xr.Dataset, law: Law) -> str | None:
    """Why a trajectory (stateful) law cannot run along ``ds`` as one trajectory (None: it can).

    A stateful law (LuGre, Dahl, GMS, a coast-down ...) carries its state from row to row along a
    trajectory. Data without a trajectory column are one trajectory: where their time goes back
    (or stands still), or a position the law reads jumps (a step :data:`JUMP_STEPS` times the
    median step and at least :data:`JUMP_SHARE` of its range), a new run starts there, and the
    law would carry the last run's state into it (friction up to 10^38 N·m was seen). Such data
    must name the column that tells the runs apart (``[dataset] trajectory``); the loader then
    checks that time increases within each.
    """
    if not law.trajectory or ds.attrs.get("trajectory"):
        return None
    where = ds.attrs.get("csv_file") or f"dataset {ds.attrs.get('name', '?')!r}"
    fix = (f"law {law.name!r} is stateful and would carry its state across the restart: name the column that "
           "numbers the runs in the sidecar ([dataset] trajectory = \"<column>\"), one trajectory per run")
    if "time" in ds.coords:
        t = np.asarray(ds["time"].values, dtype=float)
        if (back := np.flatnonzero(np.diff(t) <= 0)).size:
            i = int(back[0]) + 1
            return f"{where}: row {i + 1} of the data: time goes from {t[i - 1]:g} s back to {t[i]:g} s; {fix}"
    for name in (q for q in DERIVED_POSITIONS if q in law.inputs and q in ds.coords):
        x = np.asarray(ds[name].values, dtype=float)
        step = np.abs(np.diff(x))
        moved = step[step > 0]
        if not moved.size:
            continue
        jumps = np.flatnonzero((step > JUMP_STEPS * np.median(moved)) & (step >= JUMP_SHARE * np.ptp(x)))
        if jumps.size:
            i = int(jumps[0]) + 1
            unit = QUANTITIES[name].unit
            return f"{where}: row {i + 1} of the data: {name} jumps from {x[i - 1]:g} to {x[i]:g} {unit}; {fix}"
    return None


def response_values(ds: xr.Dataset, law: Law | None = None) -> np.ndarray:
    """The response column in SI units; checks it is the quantity the law predicts."""
    name = ds.attrs["response"]
    if law is not None and name != law.response:
        raise DataError(
            f"law {law.name!r} predicts {law.response}, but dataset "
            f"{ds.attrs.get('name', '?')!r} has response {name}"
        )
    return np.asarray(ds[name].values, dtype=float)


def response_se(ds: xr.Dataset) -> np.ndarray | None:
    """The response's standard error per row in SI units (the ``se`` column of a reduced data
    set, :mod:`bayesfric.datasets.reduce`), or None when the data set has none."""
    for var in ds.data_vars.values():
        if var.attrs.get("role") == "se":
            return np.asarray(var.values, dtype=float)
    return None


def data_scale(ds: xr.Dataset) -> DataScale:
    """Scales used by data-scaled priors (rule in :mod:`bayesfric.priors`).

    Where the data set has a speed and time but no position input (:data:`bayesfric.quantities.DERIVED_POSITIONS`),
    the position's scale is the largest excursion :func:`travel` integrates from them: the scale
    of a prior on a deflection of a law that reads velocity and time (GMS's break-away deflections),
    the same as the largest |angle| a recorded angle would give on loops from rest.
    """
    inputs = {k: v.values for k, v in ds.coords.items() if v.attrs.get("role") == "input"}
    for position, speed in DERIVED_POSITIONS.items():
        if position not in inputs and speed in inputs and "time" in inputs:
            inputs[position] = travel(inputs[speed], inputs["time"], trajectory_starts(ds))
    return DataScale.of(ds[ds.attrs["response"]].values, inputs)


def travel(speed: np.ndarray, time: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Position relative to each trajectory's first row, ∫ speed dt by the trapezoid rule.

    Parameters
    ----------
    speed, time : array, shape (n,)
        Rows in order within each trajectory (time restarts or continues, either way).
    starts : array of bool, shape (n,)
        True at each trajectory's first row (:func:`trajectory_starts`).

    Returns
    -------
    array, shape (n,)
        0 at every start.
    """
    v, t = np.asarray(speed, dtype=float), np.asarray(time, dtype=float)
    steps = np.where(starts, 0.0, 0.5 * (v + np.r_[v[:1], v[:-1]]) * np.diff(t, prepend=t[:1]))
    total = np.cumsum(np.where(np.isfinite(steps), steps, 0.0))
    first = np.maximum.accumulate(np.where(starts, np.arange(v.size), 0))
    return total - total[first]
