"""Load friction measurements from CSV + a TOML sidecar into an xarray Dataset in SI units.

The sidecar (``FILE.toml`` next to ``FILE.csv`` unless named explicitly) says what each column is::

    [dataset]
    name = "joint1"
    title = "Stribeck curve of a robot joint"
    provenance = "measured"          # measured | reconstructed | simulated
    source = "lab notebook 12, 2026-03-02"
    trajectory = "run"               # optional: group column whose values delimit ordered trajectories

    [columns.speed]                  # a CSV header name
    role = "input"                   # input | response | group | aux
    quantity = "velocity"            # from bayesfric.quantities.QUANTITIES
    unit = "rpm"                     # any pint unit of that quantity's dimension
    [columns.torque]
    role = "response"
    quantity = "torque"
    unit = "N*m"
    [columns.series]
    role = "group"

The result has one dimension ``obs``; every input becomes a coordinate named by its *quantity*
(so laws find ``velocity`` whatever the column was called), groups become coordinates named by
their column, the response a data variable named by its quantity, aux columns data variables.
Units (canonical SI) and the original column/unit live in each variable's attrs; provenance,
source and a content hash live in the dataset's attrs.

Every problem raises :class:`DataError` with one line naming file, column and row.
"""

from __future__ import annotations

import csv
import hashlib
import math
import tomllib
from pathlib import Path

import numpy as np
import xarray as xr

from bayesfric.quantities import QUANTITIES, RESPONSES, UnitError, conversion

__all__ = ["DataError", "load_dataset", "PROVENANCES", "ROLES", "OBS_DIM"]

OBS_DIM = "obs"
PROVENANCES = ("measured", "reconstructed", "simulated")
ROLES = ("input", "response", "group", "aux")


class DataError(ValueError):
    """Bad input data: the message is one line naming file, column and row where they apply."""


def load_dataset(csv_path: str | Path, meta_path: str | Path | None = None) -> xr.Dataset:
    """Load ``csv_path`` with its TOML sidecar into an SI-unit :class:`xarray.Dataset`.

    Parameters
    ----------
    csv_path : str or Path
        The measurement table; first line is the header.
    meta_path : str or Path, optional
        The sidecar; default ``csv_path`` with suffix ``.toml``.

    Returns
    -------
    xarray.Dataset
        Dimension ``obs``; inputs as coordinates named by quantity; response as a data variable.

    Raises
    ------
    DataError
        Missing file or column, unknown or wrong-dimension unit, NaN/inf, empty file,
        non-numeric cell, bad metadata.
    """
    csv_path = Path(csv_path)
    meta_path = Path(meta_path) if meta_path is not None else csv_path.with_suffix(".toml")
    meta = _read_meta(meta_path)
    header, rows = _read_csv(csv_path)
    columns = meta["columns"]

    for col in columns:
        if col not in header:
            raise DataError(f"{csv_path}: column {col!r} named in {meta_path.name} is missing from the header")

    coords: dict[str, tuple] = {}
    data_vars: dict[str, tuple] = {}
    response_name = None
    for col, spec in columns.items():
        idx = header.index(col)
        role = spec["role"]
        raw = [r[idx] for r in rows]
        if role == "group":
            values = _group_values(raw)
            coords[col] = (OBS_DIM, values, {"role": "group", "column": col})
            continue
        quantity = spec.get("quantity")
        unit = spec.get("unit", "1")
        numbers = _numeric(raw, csv_path, col)
        attrs = {"role": role, "column": col, "original_unit": unit}
        if quantity is not None:
            try:
                scale, offset = conversion(unit, quantity)
            except UnitError as exc:
                raise DataError(f"{meta_path}: column {col!r}: {exc}") from None
            numbers = numbers * scale + offset
            attrs.update(quantity=quantity, units=QUANTITIES[quantity].unit)
        else:
            attrs.update(units=unit)
        name = quantity if role in ("input", "response") else col
        if role == "input":
            if name in coords:
                raise DataError(f"{meta_path}: columns {coords[name][2]['column']!r} and {col!r} are both {name}")
            coords[name] = (OBS_DIM, numbers, attrs)
            if spec.get("group"):
                coords[f"{col}_group"] = (OBS_DIM, numbers, {"role": "group", "column": col})
        elif role == "response":
            response_name = name
            data_vars[name] = (OBS_DIM, numbers, attrs)
        else:
            data_vars[col] = (OBS_DIM, numbers, attrs)

    ds_meta = meta["dataset"]
    content = csv_path.read_bytes() + meta_path.read_bytes()
    attrs = {
        "name": ds_meta.get("name", csv_path.stem),
        "title": ds_meta.get("title", ""),
        "provenance": ds_meta["provenance"],
        "source": ds_meta["source"],
        "description": ds_meta.get("description", ""),
        "response": response_name,
        "data_hash": hashlib.sha256(content).hexdigest()[:16],
        "csv_file": str(csv_path),
    }
    if "trajectory" in ds_meta:
        traj = ds_meta["trajectory"]
        if traj not in coords or coords[traj][2].get("role") != "group":
            raise DataError(f"{meta_path}: [dataset] trajectory = {traj!r} is not a group column")
        attrs["trajectory"] = traj
    ds = xr.Dataset(data_vars=data_vars, coords=coords, attrs=attrs)
    return ds


# -- metadata ------------------------------------------------------------------------------------
def _read_meta(path: Path) -> dict:
    if not path.exists():
        raise DataError(f"{path}: metadata file not found (expected next to the CSV, same name, .toml)")
    try:
        meta = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise DataError(f"{path}: invalid TOML: {exc}") from None
    if "dataset" not in meta or "columns" not in meta:
        raise DataError(f"{path}: needs a [dataset] table and [columns.<name>] tables")
    ds = meta["dataset"]
    for key in ("provenance", "source"):
        if key not in ds:
            raise DataError(f"{path}: [dataset] is missing {key!r}")
    if ds["provenance"] not in PROVENANCES:
        raise DataError(f"{path}: [dataset] provenance {ds['provenance']!r} not one of {PROVENANCES}")
    n_response = 0
    for col, spec in meta["columns"].items():
        where = f"{path}: column {col!r}"
        if not isinstance(spec, dict) or "role" not in spec:
            raise DataError(f"{where}: needs a 'role' ({', '.join(ROLES)})")
        if spec["role"] not in ROLES:
            raise DataError(f"{where}: role {spec['role']!r} not one of {ROLES}")
        if spec["role"] in ("input", "response"):
            q = spec.get("quantity")
            if q not in QUANTITIES:
                raise DataError(f"{where}: quantity {q!r} unknown; known: {', '.join(QUANTITIES)}")
            if "unit" not in spec:
                raise DataError(f"{where}: needs a 'unit'")
        if spec["role"] == "response":
            n_response += 1
            if spec["quantity"] not in RESPONSES:
                raise DataError(f"{where}: a response must be one of {RESPONSES}")
        if spec["role"] == "aux" and "quantity" in spec and "unit" not in spec:
            raise DataError(f"{where}: needs a 'unit'")
    if n_response != 1:
        raise DataError(f"{path}: exactly one column must have role 'response' (found {n_response})")
    return meta


# -- CSV -----------------------------------------------------------------------------------------
def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    if not path.exists():
        raise DataError(f"{path}: file not found")
    with path.open(newline="") as fh:
        lines = [row for row in csv.reader(line for line in fh if not line.startswith("#"))]
    lines = [r for r in lines if any(c.strip() for c in r)]
    if not lines:
        raise DataError(f"{path}: file is empty")
    header = [h.strip() for h in lines[0]]
    rows = lines[1:]
    if not rows:
        raise DataError(f"{path}: file has a header but no data rows")
    for i, r in enumerate(rows):
        if len(r) != len(header):
            raise DataError(f"{path}: row {i + 1}: has {len(r)} cells, header has {len(header)}")
    return header, rows


def _numeric(raw: list[str], path: Path, col: str) -> np.ndarray:
    out = np.empty(len(raw))
    for i, cell in enumerate(raw):
        text = cell.strip()
        try:
            value = float(text)
        except ValueError:
            raise DataError(f"{path}: row {i + 1}: column {col!r}: {text!r} is not a number") from None
        if not math.isfinite(value):
            raise DataError(f"{path}: row {i + 1}: column {col!r}: non-finite value {text!r}")
        out[i] = value
    return out


def _group_values(raw: list[str]) -> np.ndarray:
    stripped = [c.strip() for c in raw]
    try:
        ints = [int(c) for c in stripped]
        return np.asarray(ints)
    except ValueError:
        return np.asarray(stripped, dtype=object).astype(str)
