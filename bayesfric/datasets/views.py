"""Views of a loaded dataset that the model needs: law inputs, response, scales, selections."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr

from bayesfric.datasets.loader import OBS_DIM, DataError
from bayesfric.laws.base import TRAJECTORY_START, Law
from bayesfric.priors import DataScale
from bayesfric.quantities import DERIVED_POSITIONS, QUANTITIES

__all__ = ["law_inputs", "response_values", "response_se", "data_scale", "select", "thin", "trajectory_starts",
           "travel"]


def trajectory_starts(ds: xr.Dataset) -> np.ndarray:
    """Boolean array, True where an ordered trajectory starts (first row, and wherever the
    dataset's ``trajectory`` group changes value). Without a trajectory group, one trajectory."""
    n = ds.sizes[OBS_DIM]
    starts = np.zeros(n, dtype=bool)
    if n:
        starts[0] = True
    key = ds.attrs.get("trajectory")
    if key:
        values = np.asarray(ds[key].values)
        starts[1:] |= values[1:] != values[:-1]
    return starts


def law_inputs(ds: xr.Dataset, law: Law) -> dict[str, np.ndarray]:
    """The arrays a law reads, by input name, in canonical SI units."""
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
    return out


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


def thin(ds: xr.Dataset, every: int = 1) -> xr.Dataset:
    """Every ``every``-th row, counted within each trajectory from its first row (which is kept, so
    a stateful law still starts each trajectory where it starts); ``ds`` itself for 1.

    A large log's neighbouring rows carry little information each (autocorrelated noise); thinning
    keeps its span and shape at a fraction of the cost. Derived inputs (an acceleration) were
    computed on the full log when it was loaded.

    Examples
    --------
    >>> from bayesfric.datasets.synthetic import make_dataset
    >>> ds = make_dataset({"velocity": np.arange(10.0)}, np.ones(10))
    >>> thin(ds, 3)["velocity"].values.tolist()
    [0.0, 3.0, 6.0, 9.0]
    """
    if every == 1:
        return ds
    starts = trajectory_starts(ds) if ds.attrs.get("trajectory") else np.eye(1, ds.sizes[OBS_DIM], dtype=bool)[0]
    position = np.arange(ds.sizes[OBS_DIM]) - np.maximum.accumulate(np.where(starts, np.arange(starts.size), 0))
    out = ds.isel({OBS_DIM: np.flatnonzero(position % every == 0)})
    out.attrs = dict(ds.attrs, selection=f"{ds.attrs.get('selection', 'all rows')}; one row in {every}")
    return out


def select(ds: xr.Dataset, where: Mapping[str, Any] | None = None) -> xr.Dataset:
    """Rows whose coordinates equal the given values (a list means 'any of')."""
    if not where:
        return ds
    keep = np.ones(ds.sizes[OBS_DIM], dtype=bool)
    for key, value in where.items():
        if key not in ds.coords:
            raise DataError(f"dataset {ds.attrs.get('name', '?')!r} has no coordinate {key!r} to select on")
        values = value if isinstance(value, list | tuple) else [value]
        keep &= np.isin(ds[key].values, values)
    if not keep.any():
        raise DataError(f"selection {dict(where)} leaves no rows of dataset {ds.attrs.get('name', '?')!r}")
    out = ds.isel({OBS_DIM: np.flatnonzero(keep)})
    out.attrs = dict(ds.attrs, selection=str(dict(where)))
    return out
