"""Load friction measurements from CSV + a TOML sidecar into an xarray Dataset in SI units.

The sidecar (``FILE.toml`` next to ``FILE.csv`` unless named explicitly) says what each column is::

    [dataset]
    name = "joint1"
    title = "Stribeck curve of a robot joint"
    provenance = "measured"          # measured | reconstructed | simulated
    source = "lab notebook 12, 2026-03-02"
    trajectory = "run"               # optional: group column whose values delimit ordered trajectories
    encoding = "latin-1"             # optional: the CSV's text encoding (default UTF-8, BOM or not)

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
    [columns.torque_se]              # optional: the response's standard error per row
    role = "se"                      # (a reduced data set, :mod:`bayesfric.datasets.reduce`)
    quantity = "torque"
    unit = "N*m"

A ``[derive.<quantity>]`` table computes an input from others: an acceleration differentiated
from velocity and time by a stated Savitzky–Golay filter, per trajectory
(:mod:`bayesfric.datasets.derive`; recorded in ``attrs["derived"]``).
A file written by ``bayesfric data reduce`` also has a ``[reduction]`` table (what was reduced:
source file and its SHA-256, the settings; :data:`bayesfric.datasets.sidecar.REDUCTION_KEYS`),
read into ``attrs["reduced_from"]``.

The result has one dimension ``obs``; every input becomes a coordinate named by its *quantity*
(so laws find ``velocity`` whatever the column was called), groups become coordinates named by
their column, the response a data variable named by its quantity, aux and se columns data variables
named by their column (an se column is >= 0, in the response's SI unit).
Units (canonical SI) and the original column/unit live in each variable's attrs; provenance,
source and a content hash live in the dataset's attrs.

Rules (each broken rule raises :class:`DataError` with one line naming file, column and row;
rows are data rows counted from 1, comment lines ``#...`` and blank lines not counted):

* Files: the CSV and the sidecar are regular files (not folders or pipes).
* Sidecar: UTF-8 TOML (a BOM is fine); only the keys above (``group = true`` on an input also
  makes it a group); exactly one response. Column names are not empty and have no surrounding
  whitespace.
* CSV: UTF-8 with or without BOM, or the codec named by ``[dataset] encoding`` (any text
  encoding Python knows: ``latin-1``, ``cp1252`` ...). First non-comment line is the header; header
  names may not repeat (empty header cells are unnamed, ignored columns); every row has as many
  cells as the header; no row limit but the memory its text needs to load (:data:`bayesfric.limits.LOAD_FACTOR`).
* Cells: numbers, finite before and after conversion to SI; group cells not empty; no cell longer
  than :data:`MAX_CELL` characters.
* Physical bounds, declared once per quantity in :mod:`bayesfric.quantities` (``Quantity.lower``),
  checked in SI: absolute temperature > 0 K; preload, axial and radial force >= 0 N (magnitudes);
  time >= 0 s. A converted value within the conversion's rounding of a bound counts as on it
  (:data:`bayesfric.quantities.ROUNDING`): -459.67 degF is 0 K and fails "> 0 K". Signed
  quantities (velocities, angles, torque, force, bending moment, initial velocity) are unbounded.
* Scale: the response must not be all zero (nothing to fit), and the largest |value| of the
  response and of every input that is not all zero must lie in
  :data:`bayesfric.quantities.SCALE_RANGE` (SI), because data-scaled priors are expressed in these
  scales (:mod:`bayesfric.priors`).
* Trajectories (``trajectory = "<group column>"``): each trajectory's rows form one contiguous
  block, and with a ``time`` input, time strictly increases within a trajectory. Without a time
  input the row order *is* the trajectory order and only contiguity is checked: hysteresis loops
  go back and forth in angle, so no input need be monotone.
"""

from __future__ import annotations

import codecs
import csv
import hashlib
import io
from pathlib import Path

import numpy as np
import xarray as xr

from bayesfric.datasets.derive import derive_inputs
from bayesfric.datasets.errors import DataError, decode_position, decode_utf8, read_file, shorten
from bayesfric.datasets.sidecar import PROVENANCES, ROLES, read_sidecar
from bayesfric.limits import load_problem
from bayesfric.quantities import QUANTITIES, SCALE_RANGE, UnitError, conversion, rounding_slack

__all__ = ["DataError", "load_dataset", "PROVENANCES", "ROLES", "OBS_DIM", "SCALE_RANGE"]

OBS_DIM = "obs"

#: No fixed row limit: loading a file is bounded by the memory its text needs
#: (:func:`bayesfric.limits.load_problem`, checked from the file's size before it is read) and a
#: fit by the memory its draws need (:func:`bayesfric.limits.sampler_problem`, checked before
#: sampling; it names the setting to lower).

#: Longest cell (characters), the csv module's own default field limit: a longer cell is not a
#: measurement (a pasted log, a binary file); the error names its row and column.
MAX_CELL = 131_072


def load_dataset(csv_path: str | Path, meta_path: str | Path | None = None, *,
                 max_rows: int | None = None, response: bool = True) -> xr.Dataset:
    """Load ``csv_path`` with its TOML sidecar into an SI-unit :class:`xarray.Dataset`.

    Parameters
    ----------
    csv_path : str or Path
        The measurement table; first line is the header.
    meta_path : str or Path, optional
        The sidecar; default ``csv_path`` with suffix ``.toml``.
    max_rows : int, optional
        Most data rows read (default: no limit but the memory the file's text needs to load).
    response : bool
        Whether the sidecar must declare a response column; ``False`` reads a log without one
        (``attrs["response"]`` is then ``""``), which only predictions can use.

    Returns
    -------
    xarray.Dataset
        Dimension ``obs``; inputs as coordinates named by quantity; response as a data variable.

    Raises
    ------
    DataError
        Any broken rule of the module docstring (missing file or column, bad encoding, unknown
        or wrong-dimension unit, NaN/inf, empty file, non-numeric cell, out-of-bound value,
        too large to load, unordered trajectory, bad metadata), in one line.
    """
    csv_path = Path(csv_path)
    meta_path = Path(meta_path) if meta_path is not None else csv_path.with_suffix(".toml")
    meta = read_sidecar(meta_path, response=response)
    ds_meta, columns = meta["dataset"], meta["columns"]
    data = _read_bytes(csv_path)
    header, rows = _parse_table(csv_path, _decode(csv_path, meta_path, data, ds_meta.get("encoding")), max_rows)
    index = _column_index(csv_path, meta_path, header, columns)
    coords, data_vars = _variables(csv_path, meta_path, columns, {c: [r[i] for r in rows] for c, i in index.items()})
    response = next((c for c, s in columns.items() if s["role"] == "response"), None)
    _check_scales(csv_path, coords, data_vars)

    attrs = {
        "name": ds_meta.get("name", csv_path.stem),
        "title": ds_meta.get("title", ""),
        "provenance": ds_meta["provenance"],
        "source": ds_meta["source"],
        "description": ds_meta.get("description", ""),
        "response": columns[response]["quantity"] if response is not None else "",
        "data_hash": hashlib.sha256(data + meta_path.read_bytes()).hexdigest()[:16],
        "csv_file": str(csv_path),
    }
    if meta.get("reduction"):
        red = meta["reduction"]
        attrs["reduced_from"] = f"{red.get('source_file', '?')} (sha256 {str(red.get('source_sha256', '?'))[:16]})"
    if "trajectory" in ds_meta:
        _check_trajectories(csv_path, meta_path, columns, coords, ds_meta["trajectory"])
        attrs["trajectory"] = ds_meta["trajectory"]
    if meta.get("derive"):
        derived, attrs["derived"] = derive_inputs(meta_path, meta["derive"], coords, ds_meta.get("trajectory"))
        coords |= derived
    return xr.Dataset(data_vars=data_vars, coords=coords, attrs=attrs)


# -- reading and decoding ------------------------------------------------------------------------
def _read_bytes(path: Path) -> bytes:
    if not path.exists():
        raise DataError(f"{path}: file not found")
    if path.is_file() and (problem := load_problem(path, path.stat().st_size)):
        raise DataError(problem)
    return read_file(path, "CSV file")


def _decode(path: Path, meta_path: Path, data: bytes, encoding: str | None) -> str:
    """The CSV's text: UTF-8 (BOM or not) by default, else the sidecar's ``encoding``."""
    if encoding is None:
        try:
            return decode_utf8(data)
        except UnicodeDecodeError as exc:
            utf16 = data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))  # Excel's "Unicode text"
            example = "(it starts with a UTF-16 byte-order mark)" if utf16 else '(e.g. "latin-1" or "cp1252")'
            raise DataError(
                f"{path}: not UTF-8 at {decode_position(data, exc)}; if the file was written in another "
                f"encoding, add encoding = \"{'utf-16' if utf16 else '...'}\" {example} to [dataset] of "
                f"{meta_path.name}"
            ) from None
    if data.startswith(codecs.BOM_UTF8) and codecs.lookup(encoding).name not in ("utf-8", "utf-8-sig"):
        raise DataError(f"{path}: starts with a UTF-8 byte-order mark, but [dataset] encoding = {encoding!r} "
                        f"in {meta_path.name}; remove the encoding key")
    try:
        return data.decode(encoding).removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not valid {encoding!r} (the [dataset] encoding of {meta_path.name}) at "
                        f"{decode_position(data, exc)}") from None


def _parse_table(path: Path, text: str, max_rows: int | None = None) -> tuple[list[str], list[list[str]]]:
    """Header (cells stripped) and data rows; with ``max_rows``, stops reading at ``max_rows + 1`` rows.

    The csv module's field limit is lifted while reading (the text is in memory already) so that
    a cell longer than :data:`MAX_CELL` is reported with its row and column (:func:`_check_cells`).
    """
    lines = (line for line in io.StringIO(text, newline="") if not line.startswith("#"))
    header: list[str] | None = None
    rows: list[list[str]] = []
    limit = csv.field_size_limit(max(csv.field_size_limit(), len(text) + 1))
    try:
        for cells in csv.reader(lines):
            if not any(c.strip() for c in cells):
                continue
            _check_cells(path, header, cells, len(rows))
            if header is None:
                header = [c.strip() for c in cells]
            elif max_rows is not None and len(rows) == max_rows:
                raise DataError(f"{path}: more than {max_rows} data rows (the file has {_line_count(text)} lines)")
            elif len(cells) != len(header):
                raise DataError(f"{path}: row {len(rows) + 1}: has {len(cells)} cells, header has {len(header)}")
            else:
                rows.append(cells)
    except csv.Error as exc:
        where = "header" if header is None else f"row {len(rows) + 1}"
        raise DataError(f"{path}: {where}: unreadable CSV ({exc})") from None
    finally:
        csv.field_size_limit(limit)
    if header is None:
        raise DataError(f"{path}: file is empty")
    if not rows:
        raise DataError(f"{path}: file has a header but no data rows")
    return header, rows


def _check_cells(path: Path, header: list[str] | None, cells: list[str], done: int) -> None:
    """No cell longer than :data:`MAX_CELL`; the error names the row (``done`` rows read) and column."""
    for j, cell in enumerate(cells):
        if len(cell) > MAX_CELL:
            where = "header" if header is None else f"row {done + 1}"
            name = f" {shorten(header[j].strip(), 20)}" if header is not None and j < len(header) else ""
            raise DataError(f"{path}: {where}: column{name} (cell {j + 1} of the row): {len(cell)} characters, "
                            f"more than {MAX_CELL}; not a measurement table cell")


def _line_count(text: str) -> int:
    """Lines of ``text`` without building a list of them (LF, CRLF or old-Mac CR line ends)."""
    return (text.count("\n") or text.count("\r")) + (not text.endswith(("\n", "\r")))


def _column_index(path: Path, meta_path: Path, header: list[str], columns: dict) -> dict[str, int]:
    """Position of each sidecar column in the header; repeated header names are an error."""
    position: dict[str, int] = {}
    for i, name in enumerate(header):
        if not name:
            continue  # an unnamed column (e.g. an exported index) cannot be named in the sidecar
        if name in position:
            raise DataError(f"{path}: header: column {shorten(name)} appears twice (columns "
                            f"{position[name] + 1} and {i + 1} of the header); rename one")
        position[name] = i
    for col in columns:
        if col not in position:
            shown = ", ".join(shorten(h, 20) for h in header[:12]) + (", ..." if len(header) > 12 else "")
            empty = [str(i + 1) for i, h in enumerate(header) if not h]
            note = f"; header cell {', '.join(empty)} empty" if empty else ""
            raise DataError(f"{path}: column {col!r} named in {meta_path.name} is missing from the header "
                            f"(header: {shown}{note})")
    return {col: position[col] for col in columns}


# -- columns -------------------------------------------------------------------------------------
def _variables(path: Path, meta_path: Path, columns: dict, cells: dict[str, list[str]]) -> tuple[dict, dict]:
    """Coordinates and data variables of the dataset, one or two per sidecar column."""
    coords: dict[str, tuple] = {}
    data_vars: dict[str, tuple] = {}
    for col, spec in columns.items():
        role = spec["role"]
        if role == "group":
            attrs = {"role": "group", "column": col} | ({"units": str(spec["unit"])} if "unit" in spec else {})
            entries = [(col, coords, _group_values(path, col, cells[col]), attrs)]
        else:
            values, attrs = _numeric_column(path, meta_path, col, spec, cells[col])
            name = spec["quantity"] if role in ("input", "response") else col
            entries = [(name, coords if role == "input" else data_vars, values, attrs)]
            if role == "input" and spec.get("group"):
                entries.append((f"{col}_group", coords, values, {"role": "group", "column": col}))
        for name, target, values, attrs in entries:
            taken = coords.get(name) or data_vars.get(name)
            if taken is not None:
                raise DataError(f"{meta_path}: columns {taken[2]['column']!r} and {col!r} both become {name!r} in "
                                f"the data set (inputs and the response are named by quantity, others by column)")
            target[name] = (OBS_DIM, values, attrs)
    return coords, data_vars


def _numeric_column(path: Path, meta_path: Path, col: str, spec: dict, raw: list[str]) -> tuple[np.ndarray, dict]:
    """A numeric column converted to SI and checked against its quantity's physical bound."""
    unit = spec.get("unit", "1")
    numbers = _numbers(path, col, raw)
    attrs = {"role": spec["role"], "column": col, "original_unit": unit}
    quantity = spec.get("quantity")
    if quantity is None:
        return numbers, attrs | {"units": unit}
    q = QUANTITIES[quantity]
    try:
        scale, offset = conversion(unit, quantity)
    except UnitError as exc:
        raise DataError(f"{meta_path}: column {col!r}: {exc}") from None
    with np.errstate(over="ignore", invalid="ignore"):
        si = numbers * scale + offset
    bad = ~np.isfinite(si)
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(f"{path}: row {i + 1}: column {col!r}: {raw[i].strip()} {unit} overflows when converted to "
                        f"{q.unit}")
    bad = q.violations(si, rounding_slack(numbers, scale, offset))  # -459.67 degF is 0 K
    if spec["role"] == "se":
        bad = si < 0
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(f"{path}: row {i + 1}: column {col!r}: {raw[i].strip()} {unit}; a standard error must be "
                            f">= 0")
    if bad.any():
        i = int(np.argmax(bad))
        value = f"{raw[i].strip()} {unit}" + (f" is {si[i]:.6g} {q.unit}" if (scale, offset) != (1.0, 0.0) else "")
        raise DataError(f"{path}: row {i + 1}: column {col!r}: {value}; {quantity} must be {q.bound_text()}")
    return si, attrs | {"quantity": quantity, "units": q.unit}


def _numbers(path: Path, col: str, raw: list[str]) -> np.ndarray:
    out = np.empty(len(raw))
    for i, cell in enumerate(raw):
        text = cell.strip()
        try:
            value = float(text)
        except ValueError:
            raise DataError(f"{path}: row {i + 1}: column {col!r}: {shorten(text)} is not a number") from None
        if not np.isfinite(value):
            raise DataError(f"{path}: row {i + 1}: column {col!r}: non-finite value {shorten(text)}")
        out[i] = value
    return out


def _group_values(path: Path, col: str, raw: list[str]) -> np.ndarray:
    """Group labels: integers if every label is one (and fits int64), else strings; none empty."""
    stripped = [c.strip() for c in raw]
    if "" in stripped:
        raise DataError(f"{path}: row {stripped.index('') + 1}: column {col!r}: empty group label")
    try:
        return np.asarray([int(c) for c in stripped], dtype=np.int64)
    except (ValueError, OverflowError):
        return np.asarray(stripped, dtype=str)


# -- whole-column checks -------------------------------------------------------------------------
def _check_scales(path: Path, coords: dict, data_vars: dict) -> None:
    """Response not all zero; largest |value| of response and non-zero inputs in SCALE_RANGE."""
    low, high = SCALE_RANGE
    for _, values, attrs in list(coords.values()) + list(data_vars.values()):
        if attrs["role"] not in ("input", "response"):
            continue
        peak = float(np.max(np.abs(values)))
        if peak == 0.0 and attrs["role"] == "response":
            raise DataError(f"{path}: column {attrs['column']!r}: the response is zero in every row; nothing to fit")
        if peak != 0.0 and not low <= peak <= high:
            side = f"below {low:g}" if peak < low else f"above {high:g}"
            raise DataError(
                f"{path}: column {attrs['column']!r}: largest |value| is {peak:.3g} {attrs['units']}, {side} in SI, "
                f"too {'small' if peak < low else 'large'} for data-scaled priors ({attrs['role']}); check the unit"
            )


def _check_trajectories(path: Path, meta_path: Path, columns: dict, coords: dict, traj: str) -> None:
    """Each trajectory one contiguous block; with a time input, time strictly increasing within it."""
    if traj not in coords or coords[traj][2].get("role") != "group":
        role = columns.get(traj, {}).get("role")
        what = f"is not a group column (its role is {role!r})" if role else "names no column of the sidecar"
        raise DataError(f"{meta_path}: [dataset] trajectory = {traj!r} {what}")
    column = coords[traj][2]["column"]
    labels = coords[traj][1].tolist()
    first_row: dict = {}
    for i, label in enumerate(labels):
        if i and label == labels[i - 1]:
            continue
        if label in first_row:
            raise DataError(f"{path}: row {i + 1}: column {column!r}: trajectory {label!r} reappears after other "
                            f"trajectories (it began at row {first_row[label] + 1}); a trajectory's rows must be "
                            f"one contiguous block")
        first_row[label] = i
    if "time" not in coords:
        return  # the row order is the trajectory order; angles may go back and forth (hysteresis)
    time, attrs = coords["time"][1], coords["time"][2]
    same = np.asarray([a == b for a, b in zip(labels[1:], labels[:-1], strict=True)], dtype=bool)
    bad = np.flatnonzero(same & (time[1:] <= time[:-1]))
    if bad.size:
        i = int(bad[0]) + 1
        raise DataError(f"{path}: row {i + 1}: column {attrs['column']!r}: time {time[i]:g} s is not after "
                        f"{time[i - 1]:g} s of row {i} in trajectory {labels[i]!r}; time must strictly increase "
                        f"within a trajectory")
