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
    import xarray as xr

    from bayesfric.study.outcome import StudyOutcome

__all__ = ["METRICS", "COLUMNS", "Criterion", "score_table", "best", "passed_over", "ranking_order", "criteria",
           "value", "fold_failure", "table_of", "criteria_of"]

COLUMNS = ["law", "metric", "scheme", "estimate", "se", "reliable", "reason"]


def _gate(w, include_failed: bool) -> tuple[bool, str]:
    if w.reliable:
        return True, ""
    if include_failed:
        return True, "fit failed the diagnostics gate; ranked because the study sets include_failed"
    return False, "fit failed the diagnostics gate"


def _loo_rows(w, gate) -> list[tuple]:
    loo = w.loo
    if loo is None or not math.isfinite(loo.elpd):
        return []
    ok, why = gate
    if ok and not loo.reliable:
        ok, why = False, f"high Pareto k not resolved ({loo.handling})"
    return [(w.name, "elpd_loo", "", loo.elpd, loo.se, ok, why)]


def fold_failure(cv) -> str:
    """Why a cross-validation result may not be ranked: which folds failed the gate and the first
    problem of each (:attr:`bayesfric.compare.CVResult.failure`); ``""`` when every fold passed."""
    return cv.failure


def _cv_rows(w, gate, blocked: list[str]) -> list[tuple]:
    rows = []
    for label, cv in w.cv.items():
        ok, why = gate
        if ok and not cv.reliable:
            ok, why = False, fold_failure(cv)
        rows.append((w.name, "elpd_cv", label, cv.elpd, cv.se, ok, why))
        if label in blocked and label in w.penalty:
            # The penalty is a mean of paired pointwise differences (LOO minus blocked, the same
            # held-out points): its standard error is that of the differences' mean
            # (bayesfric.compare.Penalty), NaN when it was not computed.
            se = w.penalty_se.get(label, math.nan)
            rows.append((w.name, "penalty", label, w.penalty[label], se, ok, why))
    return rows


def _evidence_rows(w, gate) -> list[tuple]:
    rows = []
    for estimator, ev in w.evidence.items():
        ok, why = gate
        if ok and not w.evidence_agree:
            ok, why = False, (f"evidence estimators disagree by {abs(w.agreement.difference):.2f} nat: "
                              "left out of the evidence ranking")
        rows.append((w.name, "log_evidence", estimator, ev.log_z, ev.error, ok, why))
    return rows


def _weight_rows(w) -> list[tuple]:
    return [(w.name, "weight", method, weight.value, math.nan, not weight.excluded, weight.excluded)
            for method, weight in w.weights.items()]


def score_table(outcome: StudyOutcome) -> pd.DataFrame:
    """The tidy law × metric table of a :class:`~bayesfric.study.outcome.StudyOutcome`.

    Parameters
    ----------
    outcome : StudyOutcome
        Per-law results (after the weights were assigned).

    Returns
    -------
    pandas.DataFrame
        Columns :data:`COLUMNS`, one row per law, metric and scheme that was computed.
    """
    rows: list[tuple] = []
    for w in outcome.laws:
        gate = _gate(w, outcome.study.include_failed)
        rows += _loo_rows(w, gate) + _cv_rows(w, gate, outcome.blocked) + _evidence_rows(w, gate)
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


def criteria(outcome: StudyOutcome) -> list[Criterion]:
    """The study's ranking criteria in display order: blocked schemes (the question), LOO, the
    other CV schemes, the log-evidence estimators."""
    out = [Criterion("elpd_cv", s, "extrapolation") for s in outcome.blocked]
    if outcome.study.loo:
        out.append(Criterion("elpd_loo", "", "interpolation"))
    out += [Criterion("elpd_cv", s, "cross-validation") for s in outcome.schemes if s not in outcome.blocked]
    estimators = list(dict.fromkeys(k for w in outcome.laws for k in w.evidence))
    out += [Criterion("log_evidence", e, "evidence") for e in estimators]
    return out


def criteria_of(tree: xr.DataTree) -> list[Criterion]:
    """The ranking criteria a result tree holds (``/criteria``, :func:`criteria` of its study)."""
    node = tree["criteria"]
    return [Criterion(str(m), str(s), str(k)) for m, s, k in
            zip(node["metric"].values, node["scheme"].values, node["kind"].values, strict=True)]
