"""The report's files as nodes of the result tree, and back (:mod:`bayesfric.report.results`).

A report is rendered from the tree only: the study run builds the tree, writes ``results.nc``
and renders every file from the tree it holds (:func:`bayesfric.report.summary.render_report`);
``bayesfric report results.nc --out FOLDER`` calls the same function on the saved tree, and a
test checks both give the same bytes (``tests/report/test_rerender.py``).

Tables. Every CSV file is one node over ``row`` (:func:`table_dataset`); each column keeps how its
cells were typed (attribute ``csv_kind``: ``bool``, ``int``, ``float`` or ``text``), so
:func:`table_records` gives back cells that :func:`bayesfric.csvout.write_csv` writes to the same
bytes; text cells that were not strings (rare: a NumPy scalar in a mixed column) are listed in
``csv_verbatim`` and written as they were, not neutralised twice; empty cells of a number column
(``None``, written as nothing) are listed in ``csv_empty`` and NaN in the tree. Numbers stay numbers.

Content. ``/report`` holds the report's content model (:class:`bayesfric.report.content.Report`:
the sections' texts, tables and findings, as built from the study's results) as JSON in its
``content`` attribute, and ``/report/figures`` the figure files (PNG bytes, ``path`` per figure).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from pathlib import Path

import h5netcdf
import numpy as np
import pandas as pd
import xarray as xr

from bayesfric.errors import InternalError, UserError
from bayesfric.report.blocks import FigureRef, Table
from bayesfric.report.findings import Finding, Summary
from bayesfric.report.sizing import Section

__all__ = ["CSV_FILES", "table_dataset", "table_records", "table_frame", "content_node", "figures_node", "read_content",
           "read_figures", "open_results", "stored_layout"]

#: Table node -> the CSV file it renders (scores.csv is written from a data frame, the others from records).
CSV_FILES = {"ranking": "ranking.csv", "parameters": "parameters.csv", "claims": "claims.csv",
             "sizing": "sizing.csv", "score_rows": "scores.csv"}
#: Version of the ``/report`` layout; a tree without it (or another) is not re-rendered.
LAYOUT = 1


class _Verbatim:
    """A CSV cell written as its text, untouched by :func:`bayesfric.csvout.neutralise` (it was not a string)."""

    __slots__ = ("text",)

    def __init__(self, text: str) -> None:
        self.text = text

    def __str__(self) -> str:
        return self.text


def _kind(cells: list) -> str:
    if all(isinstance(v, bool | np.bool_) for v in cells):
        return "bool"
    if all(isinstance(v, int | np.integer) and not isinstance(v, bool | np.bool_) for v in cells):
        return "int"
    if all(isinstance(v, float) for v in cells):  # float and np.float64: str() writes them alike
        return "float"
    return "text"


def table_dataset(records: list[dict] | pd.DataFrame, csv_file: str = "") -> xr.Dataset:
    """One report table (CSV records or a data frame) as a Dataset over ``row`` that
    :func:`table_records` turns back into the same cells; a column name NetCDF refuses (``/``)
    keeps its CSV name in ``csv_name``."""
    frame = records if isinstance(records, pd.DataFrame) else None
    rows = frame.to_dict("records") if frame is not None else list(records)
    header = list(frame.columns) if frame is not None else list(dict.fromkeys(k for r in rows for k in r))
    data = {}
    for column in header:
        cells = [r.get(column, "") for r in rows]
        empty = [i for i, v in enumerate(cells) if frame is None and (v is None or (isinstance(v, str) and not v))]
        gaps = set(empty)
        kind = _kind([v for i, v in enumerate(cells) if i not in gaps]) if len(empty) < len(cells) else "text"
        attrs = {"csv_kind": kind}
        if kind != "text" and empty:  # a number column with empty cells: NaN (or 0) in the tree, "" in the CSV
            attrs["csv_empty"] = json.dumps(empty)
            fill = {"bool": False, "int": 0, "float": math.nan}[kind]
            cells = [fill if i in gaps else v for i, v in enumerate(cells)]
        if kind == "text":
            verbatim = [i for i, v in enumerate(cells) if v is not None and not isinstance(v, str)]
            if verbatim:
                attrs["csv_verbatim"] = json.dumps(verbatim)
            values = np.array(["" if v is None else str(v) for v in cells], dtype=str)
        else:
            values = np.array(cells, dtype={"bool": bool, "int": np.int64, "float": float}[kind])
        name = str(column).replace("/", "\u2215")  # NetCDF names may not hold '/': DIVISION SLASH instead
        if name != column:
            attrs["csv_name"] = str(column)
        data[name] = xr.Variable("row", values, attrs=attrs)
    attrs = {"columns": json.dumps([str(c) for c in header]), "csv_file": csv_file,
             "csv_frame": int(frame is not None)}
    return xr.Dataset(data, coords={"row": np.arange(len(rows))}, attrs=attrs)


def _cells(var: xr.DataArray) -> list:
    kind = var.attrs.get("csv_kind", "text")
    cast = {"bool": bool, "int": int, "float": float}.get(kind)
    if cast is not None:
        cells: list = [cast(v) for v in var.values]
        for i in json.loads(var.attrs.get("csv_empty", "[]")):
            cells[i] = ""
        return cells
    cells = [str(v) for v in var.values]
    for i in json.loads(var.attrs.get("csv_verbatim", "[]")):
        cells[i] = _Verbatim(cells[i])
    return cells


def table_records(ds: xr.Dataset) -> list[dict] | pd.DataFrame:
    """The records (or data frame, ``csv_frame``) a table node was built from, cell for cell as
    CSV text."""
    header = json.loads(ds.attrs["columns"])
    columns = {c: _cells(ds[str(c).replace("/", "\u2215")]) for c in header}
    n = int(ds.sizes.get("row", 0))
    if int(ds.attrs.get("csv_frame", 0)):
        return pd.DataFrame({c: columns[c] for c in header}, columns=header)
    return [{c: columns[c][i] for c in header} for i in range(n)]


def table_frame(ds: xr.Dataset) -> pd.DataFrame:
    """A table node as a typed data frame, as pandas reads its CSV file: numbers and booleans as
    such, an empty cell NaN (a number column with one becomes float, a boolean one object)."""
    header = json.loads(ds.attrs["columns"])
    columns = {}
    for c in header:
        var = ds[str(c).replace("/", "\u2215")]
        if var.attrs.get("csv_kind", "text") == "text":  # the dtype pandas infers, as read_csv does
            column = pd.Series([np.nan if str(v) == "" else str(v) for v in var.values])
        else:
            column = pd.Series(var.values)
            if empty := json.loads(var.attrs.get("csv_empty", "[]")):
                column = column.astype(object if var.dtype == bool else float)
                column.iloc[empty] = np.nan
        columns[c] = column
    return pd.DataFrame(columns, columns=header)


def _finding(d: Mapping) -> Finding:
    return Finding(tuple((str(t), bool(b)) for t, b in d["parts"]), bool(d["warning"]))


def _table(d: Mapping | None) -> Table | None:
    return None if d is None else Table(d["caption"], list(d["header"]), [list(r) for r in d["rows"]], list(d["warn"]))


def _figure(d: Mapping | None) -> FigureRef | None:
    return None if d is None else FigureRef(**d)


def _from_json(d: dict):
    """The content model from its JSON form (the inverse of :func:`dataclasses.asdict`)."""
    from bayesfric.report.content import LawSection, Report

    s = d["summary"]
    fields = dict(d)
    fields.update(
        summary=Summary(s["question"], [_finding(f) for f in s["answers"]],
                        _finding(s["recommendation"]) if s["recommendation"] else None,
                        [_finding(f) for f in s["warnings"]]),
        findings=[_finding(f) for f in d["findings"]], claims=_table(d["claims"]), ranking=_table(d["ranking"]),
        extrapolation=_table(d["extrapolation"]), checks=_table(d["checks"]), structure=_table(d.get("structure")),
        identifiability=_table(d.get("identifiability")),
        laws=[LawSection(**{**w, "table": _table(w["table"]), "figure": _figure(w["figure"])}) for w in d["laws"]],
        sizing=[Section(x["title"], list(x["lines"]), list(x["warnings"]),
                        [(c, list(h), [list(r) for r in rows]) for c, h, rows in x["tables"]], x["figure"],
                        x.get("caption", ""))
                for x in d["sizing"]],
        figures={k: [_figure(f) for f in v] for k, v in d["figures"].items()},
        sections=[(k, h) for k, h in d["sections"]],
    )
    return Report(**fields)


def _plain(value):
    """JSON has no NaN or NumPy scalars: a content model holds strings, flags and lists only."""
    if isinstance(value, float) and not math.isfinite(value):
        raise InternalError(f"report content holds a non-finite number {value!r}: it must be text")
    return value


def content_node(content) -> xr.Dataset:
    """The content model as ``/report`` (JSON in the ``content`` attribute)."""
    text = json.dumps(dataclasses.asdict(content), ensure_ascii=False, allow_nan=False, default=_plain)
    return xr.Dataset(attrs={"content": text, "layout": LAYOUT})


def read_content(node: xr.Dataset):
    """The content model stored by :func:`content_node`."""
    return _from_json(json.loads(node.attrs["content"]))


def figures_node(folder: Path) -> xr.Dataset:
    """Every file under ``folder/figures`` as ``/report/figures``: ``path`` over ``figure``, the
    bytes one after another in ``data`` over ``byte`` (``start``, ``size`` per figure)."""
    files = sorted((folder / "figures").glob("*")) if (folder / "figures").is_dir() else []
    blobs = [p.read_bytes() for p in files]
    sizes = np.array([len(b) for b in blobs], dtype=np.int64)
    return xr.Dataset({"path": ("figure", np.array([f"figures/{p.name}" for p in files], dtype=str)),
                       "start": ("figure", np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)),
                       "size": ("figure", sizes),
                       "data": ("byte", np.frombuffer(b"".join(blobs), dtype=np.uint8))})


def read_figures(node: xr.Dataset) -> dict[str, bytes]:
    """Figure path (relative to the report folder) -> its bytes, from :func:`figures_node`."""
    data = node["data"].values.tobytes()
    return {str(p): data[int(s):int(s) + int(n)]
            for p, s, n in zip(node["path"].values, node["start"].values, node["size"].values, strict=True)}


def stored_layout(tree: xr.DataTree) -> str | None:
    """The layout of the report a result tree stores (``/report``), None without one."""
    return tree["report"].attrs.get("layout") if "report" in tree.children else None


def open_results(path: str | Path) -> xr.DataTree:
    """Open the nodes of a study's ``results.nc`` that the report renders from (root, ``/report``,
    ``/report/figures`` and the CSV tables; not the fits), loaded: the file is closed on return.

    Raises
    ------
    UserError
        The file is missing, is not a NetCDF/HDF5 file, or is not a bayesfric result tree with a
        stored report (``/report`` of this layout).
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such file (a study's results.nc)")
    try:
        with h5netcdf.File(path, "r") as fh:  # the groups' names and attributes, without opening the fits
            groups = fh.groups
            layout = groups["report"].attrs.get("layout") if "report" in groups else None
            keep = [n for n in groups if "csv_file" in groups[n].attrs]
        if layout != LAYOUT:
            raise UserError(f"{path}: not a bayesfric result tree with a stored report (no /report group of "
                            f"layout {LAYOUT}; rerun the study with this version)")
        nodes = {}
        for name in ("/", "report", "report/figures", *keep):
            with xr.open_dataset(path, group=name, engine="h5netcdf") as ds:
                nodes[name] = ds.load()
        return xr.DataTree.from_dict(nodes)
    except UserError:
        raise
    except (OSError, ValueError, KeyError) as exc:
        raise UserError(f"{path}: not a readable result tree ({type(exc).__name__}: "
                        f"{' '.join(str(exc).split())[:200]})") from None
