"""The ranking of a study report: the ranking table of both documents, ``ranking.csv`` and the
"Inside vs outside the tested envelope" table, all read from the law × metric table
(:mod:`bayesfric.study.scores`).

Every law keeps the place its score gives it (issue 29): a law whose result may not be ranked
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
from bayesfric.study import scores as sc
from bayesfric.study.outcome import Checks

if TYPE_CHECKING:
    from bayesfric.study.outcome import LawOutcome, StudyOutcome

__all__ = ["rank_cells", "ranking_table", "ranking_records", "extrapolation_table", "score_text", "weight_text"]


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


def _unscored(w: LawOutcome, criterion: sc.Criterion) -> str:
    if w.skipped and criterion.metric in ("elpd_cv", "log_evidence"):
        return "⚠ not scored: the full fit failed the diagnostics gate, so this score was not computed"
    if not w.reliable:
        return "⚠ not scored: the fit failed the diagnostics gate"
    return "⚠ not scored"


def rank_cells(outcome: StudyOutcome) -> tuple[list[str], dict[str, str]]:
    """(laws in ranking order, law -> its rank cell) on the study's first criterion.

    A ranked law's cell is its number among the ranked laws; a law that scored but may not be
    ranked reads ``⚠ not ranked (scored 1st): <reason>``, where it stands in the list; a law
    without the score, ``⚠ not scored: <why>``.
    """
    table, crits = outcome.table, sc.criteria(outcome)
    crit = crits[0] if crits else None
    order = sc.ranking_order(table, [w.name for w in outcome.laws], crit)
    if crit is None:  # no criterion ranks the laws: none is numbered (bayesfric.report.findings.NO_CRITERION)
        return order, {name: "–" for name in order}
    laws = {w.name: w for w in outcome.laws}
    cells, ranked = {}, 0
    for place, name in enumerate(order, start=1):
        row = sc.value(table, name, crit.metric, crit.scheme)
        if row is None:
            cells[name] = _unscored(laws[name], crit)
        elif row["reliable"]:
            ranked += 1
            cells[name] = str(ranked)
        else:
            cells[name] = f"⚠ not ranked (scored {_ordinal(place)}): {row['reason']}"
    return order, cells


def ranking_table(outcome: StudyOutcome) -> tuple[Table, list[str]]:
    """The ranking table of both documents, and the ranking order."""
    table, crits = outcome.table, sc.criteria(outcome)
    order, cells = rank_cells(outcome)
    weight_key = f"stacking {outcome.blocked[0]}" if outcome.blocked else "stacking LOO"
    header = ["rank", "law", "diagnostics"] + [c.label for c in crits] + [f"penalty/pt {s}" for s in outcome.blocked]
    header.append(f"weight ({weight_key})")
    laws = {w.name: w for w in outcome.laws}
    rows, warn = [], []
    for i, name in enumerate(order):
        row = [cells[name], name, "passed" if laws[name].reliable else "FAILED"]
        row += [score_text(sc.value(table, name, c.metric, c.scheme)) for c in crits]
        row += [score_text(sc.value(table, name, "penalty", s)) for s in outcome.blocked]
        w = sc.value(table, name, "weight", weight_key)
        row.append(weight_text(w["estimate"] if w is not None else None))
        rows.append(row)
        if cells[name].startswith("⚠") or not laws[name].reliable:
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
    return Table(caption + subsample_note(outcome), header, rows, warn), order


def subsample_note(outcome: StudyOutcome) -> str:
    """Where PSIS-LOO was subsampled (data above ``limits.LOO_SUBSAMPLE_ROWS`` rows), one sentence
    per study naming each law's ``subsampled: n of N rows, subsampling se X`` ("" otherwise)."""
    parts = [f"{w.name} {w.loo.subsampled}" for w in outcome.laws if w.loo is not None and w.loo.subsample is not None]
    if not parts:
        return ""
    return (" PSIS-LOO is subsampled on data this large (arviz-stats loo_subsample: the rows not scored enter by "
            "an approximation; the elpd's ± includes the subsampling se, and the stacking weights read the "
            "approximated rows): " + "; ".join(parts) + ".")


def ranking_records(outcome: StudyOutcome) -> list[dict]:
    """``ranking.csv``: one row per law in ranking order — its rank cell as the documents show it
    (``rank``), its place by score (``place``), every score of the table in columns, with the
    law's diagnostics and checks."""
    table = outcome.table
    order, cells = rank_cells(outcome)
    laws = {w.name: w for w in outcome.laws}
    records = []
    for place, name in enumerate(order, start=1):
        w = laws[name]
        rec: dict = {"rank": cells[name], "place": place, "law": name,
                     "n_params": sum(max(1, math.prod(p.shape)) for p in w.law.params.values()),
                     "diagnostics_passed": w.reliable, "rhat_max": w.verdict.rhat_max,
                     "ess_bulk_min": w.verdict.ess_bulk_min}
        for r in table[table["law"] == name].itertuples():
            key = {"elpd_loo": "elpd_loo", "elpd_cv": f"elpd[{r.scheme}]", "log_evidence": f"log_z_{r.scheme}",
                   "penalty": f"penalty_per_point[{r.scheme}]", "weight": f"weight[{r.scheme}]"}[r.metric]
            rec[key] = r.estimate
            if r.metric in ("elpd_loo", "elpd_cv", "log_evidence", "penalty"):
                err = {"elpd_loo": "elpd_loo_se", "elpd_cv": f"se[{r.scheme}]",
                       "penalty": f"penalty_se[{r.scheme}]"}.get(r.metric, f"{key}_error")
                rec[err] = r.se
            rec[f"reliable[{r.metric} {r.scheme}]".replace(" ]", "]")] = r.reliable
            if not r.reliable and r.reason:
                rec[f"reason[{r.metric} {r.scheme}]".replace(" ]", "]")] = r.reason
        if w.agreement is not None:
            rec["evidence_disagreement"] = abs(w.agreement.difference)
        checks = w.checks or Checks()
        shape = checks.pit_shape
        rec.update(loo_numbers(w), loo_pit_pvalue=checks.loo_pit_pvalue, loo_pit_ok=checks.loo_pit_ok,
                   loo_pit_shape=shape.label if shape is not None and not checks.loo_pit_ok else "",
                   flags="; ".join(w.flags))
        records.append(rec)
    return records


def loo_numbers(w: LawOutcome) -> dict:
    """p_loo, the number of high-k points and the largest Pareto k of a law's PSIS-LOO (NaN: not run)."""
    if w.loo is None:
        return dict(p_loo=math.nan, n_high_k=0, pareto_k_max=math.nan)
    numbers = dict(p_loo=w.loo.p_loo, n_high_k=w.loo.n_high_k, pareto_k_max=float(np.nanmax(w.loo.pareto_k)))
    if w.loo.subsample is not None:  # only then: a study on smaller data keeps its columns
        numbers.update(loo_rows_scored=w.loo.subsample.size, loo_rows=w.loo.subsample.n_rows,
                       elpd_loo_subsampling_se=w.loo.subsampling_se)
    return numbers


def _loo_on(w: LawOutcome, held: np.ndarray | None) -> tuple[float, float]:
    """PSIS-LOO elpd summed over the held-out points of a blocked scheme, and its standard error
    ``sqrt(n var(elpd_i))`` (what the law scores there having trained on them)."""
    if w.loo is None or held is None or not held.any():
        return math.nan, math.nan
    if w.loo.subsample is not None:
        return _subsampled_loo_on(w, held)
    values = np.asarray(w.loo.elpd_i, dtype=float)[held]
    return float(values.sum()), float(math.sqrt(values.size * values.var(ddof=1))) if values.size > 1 else math.nan


def _subsampled_loo_on(w: LawOutcome, held: np.ndarray) -> tuple[float, float]:
    """:func:`_loo_on` of a subsampled PSIS-LOO: the held-out rows it scored exactly stand for all
    ``n`` held-out rows (sum ``n · mean``), the se adding the subsampling part ``n · sd / sqrt(m)``."""
    exact = np.zeros(held.size, dtype=bool)
    exact[w.loo.subsample.rows] = True
    values = np.asarray(w.loo.elpd_i, dtype=float)[held & exact]
    n, m = int(held.sum()), values.size
    if m < 2:
        return math.nan, math.nan
    var = values.var(ddof=1)
    return float(n * values.mean()), float(math.sqrt(n * var + n * n * var / m * (1 - m / n)))


def extrapolation_table(outcome: StudyOutcome, order: list[str]) -> Table | None:
    """"Inside vs outside the tested envelope": per blocked scheme, the elpd on its held-out points
    when the law trained on them (PSIS-LOO) and when it did not (the blocked fold), and the
    penalty per point between the two, each ± its standard error."""
    if not outcome.blocked:
        return None
    table = outcome.table
    laws = {w.name: w for w in outcome.laws}
    header = ["law"]
    for s in outcome.blocked:
        header += [f"elpd on held-out, trained on them (LOO) {s}", f"elpd on held-out, not trained on them "
                   f"(blocked) {s}", f"penalty/pt {s}"]
    rows = []
    for name in order:
        row = [name]
        for s in outcome.blocked:
            cv = laws[name].cv.get(s)
            loo, loo_se = _loo_on(laws[name], cv.heldout if cv is not None else None)
            row += [fmt(loo, loo_se), score_text(sc.value(table, name, "elpd_cv", s)),
                    score_text(sc.value(table, name, "penalty", s))]
        rows.append(row)
    return Table("Each blocked scheme holds out the points beyond a threshold. LOO: the law's elpd on those points "
                 "when they were in its training data; blocked: when they were not. penalty/pt = (LOO − blocked) / "
                 "points: how many nats per point worse the law predicts outside the tested envelope than inside "
                 "it (± the standard error of the paired differences).", header, rows)
