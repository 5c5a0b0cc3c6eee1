"""A study's results as one ``xarray.DataTree``, saved as ``results.nc`` beside the report.

The tree holds what the study computed, in numbers a notebook can use without parsing a CSV
file (``xarray.open_datatree("reports/<study>/results.nc")``):

``/``
    attrs: study, data set, data hash, bayesfric version, run seconds, CV schemes.
``/scores``
    over ``(law, criterion)``: ``estimate``, ``se``, ``reliable``, ``reason``; a criterion is a
    metric and its scheme (``elpd_loo``, ``elpd_cv[<scheme>]``, ``penalty[<scheme>]``,
    ``log_evidence[<estimator>]``, ``weight[<weighting>]``), with ``metric`` and ``scheme``
    coordinates (the rows of ``scores.csv``).
``/pointwise``
    ``elpd`` over ``(criterion, law, obs)``: PSIS-LOO and each CV scheme's pointwise elpd (NaN
    where a point is not held out or the stage did not run); ``heldout`` over ``(scheme, obs)``.
``/weights``
    over ``(law, weighting)``: ``weight`` and ``excluded`` (why the weighting left the law out).
``/diagnostics``, ``/checks``
    over ``law``: the gate's verdict and problems; the checks unit's LOO-PIT and prior checks.
``/ranking``, ``/parameters``, ``/claims``, ``/sizing``
    the report's tables over ``row`` (the rows of ``ranking.csv``, ``parameters.csv``,
    ``claims.csv``, ``sizing.csv``); a variable's ``csv_name`` attribute is its column's name
    where NetCDF does not allow it (``/`` in a unit).
``/fits/<law>``
    each law's posterior, sample statistics and observed data; the pointwise log-likelihood and
    predictive draws stay in the full fit, ``fits/<law>.nc`` (attribute ``fit_file``).

This is the first step of issue 31's one result tree: the tree is built from the study's
in-memory outcome and written with the report; the report itself is still rendered from that
outcome, not yet re-rendered from the tree.
"""

from __future__ import annotations

import math
import os
import secrets
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
import xarray as xr

from bayesfric._version import __version__

if TYPE_CHECKING:
    from bayesfric.study.outcome import StudyOutcome

__all__ = ["RESULTS", "result_tree", "write_results", "table_dataset"]

#: The file name of the saved tree in a report folder.
RESULTS = "results.nc"
#: Groups of a fit copied into ``/fits/<law>`` (the per-row groups stay in the fit file).
FIT_GROUPS = ("posterior", "sample_stats", "observed_data", "constant_data")


def _criterion(metric: str, scheme: str) -> str:
    return metric if not scheme else f"{metric}[{scheme}]"


def _scores(outcome: StudyOutcome) -> xr.Dataset:
    table = outcome.table
    laws = [w.name for w in outcome.laws]
    crit = list(dict.fromkeys(_criterion(m, s) for m, s in zip(table["metric"], table["scheme"], strict=True)))
    meta = {_criterion(m, s): (m, s) for m, s in zip(table["metric"], table["scheme"], strict=True)}
    shape = (len(laws), len(crit))
    est, se = np.full(shape, np.nan), np.full(shape, np.nan)
    reliable = np.zeros(shape, dtype=bool)
    reason = np.full(shape, "", dtype=object)
    li, ci = {n: i for i, n in enumerate(laws)}, {c: j for j, c in enumerate(crit)}
    for row in table.itertuples(index=False):
        i, j = li[row.law], ci[_criterion(row.metric, row.scheme)]
        est[i, j], se[i, j] = row.estimate, row.se
        reliable[i, j], reason[i, j] = bool(row.reliable), str(row.reason)
    dims = ("law", "criterion")
    return xr.Dataset(
        {"estimate": (dims, est), "se": (dims, se), "reliable": (dims, reliable), "reason": (dims, reason.astype(str))},
        coords={"law": laws, "criterion": crit, "metric": ("criterion", [meta[c][0] for c in crit]),
                "scheme": ("criterion", [meta[c][1] for c in crit])},
    )


def _pointwise(outcome: StudyOutcome) -> xr.Dataset:
    n = int(outcome.data.sizes["obs"])
    laws = [w.name for w in outcome.laws]
    crit = ["elpd_loo"] + [_criterion("elpd_cv", s) for s in outcome.schemes]
    elpd = np.full((len(crit), len(laws), n), np.nan)
    for i, w in enumerate(outcome.laws):
        if w.loo is not None:
            elpd[0, i] = np.asarray(w.loo.elpd_i, dtype=float)
        for j, scheme in enumerate(outcome.schemes, start=1):
            cv = w.cv.get(scheme)
            if cv is not None:
                elpd[j, i] = np.asarray(cv.elpd_i, dtype=float)
    schemes = list(outcome.heldout)
    heldout = np.array([np.asarray(outcome.heldout[s], dtype=bool) for s in schemes]).reshape(len(schemes), n)
    return xr.Dataset({"elpd": (("criterion", "law", "obs"), elpd), "heldout": (("scheme", "obs"), heldout)},
                      coords={"criterion": crit, "law": laws, "scheme": schemes, "obs": np.arange(n)})


def _weights(outcome: StudyOutcome) -> xr.Dataset:
    laws = [w.name for w in outcome.laws]
    names = list(dict.fromkeys(k for w in outcome.laws for k in w.weights))
    value = np.full((len(laws), len(names)), np.nan)
    excluded = np.full((len(laws), len(names)), "", dtype=object)
    for i, w in enumerate(outcome.laws):
        for j, k in enumerate(names):
            if k in w.weights:
                value[i, j], excluded[i, j] = w.weights[k].value, w.weights[k].excluded
    dims = ("law", "weighting")
    return xr.Dataset({"weight": (dims, value), "excluded": (dims, excluded.astype(str))},
                      coords={"law": laws, "weighting": names})


def _per_law(outcome: StudyOutcome) -> tuple[xr.Dataset, xr.Dataset]:
    laws = [w.name for w in outcome.laws]
    diag = xr.Dataset({
        "passed": ("law", [bool(w.verdict.passed) for w in outcome.laws]),
        "problems": ("law", ["; ".join(w.verdict.problems) for w in outcome.laws]),
        "evidence_agree": ("law", [bool(w.evidence_agree) for w in outcome.laws]),
        "skipped": ("law", [", ".join(w.skipped) for w in outcome.laws]),
        "seconds": ("law", [float(w.seconds) for w in outcome.laws]),
    }, coords={"law": laws})
    checks = [w.checks for w in outcome.laws]
    nan = math.nan
    chk = xr.Dataset({
        "prior_implausible": ("law", [c.prior_implausible if c else nan for c in checks]),
        "loo_pit_pvalue": ("law", [c.loo_pit_pvalue if c else nan for c in checks]),
        "loo_pit_ok": ("law", [bool(c.loo_pit_ok) if c else True for c in checks]),
        "loo_pit_direction": ("law", [c.pit_shape.label if c and c.pit_shape is not None else "" for c in checks]),
        "psense": ("law", [", ".join(c.psense) if c else "" for c in checks]),
    }, coords={"law": laws})
    return diag, chk


def table_dataset(records: list[dict] | pd.DataFrame) -> xr.Dataset:
    """One report table (a list of CSV records) as a Dataset over ``row``: numbers as float,
    flags as bool, the rest as text; a column name NetCDF refuses keeps it in ``csv_name``."""
    frame = pd.DataFrame(records).reset_index(drop=True)
    data = {}
    for column in frame.columns:
        values = frame[column]
        kind = pd.api.types.infer_dtype(values, skipna=True)
        if kind == "boolean":
            arr = values.fillna(False).astype(bool).to_numpy()
        elif kind in ("floating", "integer", "mixed-integer-float"):
            arr = pd.to_numeric(values, errors="coerce").astype(float).to_numpy()
        else:
            arr = values.map(lambda v: "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v))
            arr = arr.to_numpy().astype(str)
        name = str(column).replace("/", "\u2215")  # NetCDF names may not hold '/': DIVISION SLASH instead
        data[name] = xr.Variable("row", arr, attrs={"csv_name": str(column)} if name != column else {})
    return xr.Dataset(data, coords={"row": np.arange(len(frame))})


def _fits(outcome: StudyOutcome) -> dict[str, xr.Dataset]:
    nodes = {}
    for w in outcome.laws:
        for group in FIT_GROUPS:
            if group in w.fit.children:
                ds = w.fit[group].to_dataset()
                nodes[f"fits/{w.name}/{group}"] = ds
        nodes.setdefault(f"fits/{w.name}", xr.Dataset())
    return nodes


def result_tree(outcome: StudyOutcome, tables: dict[str, list[dict] | pd.DataFrame]) -> xr.DataTree:
    """The study's results as one DataTree (layout in the module docstring).

    ``tables`` are the report's tables by node name (``ranking``, ``parameters``, ``claims``,
    ``sizing``) as the report writes them, so the tree and the CSV files hold the same rows.
    """
    diag, checks = _per_law(outcome)
    nodes: dict[str, xr.Dataset] = {"/": xr.Dataset(attrs=_root_attrs(outcome)), "scores": _scores(outcome),
                                    "pointwise": _pointwise(outcome), "weights": _weights(outcome),
                                    "diagnostics": diag, "checks": checks}
    nodes.update({name: table_dataset(rows) for name, rows in tables.items() if len(rows)})
    nodes.update(_fits(outcome))
    tree = xr.DataTree.from_dict(nodes)
    for w in outcome.laws:
        tree[f"fits/{w.name}"].attrs.update({k: v for k, v in w.fit.attrs.items() if _attr_ok(v)}
                                            | {"fit_file": f"fits/{w.fit_file.name}"})
    return tree


def _attr_ok(value) -> bool:
    return isinstance(value, str | int | float | np.number) and not isinstance(value, bool)


def _root_attrs(outcome: StudyOutcome) -> dict:
    return {"study": outcome.study.name, "dataset": str(outcome.data.attrs.get("name", "")),
            "data_hash": str(outcome.data.attrs.get("data_hash", "")), "bayesfric_version": __version__,
            "seconds": float(outcome.seconds), "schemes": "; ".join(outcome.schemes),
            "blocked_schemes": "; ".join(outcome.blocked), "quick": int("quick" in outcome.extra)}


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
