"""Writing a reduced log (:mod:`bayesfric.datasets.reduce`) as a data file the loader reads.

One CSV row per kept segment -- the inputs' means (``time`` left out) and group labels under the
source's column names and units, the response mean, ``<response>_se`` (role ``se``), ``count``,
``n_eff``, ``segment``, ``first_row``/``last_row`` -- and its TOML sidecar with a ``[reduction]``
table (source file, SHA-256 of it and of its sidecar, every setting). Each file is written through
a hidden temporary file in its folder and renamed into place; the CSV through
:func:`bayesfric.csvout.write_csv`, the only CSV writer.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from bayesfric.csvout import write_csv
from bayesfric.datasets.errors import DataError
from bayesfric.datasets.sidecar import read_sidecar
from bayesfric.quantities import conversion

if TYPE_CHECKING:
    import xarray as xr

# Segment and Reduction are what this module writes; bayesfric.datasets.reduce makes and re-exports them.
__all__ = ["write_reduction", "Segment", "Reduction"]


@dataclass(frozen=True)
class Segment:
    """One kept segment: source rows ``first:stop`` (0-based) and the response statistics."""

    first: int
    stop: int
    mean: float
    se: float
    n_eff: float


@dataclass
class Reduction:
    """A reduced log: the source data set, the kept segments and what the sidecar records."""

    source: xr.Dataset
    on: str
    segments: list[Segment]
    record: dict[str, object] = field(default_factory=dict)

def write_reduction(red: Reduction, out: str | Path, source_meta: str | Path | None = None) -> tuple[Path, Path]:
    """Write the reduced CSV and its sidecar (``out`` with suffix ``.toml``), each atomically.

    Parameters
    ----------
    red : Reduction
        From :func:`bayesfric.datasets.reduce.reduce_log`.
    out : str or Path
        The reduced CSV.
    source_meta : str or Path, optional
        The source's sidecar (default: its CSV with suffix ``.toml``), read for column names and units.
    """
    src = Path(red.source.attrs["csv_file"])
    meta_path = Path(source_meta) if source_meta is not None else src.with_suffix(".toml")
    header, rows, columns = _table(red, read_sidecar(meta_path)["columns"])
    record = dict(source_file=src.name, source_sha256=_sha256(src), sidecar_sha256=_sha256(meta_path),
                  **red.record, bayesfric=_version())
    out = Path(out)
    sidecar = out.with_suffix(".toml")
    _atomic(out, lambda tmp: write_csv(tmp, rows, header))
    _atomic(sidecar, lambda tmp: tmp.write_text(_sidecar_text(red.source.attrs, record, columns), encoding="utf-8"))
    return out, sidecar


def _table(red: Reduction, source_columns: dict) -> tuple[list[str], list[list[object]], dict[str, dict]]:
    """Header, rows (source units) and sidecar column specs of the reduced table."""
    ds, segs = red.source, red.segments
    names, values, columns = [], [], {}
    for name, var in ds.coords.items():
        role, col = var.attrs.get("role"), var.attrs.get("column", name)
        if role == "input" and name != "time":
            scale, offset = conversion(var.attrs["original_unit"], str(name))
            means = [(float(var.values[s.first:s.stop].mean()) - offset) / scale for s in segs]
            spec = {k: v for k, v in source_columns[col].items() if k in ("role", "quantity", "unit", "group")}
        elif role == "group" and str(name) == col:
            means, spec = [var.values[s.first].item() for s in segs], {"role": "group"}
        else:
            continue
        names.append(col)
        values.append(means)
        columns[col] = spec
    resp = ds[ds.attrs["response"]]
    col, unit = resp.attrs["column"], resp.attrs["original_unit"]
    scale, offset = conversion(unit, ds.attrs["response"])
    kind = {"quantity": ds.attrs["response"], "unit": unit}
    extra = {col: ([(s.mean - offset) / scale for s in segs], {"role": "response"} | kind),
             f"{col}_se": ([s.se / scale for s in segs], {"role": "se"} | kind),
             "count": ([s.stop - s.first for s in segs], {"role": "aux"}),
             "n_eff": ([round(s.n_eff, 3) for s in segs], {"role": "aux"}),
             "segment": (list(range(1, len(segs) + 1)), {"role": "group"}),
             "first_row": ([s.first + 1 for s in segs], {"role": "aux"}),
             "last_row": ([s.stop for s in segs], {"role": "aux"})}
    for name, (column, spec) in extra.items():
        if name in columns:
            raise DataError(f"{ds.attrs['csv_file']}: column {name!r}: the reduced table writes a column of that "
                            f"name; rename the source column")
        names.append(name)
        values.append(column)
        columns[name] = spec
    return names, [list(row) for row in zip(*values, strict=True)], columns


def _sidecar_text(attrs: dict, record: dict, columns: dict[str, dict]) -> str:
    """The reduced table's TOML sidecar (strings JSON-escaped: a valid TOML basic string)."""
    def value(v: object) -> str:
        return ("true" if v else "false") if isinstance(v, bool) else json.dumps(v, ensure_ascii=False)

    what = f"steady-state reduction of {record['source_file']} (sha256 {str(record['source_sha256'])[:16]})"
    dataset = {"name": f"{attrs.get('name', 'data')}_reduced",
               "title": f"{attrs.get('title') or attrs.get('name', '')} -- {what}",
               "provenance": attrs["provenance"],
               "source": f"{attrs['source']}; {what} by bayesfric data reduce",
               "description": (f"Means of {record['segments']} segments of constant {record['on']} "
                               f"(bayesfric.datasets.reduce), each with its standard error "
                               f"({record['se_method']}) and the count of rows averaged. "
                               f"{attrs.get('description', '')}").strip()}
    lines = ["# written by bayesfric data reduce (bayesfric.datasets.reduce); fit it like any data file", "",
             "[dataset]", *(f"{k} = {value(v)}" for k, v in dataset.items()), "", "[reduction]",
             *(f"{k} = {value(v)}" for k, v in record.items())]
    for col, spec in columns.items():
        lines += ["", f"[columns.{value(col)}]", *(f"{k} = {value(v)}" for k, v in spec.items())]
    return "\n".join(lines) + "\n"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("bayesfric")
    except PackageNotFoundError:
        return "unknown"


def _atomic(path: Path, write: Callable[[Path], object]) -> None:
    """Write ``path`` through a hidden temporary file in its folder, then rename it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # mode: 0o666 less umask
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
