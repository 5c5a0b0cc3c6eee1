"""The ranking of a study report: the ranking table of both documents, ``ranking.csv`` and the
"Inside vs outside the tested envelope" table, all read from the study's result tree alone
(:mod:`bayesfric.study.tree`: the law × metric table ``/scores``, ``/criteria``,
``/diagnostics``, ``/checks``, ``/pointwise``).

Every law keeps the place its score gives it: a law whose result may not be ranked
(a fold failed the diagnostics gate, the evidence estimators disagree, the fit failed) is listed
where it scored, its rank cell says ``⚠`` and why, and only the ranked laws are numbered, so
rank 1 is the winner the summary names. Numbers are rounded to their standard errors
(:func:`bayesfric.report.typeset.fmt`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from bayesfric.report.blocks import Table
from bayesfric.report.typeset import fmt
from bayesfric.report.view import TreeView
from bayesfric.study import scores as sc

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr

__all__ = ["rank_cells", "ranking_table", "ranking_records", "extrapolation_table", "score_text", "weight_text",
           "loo_numbers", "law_flags"]


def score_text(row) -> str:
    """A score ``estimate ± se`` rounded to its error, ``⚠`` when it may not be ranked; ``–``
    when it was not computed."""
    if row is None or not math.isfinite(row["estimate"]):
        return "–"
    return fmt(row["estimate"], row["se"]) + ("" if row["reliable"] else " ⚠")


def weight_text(w: float | None) -> str:
    """A stacking weight at two decimals (``0`` below 0.005, ``–`` when not computed)."""
    if w is None or not math.isfinite(w):
        return "–"
    return "0" if w < 0.005 else fmt(w, digits=2)


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def law_flags(diag: xr.Dataset) -> list[str]:
    """A law's flags (``/diagnostics`` ``flags`` of one law), one line each."""
    text = str(diag["flags"].values)
    return text.split("\n") if text else []


def _unscored(t: TreeView, name: str, criterion: sc.Criterion) -> str:
    if str(t.law(name)["skipped"].values) and criterion.metric in ("elpd_cv", "log_evidence"):
        return "⚠ not scored: the full fit failed the diagnostics gate, so this score was not computed"
    if not t.passed(name):
        return "⚠ not scored: the fit failed the diagnostics gate"
    return "⚠ not scored"


def rank_cells(t: TreeView) -> tuple[list[str], dict[str, str]]:
    """(laws in ranking order, law -> its rank cell) on the study's first criterion.

    A ranked law's cell is its number among the ranked laws; a law that scored but may not be
    ranked reads ``⚠ not ranked (scored 1st): <reason>``, where it stands in the list; a law
    without the score, ``⚠ not scored: <why>``.
    """
    crit = t.crits[0] if t.crits else None
    order = sc.ranking_order(t.table, t.laws, crit)
    if crit is None:  # no criterion ranks the laws: none is numbered (bayesfric.report.findings.NO_CRITERION)
        return order, {name: "–" for name in order}
    cells, ranked = {}, 0
    for place, name in enumerate(order, start=1):
        row = sc.value(t.table, name, crit.metric, crit.scheme)
        if row is None:
            cells[name] = _unscored(t, name, crit)
        elif row["reliable"]:
            ranked += 1
            cells[name] = str(ranked)
        else:
            cells[name] = f"⚠ not ranked (scored {_ordinal(place)}): {row['reason']}"
    return order, cells


def ranking_table(tree: xr.DataTree | TreeView) -> tuple[Table, list[str]]:
    """The ranking table of both documents, and the ranking order."""
    t = TreeView.of(tree)
    table, crits = t.table, t.crits
    order, cells = rank_cells(t)
    weight_key = f"stacking {t.blocked[0]}" if t.blocked else "stacking LOO"
    header = ["rank", "law", "diagnostics"] + [c.label for c in crits] + [f"penalty/pt {s}" for s in t.blocked]
    header.append(f"weight ({weight_key})")
    rows, warn = [], []
    for i, name in enumerate(order):
        row = [cells[name], name, t.gate(name)]
        row += [score_text(sc.value(table, name, c.metric, c.scheme)) for c in crits]
        row += [score_text(sc.value(table, name, "penalty", s)) for s in t.blocked]
        w = sc.value(table, name, "weight", weight_key)
        row.append(weight_text(w["estimate"] if w is not None else None))
        rows.append(row)
        if cells[name].startswith("⚠") or not t.passed(name):
            warn.append(i)
    if not crits:
        return Table("Laws in the study file's order: the study has no ranking criterion (no LOO, cross-validation "
                     "or evidence), so no law is ranked. Every number: ranking.csv and scores.csv.", header, rows,
                     warn), order
    caption = (f"Laws ordered by {crits[0].label} (higher elpd / log Z is better; penalty/pt: lower is better; ± one "
               "standard error, numbers rounded to it). Every law stands where its score puts it; ⚠ in the rank "
               "column = not ranked, with the reason (a fold or the fit failed the diagnostics gate, or the evidence "
               "estimators disagree), and only ranked laws are numbered. Every number, with p_loo, Pareto k and all "
               "weights: ranking.csv and scores.csv.")
    return Table(caption + subsample_note(t), header, rows, warn), order


def subsample_note(t: TreeView) -> str:
    """Where PSIS-LOO was subsampled (data above ``limits.LOO_SUBSAMPLE_ROWS`` rows), one sentence
    per study naming each law's ``subsampled: n of N rows, subsampling se X`` ("" otherwise)."""
    parts = [f"{name} {text}" for name in t.laws if (text := str(t.law(name)["loo_subsampled"].values))]
    if not parts:
        return ""
    return (" PSIS-LOO is subsampled on data this large (arviz-stats loo_subsample: the rows not scored enter by "
            "an approximation; the elpd's ± includes the subsampling se, and the stacking weights read the "
            "approximated rows): " + "; ".join(parts) + ".")


def ranking_records(tree: xr.DataTree | TreeView) -> list[dict]:
    """``ranking.csv``: one row per law in ranking order — its rank cell as the documents show it
    (``rank``), its place by score (``place``), every score of the table in columns, with the
    law's diagnostics and checks."""
    t = TreeView.of(tree)
    order, cells = rank_cells(t)
    records = []
    for place, name in enumerate(order, start=1):
        d = t.law(name)
        rec: dict = {"rank": cells[name], "place": place, "law": name, "n_params": int(d["n_params"]),
                     "diagnostics_passed": bool(d["passed"]), "rhat_max": float(d["rhat_max"]),
                     "ess_bulk_min": float(d["ess_bulk_min"])}
        for r in t.table[t.table["law"] == name].itertuples():
            key = {"elpd_loo": "elpd_loo", "elpd_cv": f"elpd[{r.scheme}]", "log_evidence": f"log_z_{r.scheme}",
                   "penalty": f"penalty_per_point[{r.scheme}]", "weight": f"weight[{r.scheme}]"}[r.metric]
            rec[key] = float(r.estimate)
            if r.metric in ("elpd_loo", "elpd_cv", "log_evidence", "penalty"):
                err = {"elpd_loo": "elpd_loo_se", "elpd_cv": f"se[{r.scheme}]",
                       "penalty": f"penalty_se[{r.scheme}]"}.get(r.metric, f"{key}_error")
                rec[err] = float(r.se)
            rec[f"reliable[{r.metric} {r.scheme}]".replace(" ]", "]")] = bool(r.reliable)
            if not r.reliable and r.reason:
                rec[f"reason[{r.metric} {r.scheme}]".replace(" ]", "]")] = str(r.reason)
        if bool(d["evidence_compared"]):
            rec["evidence_disagreement"] = float(d["evidence_disagreement"])
        c = t.checks.sel(law=name)
        ok = bool(c["loo_pit_ok"])
        rec.update(loo_numbers(d), loo_pit_pvalue=float(c["loo_pit_pvalue"]), loo_pit_ok=ok,
                   loo_pit_shape=str(c["loo_pit_direction"].values) if not ok else "",
                   flags="; ".join(law_flags(d)))
        records.append(rec)
    return records


def loo_numbers(diag: xr.Dataset) -> dict:
    """p_loo, the number of high-k points and the largest Pareto k of a law's PSIS-LOO (NaN: not
    run), from its ``/diagnostics`` (one law)."""
    if int(diag["n_high_k"]) < 0:  # no LOO
        return dict(p_loo=math.nan, n_high_k=0, pareto_k_max=math.nan)
    numbers = dict(p_loo=float(diag["p_loo"]), n_high_k=int(diag["n_high_k"]),
                   pareto_k_max=float(diag["pareto_k_max"]))
    if int(diag["loo_rows_scored"]) >= 0:  # only then: a study on smaller data keeps its columns
        numbers.update(loo_rows_scored=int(diag["loo_rows_scored"]), loo_rows=int(diag["loo_rows"]),
                       elpd_loo_subsampling_se=float(diag["loo_subsampling_se"]))
    return numbers


def _loo_on(t: TreeView, name: str, held: np.ndarray | None) -> tuple[float, float]:
    """PSIS-LOO elpd summed over the held-out points of a blocked scheme, and its standard error
    ``sqrt(n var(elpd_i))`` (what the law scores there having trained on them)."""
    if int(t.law(name)["n_high_k"]) < 0 or held is None or not held.any():
        return math.nan, math.nan
    values = np.asarray(t.pointwise["elpd"].sel(criterion="elpd_loo", law=name).values, dtype=float)
    if int(t.law(name)["loo_rows_scored"]) >= 0:
        return _subsampled_loo_on(values, np.asarray(t.pointwise["loo_scored"].sel(law=name).values), held)
    values = values[held]
    return float(values.sum()), float(math.sqrt(values.size * values.var(ddof=1))) if values.size > 1 else math.nan


def _subsampled_loo_on(elpd_i: np.ndarray, exact: np.ndarray, held: np.ndarray) -> tuple[float, float]:
    """:func:`_loo_on` of a subsampled PSIS-LOO: the held-out rows it scored exactly (``exact``)
    stand for all ``n`` held-out rows (sum ``n · mean``), the se adding the subsampling part
    ``n · sd / sqrt(m)``."""
    values = elpd_i[held & exact]
    n, m = int(held.sum()), values.size
    if m < 2:
        return math.nan, math.nan
    var = values.var(ddof=1)
    return float(n * values.mean()), float(math.sqrt(n * var + n * n * var / m * (1 - m / n)))


def extrapolation_table(tree: xr.DataTree | TreeView, order: list[str]) -> Table | None:
    """"Inside vs outside the tested envelope": per blocked scheme, the elpd on its held-out points
    when the law trained on them (PSIS-LOO) and when it did not (the blocked fold), and the
    penalty per point between the two, each ± its standard error."""
    t = TreeView.of(tree)
    if not t.blocked:
        return None
    header = ["law"]
    for s in t.blocked:
        header += [f"elpd on held-out, trained on them (LOO) {s}", f"elpd on held-out, not trained on them "
                   f"(blocked) {s}", f"penalty/pt {s}"]
    rows = []
    for name in order:
        row = [name]
        for s in t.blocked:
            held = (np.asarray(t.pointwise["heldout"].sel(scheme=s).values, dtype=bool)
                    if _computed(t.table, name, "elpd_cv", s) else None)  # no blocked fold: no points to compare
            loo, loo_se = _loo_on(t, name, held)
            row += [fmt(loo, loo_se), score_text(sc.value(t.table, name, "elpd_cv", s)),
                    score_text(sc.value(t.table, name, "penalty", s))]
        rows.append(row)
    return Table("Each blocked scheme holds out the points beyond a threshold. LOO: the law's elpd on those points "
                 "when they were in its training data; blocked: when they were not. penalty/pt = (LOO − blocked) / "
                 "points: how many nats per point worse the law predicts outside the tested envelope than inside "
                 "it (± the standard error of the paired differences).", header, rows)


def _computed(table: pd.DataFrame, name: str, metric: str, scheme: str) -> bool:
    """The law has a row under ``metric`` and ``scheme`` (its estimate may be NaN)."""
    return bool(((table["law"] == name) & (table["metric"] == metric) & (table["scheme"] == scheme)).any())
