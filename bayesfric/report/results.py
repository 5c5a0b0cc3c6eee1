"""A study's results as one ``xarray.DataTree``, saved as ``results.nc`` beside the report.

The study run builds its result tree once (:func:`bayesfric.study.tree.study_tree`: root attrs,
``/scores``, ``/pointwise``, ``/weights``, ``/diagnostics``, ``/checks``, ``/sizing_basis``,
``/fits/<law>``); sizing and the claims read it. :func:`result_tree` adds what the report is
rendered from, so a notebook can use the numbers without parsing a CSV file
(``xarray.open_datatree("reports/<study>/results.nc")``):

``/`` attrs
    ``seconds``: the run's wall time, and what its units cost (put there by the runner,
    :func:`bayesfric.study.tree.run_attrs`).
``/ranking``, ``/parameters``, ``/claims``, ``/sizing``, ``/score_rows``
    the report's CSV tables over ``row`` (the rows of ``ranking.csv``, ``parameters.csv``,
    ``claims.csv``, ``sizing.csv``, ``scores.csv``; attribute ``csv_file``), each column typed so
    that the CSV file is written again to the same bytes (:mod:`bayesfric.report.stored`); a
    variable's ``csv_name`` attribute is its column's name where NetCDF does not allow it (``/``).
``/report``, ``/report/figures``
    the report's content model (section texts, tables, findings, as JSON in ``content``) and its
    figure files (PNG bytes).

The report is rendered from this tree alone: the study run writes ``results.nc`` and renders
every report file from the tree it holds (:func:`bayesfric.report.summary.render_report`), the
function ``bayesfric report results.nc --out FOLDER`` calls on the saved tree; a test checks that
both give the same bytes. The content model and the figures are made from the study's tree (its
texts, tables, findings and figures read the tree's nodes, :mod:`bayesfric.report.content`,
:mod:`bayesfric.report.study_figures`), with the data set, the full fits (the bands' predictive
draws, which the tree does not keep), the claims' results and the sizing result passed as objects.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path

import pandas as pd
import xarray as xr

from bayesfric.report.stored import CSV_FILES, table_dataset

__all__ = ["RESULTS", "result_tree", "write_results", "table_dataset"]

#: The file name of the saved tree in a report folder.
RESULTS = "results.nc"


def result_tree(core: xr.DataTree, tables: dict[str, list[dict] | pd.DataFrame],
                extra: dict[str, xr.Dataset] | None = None) -> xr.DataTree:
    """The study's result tree ``core`` (:func:`bayesfric.study.tree.study_tree`, with the run's
    :func:`~bayesfric.study.tree.run_attrs`) with the report's nodes added (layout in the module
    docstring); ``core`` itself is left as it is.

    ``tables`` are the report's CSV tables by node name (:data:`bayesfric.report.stored.CSV_FILES`:
    ``ranking``, ``parameters``, ``claims``, ``sizing``, ``score_rows``) as records or a data frame,
    so the tree and the CSV files hold the same rows; ``extra`` adds nodes by path (the report's
    content and figures, :mod:`bayesfric.report.stored`).
    """
    tree = core.copy(deep=False)
    for name, rows in tables.items():
        tree[name] = xr.DataTree(table_dataset(rows, CSV_FILES[name]))
    for path, node in (extra or {}).items():
        tree[path] = xr.DataTree(node)
    return tree


def write_results(tree: xr.DataTree, folder: Path) -> Path:
    """Save ``tree`` as ``folder/results.nc`` atomically (a temporary file, then a rename)."""
    path = Path(folder) / RESULTS
    tmp = path.parent / f".{RESULTS}.{secrets.token_hex(4)}.tmp"
    try:
        tree.to_netcdf(tmp, engine="h5netcdf")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
