"""Which rows of a loaded data set are used, and which columns can group them.

:func:`select` keeps the rows whose coordinates equal given values (``[data] select``, ``--select``;
a value no row has is an error, not a silent no-op), :func:`thin` one row in n of each
trajectory (``[data] every``), :func:`trajectory_starts` marks where each trajectory starts, and
:func:`group_problem` says why a column cannot serve as a group column (``vary_by``, ``trend``,
``[compare] grouped`` or ``forecast``, ``[noise] group``, ``fit --group``): a continuous input
is not a group, nor a column whose levels do not repeat. :data:`MAX_LEVELS` is the number of
levels a study accepts without being told (``[data] max_levels``): every level is a refit of
every law in leave-one-group-out folds.

Light: it imports the loader's names and numpy, not the laws (nor JAX), so the command line runs
it before JAX loads. :mod:`bayesfric.datasets.views` re-exports these names.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr

from bayesfric.datasets.loader import OBS_DIM, DataError

__all__ = ["MAX_LEVELS", "trajectory_starts", "select", "thin", "group_problem", "levels_of"]

#: Levels a group column may have before a study must confirm them with ``[data] max_levels``:
#: leave-one-group-out refits every law once per level, and ``vary_by`` samples one value per level
#: and parameter.
MAX_LEVELS = 100


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


def levels_of(ds: xr.Dataset, column: str) -> list[str]:
    """The distinct values of ``column`` as text, in the data's sorted order."""
    return [str(v) for v in np.unique(np.asarray(ds[column].values))]


def _shown(labels: list[str], most: int = 8) -> str:
    return ", ".join(labels[:most]) + (f" … ({len(labels)} in all)" if len(labels) > most else "")


def select(ds: xr.Dataset, where: Mapping[str, Any] | None = None) -> xr.Dataset:
    """Rows whose coordinates equal the given values (a list means 'any of').

    Raises
    ------
    DataError
        A coordinate the data lack, a value no row has (naming it and the levels there are), or a
        selection that leaves no row.
    """
    if not where:
        return ds
    keep = np.ones(ds.sizes[OBS_DIM], dtype=bool)
    name = ds.attrs.get("name", "?")
    for key, value in where.items():
        if key not in ds.coords:
            raise DataError(f"dataset {name!r} has no coordinate {key!r} to select on")
        values = list(value) if isinstance(value, list | tuple) else [value]
        if not values:
            raise DataError(f"{key}: an empty list selects no row of dataset {name!r}")
        column = np.asarray(ds[key].values)
        for v in values:
            if not np.isin(column, [v]).any():
                raise DataError(f"{key} = {v!r}: no row of dataset {name!r} has it (its {key} values: "
                                f"{_shown(levels_of(ds, key))})")
        keep &= np.isin(column, values)
    if not keep.any():
        raise DataError(f"selection {dict(where)} leaves no rows of dataset {name!r}")
    out = ds.isel({OBS_DIM: np.flatnonzero(keep)})
    out.attrs = dict(ds.attrs, selection=str(dict(where)))
    return out


def group_problem(ds: xr.Dataset, column: str) -> str | None:
    """Why ``column`` cannot group the rows of ``ds`` (None: it can).

    A group column labels runs, series, units or campaigns (role ``group`` in the sidecar, or an
    input declared ``group = true``, which adds ``<column>_group``): each level many rows. A CSV
    column that became an input (named by its quantity), a continuous input, or a column whose
    levels do not repeat (more levels than half the rows) is none.

    Examples
    --------
    >>> from bayesfric.datasets.synthetic import make_dataset
    >>> ds = make_dataset({"velocity": np.arange(6.0)}, np.ones(6), groups={"run": [1, 1, 1, 2, 2, 2]})
    >>> group_problem(ds, "run") is None
    True
    >>> group_problem(ds, "velocity").split(":")[0]
    "'velocity' is an input (6 distinct values), not a group column"
    """
    groups = [k for k, v in ds.coords.items() if v.attrs.get("role") == "group"]
    if column not in ds.coords:
        became = next((k for k, v in ds.coords.items() if v.attrs.get("column") == column and k != column), None)
        if became is not None:
            return (f"{column!r} is the CSV column of input {became!r}, not a group column (group columns of the "
                    f"data: {', '.join(groups) or 'none'})")
        return f"{column!r} is not a column of the data (group columns: {', '.join(groups) or 'none'})"
    coord = ds.coords[column]
    if coord.attrs.get("role") != "group":
        n = np.unique(np.asarray(coord.values)).size
        return (f"{column!r} is an {coord.attrs.get('role', 'untyped')} ({n} distinct values), not a group column: "
                "group terms, trends and grouped folds need a column of run, series, unit or campaign labels "
                "(role = \"group\" in the sidecar, or group = true on an input, which adds '<column>_group')")
    levels, rows = np.unique(np.asarray(coord.values)).size, ds.sizes[OBS_DIM]
    if rows > 1 and levels > rows / 2:
        return (f"{column!r} has {levels} levels over {rows} rows: most hold a single row, so it does not group "
                "rows (a group column labels runs, series, units or campaigns of many rows each)")
    return None
