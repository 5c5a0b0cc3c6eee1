"""The one law × metric table of a study: every score with its standard error, whether it may be
ranked, and why not.

A study's comparison is a loop over scorers (PSIS-LOO, each cross-validation scheme, the
extrapolation penalty of each blocked scheme, each log-evidence estimator, each weighting); each
scorer adds rows to one tidy table (:func:`score_table`), with columns

``law, metric, scheme, estimate, se, reliable, reason``

- ``metric``: one of :data:`METRICS` (``elpd_loo``, ``elpd_cv``, ``penalty``, ``log_evidence``,
  ``weight``);
- ``scheme``: the CV scheme label, the evidence estimator or the weighting; ``""`` for LOO;
- ``reliable``: the row may be ranked under this study's rules (a fit that failed the
  diagnostics gate is ranked only when the study sets ``include_failed``); ``reason`` says why a
  row is not reliable, or what was overridden.

The winner per metric (:func:`best`), the laws that scored higher but may not be ranked
(:func:`passed_over`), the ranking order (:func:`ranking_order`), ``ranking.csv``,
``scores.csv``, ``summary.md`` and ``report.html`` all read this table: no verdict is written as
text and searched back.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from bayesfric.study.metrics import METRICS, Criterion

if TYPE_CHECKING:
    from collections.abc import Sequence

    import xarray as xr

    from bayesfric.study.spec import Study

__all__ = ["METRICS", "COLUMNS", "Criterion", "score_table", "best", "passed_over", "ranking_order", "criteria",
           "value", "fold_failure", "table_of", "criteria_of"]

COLUMNS = ["law", "metric", "scheme", "estimate", "se", "reliable", "reason"]


def _gate(w: xr.Dataset, include_failed: bool) -> tuple[bool, str]:
    if bool(w["passed"]):
        return True, ""
    if include_failed:
        return True, "fit failed the diagnostics gate; ranked because the study sets include_failed"
    return False, "fit failed the diagnostics gate"


def _name(w: xr.Dataset) -> str:
    return str(w.attrs["law"])


def _loo_rows(w: xr.Dataset, gate) -> list[tuple]:
    if not bool(w["loo_computed"]) or not math.isfinite(float(w["elpd_loo"])):
        return []
    ok, why = gate
    if ok and not bool(w["loo_reliable"]):
        ok, why = False, f"high Pareto k not resolved ({w['loo_handling'].item()})"
    return [(_name(w), "elpd_loo", "", float(w["elpd_loo"]), float(w["elpd_loo_se"]), ok, why)]


def fold_failure(cv) -> str:
    """Why a cross-validation result may not be ranked: which folds failed the gate and the first
    problem of each (:attr:`bayesfric.compare.CVResult.failure`); ``""`` when every fold passed."""
    return cv.failure


def _cv_rows(w: xr.Dataset, gate, blocked: list[str]) -> list[tuple]:
    rows = []
    for label in map(str, w["scheme"].values):
        at = w.sel(scheme=label)
        ok, why = gate
        if ok and not bool(at["cv_ok"]):
            ok, why = False, str(at["cv_failure"].values)  # fold_failure of the scheme's result
        rows.append((_name(w), "elpd_cv", label, float(at["cv_elpd"]), float(at["cv_se"]), ok, why))
        if label in blocked and bool(at["penalty_computed"]):
            # The penalty is a mean of paired pointwise differences (LOO minus blocked, the same
            # held-out points): its standard error is that of the differences' mean
            # (bayesfric.compare.Penalty), NaN when it was not computed.
            rows.append((_name(w), "penalty", label, float(at["penalty"]), float(at["penalty_se"]), ok, why))
    return rows


def _evidence_rows(w: xr.Dataset, gate) -> list[tuple]:
    rows = []
    for estimator in map(str, w["estimator"].values):
        at = w.sel(estimator=estimator)
        ok, why = gate
        if ok and not bool(w["evidence_agree"]):
            ok, why = False, (f"evidence estimators disagree by {abs(float(w['evidence_difference'])):.2f} nat: "
                              "left out of the evidence ranking")
        rows.append((_name(w), "log_evidence", estimator, float(at["log_z"]), float(at["log_z_error"]), ok, why))
    return rows


def _weight_rows(w: xr.Dataset) -> list[tuple]:
    return [(_name(w), "weight", str(method), float(value), math.nan, not str(excluded), str(excluded))
            for method, value, excluded in zip(w["weighting"].values, w["weight"].values,
                                               w["weight_excluded"].values, strict=True)]


def score_table(laws: Sequence[xr.Dataset], blocked: Sequence[str], include_failed: bool = False) -> pd.DataFrame:
    """The tidy law × metric table of a study's law results.

    Parameters
    ----------
    laws : sequence of xarray.Dataset
        Each law's results after its weights (:func:`bayesfric.study.lawresult.law_result`), in
        the study's order.
    blocked : sequence of str
        The study's blocked-extrapolation scheme labels (their penalties are scored).
    include_failed : bool
        The study ranks fits that failed the diagnostics gate (``[compare] include_failed``).

    Returns
    -------
    pandas.DataFrame
        Columns :data:`COLUMNS`, one row per law, metric and scheme that was computed.
    """
    rows: list[tuple] = []
    for w in laws:
        gate = _gate(w, include_failed)
        rows += _loo_rows(w, gate) + _cv_rows(w, gate, list(blocked)) + _evidence_rows(w, gate)
        rows += _weight_rows(w)
    table = pd.DataFrame(rows, columns=COLUMNS)
    return table.astype({"estimate": float, "se": float, "reliable": bool})


def table_of(node: xr.Dataset) -> pd.DataFrame:
    """The tidy table (:data:`COLUMNS`) back from a result tree's ``/scores`` node
    (:mod:`bayesfric.study.tree`): one row per law and criterion the study scored, laws in the
    node's order within each criterion (what :func:`value`, :func:`best` and :func:`passed_over`
    read; ``scores.csv`` keeps the scorers' own row order)."""
    flat = node.stack(row=("law", "criterion"))
    flat = flat.isel(row=np.flatnonzero(flat["computed"].values))
    table = pd.DataFrame({
        "law": flat["law"].values.astype(str), "metric": flat["metric"].values.astype(str),
        "scheme": flat["scheme"].values.astype(str), "estimate": flat["estimate"].values.astype(float),
        "se": flat["se"].values.astype(float), "reliable": flat["reliable"].values.astype(bool),
        "reason": flat["reason"].values.astype(str)})
    return table[COLUMNS]


def _select(table: pd.DataFrame, metric: str, scheme: str) -> pd.DataFrame:
    rows = table[(table["metric"] == metric) & (table["scheme"] == scheme)]
    return rows[np.isfinite(rows["estimate"].to_numpy(dtype=float))]


def value(table: pd.DataFrame, law: str, metric: str, scheme: str = "") -> pd.Series | None:
    """The row of ``law`` under ``metric`` and ``scheme``, or None when it was not computed."""
    rows = _select(table, metric, scheme)
    rows = rows[rows["law"] == law]
    return None if rows.empty else rows.iloc[0]


def best(table: pd.DataFrame, metric: str, scheme: str = "", counted: bool = False) -> str | None:
    """The best reliable law under ``metric`` and ``scheme`` (lowest penalty, highest otherwise);
    ``counted``: the best of every scored law, reliable or not (who would win if the laws that
    may not be ranked were counted)."""
    rows = _select(table, metric, scheme)
    rows = rows if counted else rows[rows["reliable"]]
    if rows.empty:
        return None
    higher = METRICS[metric][1]
    return str(rows.loc[rows["estimate"].idxmax() if higher else rows["estimate"].idxmin(), "law"])


def passed_over(table: pd.DataFrame, metric: str, scheme: str = "") -> list[str]:
    """Laws that score better than :func:`best` under ``metric`` but may not be ranked."""
    winner = best(table, metric, scheme)
    if winner is None:
        return []
    rows = _select(table, metric, scheme)
    top = float(rows.loc[rows["law"] == winner, "estimate"].iloc[0])
    better = rows["estimate"] > top if METRICS[metric][1] else rows["estimate"] < top
    return [str(x) for x in rows.loc[better & ~rows["reliable"], "law"]]


def ranking_order(table: pd.DataFrame, laws: list[str], criterion: Criterion | None) -> list[str]:
    """``laws`` ordered by ``criterion``, best first, then the laws it did not score.

    A law whose row may not be ranked (a fold failed the gate, ...) keeps the place its score
    gives it: a failure never moves a law silently; the report marks it there with the reason
    (:mod:`bayesfric.report.ranking`) and numbers only the ranked laws.
    """
    if criterion is None:
        return list(laws)
    rows = _select(table, criterion.metric, criterion.scheme).set_index("law")
    sign = -1.0 if METRICS[criterion.metric][1] else 1.0

    def key(name: str) -> tuple:
        if name not in rows.index:
            return (1, 0.0)
        return (0, sign * float(rows.loc[name, "estimate"]))

    return sorted(laws, key=key)


def criteria(study: Study, schemes: Sequence[str], blocked: Sequence[str],
             laws: Sequence[xr.Dataset]) -> list[Criterion]:
    """The study's ranking criteria in display order: blocked schemes (the question), LOO, the
    other CV schemes, the log-evidence estimators the laws' results hold."""
    out = [Criterion("elpd_cv", s, "extrapolation") for s in blocked]
    if study.loo:
        out.append(Criterion("elpd_loo", "", "interpolation"))
    out += [Criterion("elpd_cv", s, "cross-validation") for s in schemes if s not in blocked]
    estimators = list(dict.fromkeys(str(k) for w in laws for k in w["estimator"].values))
    out += [Criterion("log_evidence", e, "evidence") for e in estimators]
    return out


def criteria_of(tree: xr.DataTree) -> list[Criterion]:
    """The ranking criteria a result tree holds (``/criteria``, :func:`criteria` of its study)."""
    node = tree["criteria"]
    return [Criterion(str(m), str(s), str(k)) for m, s, k in
            zip(node["metric"].values, node["scheme"].values, node["kind"].values, strict=True)]
