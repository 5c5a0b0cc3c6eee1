"""The content model of a study report: every section of ``summary.md`` and ``report.html`` as
plain data, built once from a :class:`~bayesfric.study.outcome.StudyOutcome` and its law × metric
table; the two templates (``templates/summary.md.j2``, ``templates/report.html.j2``) only lay it
out. Nothing here computes a statistic: numbers come from the table, the outcome's fields or the
fits' posterior summaries (:func:`bayesfric.report.tables.parameter_rows`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from bayesfric.report import findings as fd
from bayesfric.report import sizing as sizing_report
from bayesfric.report.figures import provenance_label
from bayesfric.report.tables import parameter_rows, retry_note
from bayesfric.study import scores as sc
from bayesfric.study.outcome import Checks

if TYPE_CHECKING:
    from bayesfric.study.outcome import StudyOutcome

__all__ = ["Table", "FigureRef", "LawSection", "Report", "build", "SECTIONS", "ranking_records"]

#: (id, heading) of every section in page order; optional ones appear only when they have content.
SECTIONS = [
    ("summary", "Summary"), ("ranking", "Ranking"),
    ("claims", "What the source paper says vs what the posterior says"),
    ("extrapolation", "Inside vs outside the tested envelope"),
    ("trajectories", "Trajectories: predicted vs measured"), ("sizing", "Sizing"),
    ("parameters", "Parameters"), ("data", "Data and checks"), ("findings", "All findings"),
]


@dataclass
class Table:
    """A caption, a header and rows of strings; ``warn``: row indices to mark."""

    caption: str
    header: list[str]
    rows: list[list[str]]
    warn: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class FigureRef:
    """A figure file (relative to the report folder), its section and what to read from it."""

    section: str
    path: str
    caption: str
    alt: str


@dataclass
class LawSection:
    """One law's parameter section."""

    name: str
    summary: str
    source: str
    diagnostics: str
    notes: str
    table: Table
    figure: FigureRef | None = None


@dataclass
class Report:
    """Everything a rendering needs (strings are raw: the templates escape them)."""

    title: str
    banner: str
    reconstructed: bool
    summary: fd.Summary
    findings: list[fd.Finding]
    claims: Table | None
    ranking: Table
    ranking_note: str
    sensitivity: str
    extrapolation: Table | None
    laws: list[LawSection]
    data_lines: list[str]
    checks: Table
    sizing_intro: str
    sizing_caption: str
    sizing: list[Any]
    figures: dict[str, list[FigureRef]]
    footer: str
    sections: list[tuple[str, str]] = field(default_factory=list)


def _num(x: Any, digits: int = 2) -> str:
    return f"{x:.{digits}f}" if isinstance(x, float | int) and math.isfinite(x) else "–"


def _pm(row) -> str:
    if row is None or not math.isfinite(row["estimate"]):
        return "–"
    text = f"{row['estimate']:.1f}" + (f" ± {row['se']:.1f}" if math.isfinite(row["se"]) else "")
    return text + ("" if row["reliable"] else " ⚠")


def _ranking(outcome: StudyOutcome, table) -> tuple[Table, list[str]]:
    crits = sc.criteria(outcome)
    order = sc.ranking_order(table, [w.name for w in outcome.laws], crits[0] if crits else None)
    weight_key = f"stacking {outcome.blocked[0]}" if outcome.blocked else "stacking LOO"
    header = ["rank", "law", "diagnostics"] + [c.label for c in crits] + [f"penalty/pt {s}" for s in outcome.blocked]
    header.append(f"weight ({weight_key})")
    laws = {w.name: w for w in outcome.laws}
    rows, warn = [], []
    for i, name in enumerate(order):
        row = [str(i + 1), name, "passed" if laws[name].reliable else "FAILED"]
        row += [_pm(sc.value(table, name, c.metric, c.scheme)) for c in crits]
        row += [_num(r["estimate"], 3) if (r := sc.value(table, name, "penalty", s)) is not None else "–"
                for s in outcome.blocked]
        w = sc.value(table, name, "weight", weight_key)
        row.append(_num(w["estimate"], 3) if w is not None else "–")
        rows.append(row)
        if not laws[name].reliable:
            warn.append(i)
    caption = (f"Laws ordered by {crits[0].label if crits else 'name'} (higher elpd / log Z is better; "
               "± one standard error). ⚠ = not ranked: the fit or a fold failed the diagnostics gate, or the evidence "
               "estimators disagree. Every number, with p_loo, Pareto k and all weights: ranking.csv and scores.csv.")
    return Table(caption, header, rows, warn), order


def _claims(outcome: StudyOutcome) -> Table | None:
    if not outcome.claims:
        return None
    rows, warn = [], []
    for i, r in enumerate(outcome.claims):
        c = r.claim
        pct = c.kind == "ratio"

        def show(x: float, pct: bool = pct) -> str:
            if math.isinf(x):
                return "+∞" if x > 0 else "−∞"
            return "–" if not math.isfinite(x) else (f"{x:+.0%}" if pct else f"{x:.3g}")

        if c.kind == "best":
            claimed, says = f"best: {c.law}", (f"best: {r.winner}" if r.winner else "–")
        else:
            claimed = f"{show(c.expect[0])} … {show(c.expect[1])}"
            interval = "90 % interval" if c.kind != "score" else "± 1 se"
            says = f"{show(r.value)} ({interval} {show(r.lo)} … {show(r.hi)})" if math.isfinite(r.lo) else show(r.value)
        verdict = r.verdict + (f": {r.why}" if r.why else "")
        rows.append([c.text, c.source, c.basis_label, claimed, says, verdict])
        if r.verdict != "reproduced":
            warn.append(i)
    caption = ("Each claim is declared in the study file ([[claims]]) and computed from the posterior: ratios are "
               "mean-function predictions of the fitted law (posterior median, 90 % interval); the claimed range is "
               "the study author's reading of the paper. Verdict: reproduced when the posterior median (or the "
               "winner) is in the claimed range. Basis: a \"pipeline check, not evidence\" is a statement the "
               "reconstructed data were built to satisfy — its verdict checks the reconstruction and the pipeline, "
               "not the paper; \"evidence\" was not used to build the data.")
    return Table(caption, ["claim", "source", "basis", "claimed", "posterior says", "verdict"], rows, warn)


def _extrapolation(outcome: StudyOutcome, table, order) -> Table | None:
    if not outcome.blocked:
        return None
    header = ["law"] + [f"{h} {s}" for s in outcome.blocked for h in ("elpd LOO on held-out", "penalty/pt")]
    rows = []
    for name in order:
        row = [name]
        for s in outcome.blocked:
            pen = sc.value(table, name, "penalty", s)
            cv = sc.value(table, name, "elpd_cv", s)
            row += [_pm(cv), _num(pen["estimate"], 3) if pen is not None else "–"]
        rows.append(row)
    return Table("penalty/pt = (elpd_LOO − elpd_blocked) per held-out point, on the same points: how much worse "
                 "(in nats per point) the law predicts outside the tested envelope than inside it.", header, rows)


def _law_sections(outcome: StudyOutcome, figures: dict[str, FigureRef]) -> list[LawSection]:
    out = []
    for w in outcome.laws:
        rows = [[r.name, r.unit, f"{r.mean:.4g}", f"{r.sd:.3g}", f"{r.q05:.4g} … {r.q95:.4g}", f"{r.r_hat:.3f}",
                 f"{r.ess_bulk:.0f}", r.meaning] for r in parameter_rows(w.fit, w.law)]
        table = Table("", ["parameter", "unit", "mean", "sd", "90 % interval", "R-hat", "ESS", "meaning"], rows)
        out.append(LawSection(w.name, w.law.summary, w.law.source, str(w.verdict) + retry_note(w.fit),
                              w.law.notes or "", table,
                              figures.get(w.name)))
    return out


def _loo_numbers(w) -> dict:
    """p_loo, the number of high-k points and the largest Pareto k of a law's PSIS-LOO (NaN: not run)."""
    if w.loo is None:
        return dict(p_loo=math.nan, n_high_k=0, pareto_k_max=math.nan)
    return dict(p_loo=w.loo.p_loo, n_high_k=w.loo.n_high_k, pareto_k_max=float(np.max(w.loo.pareto_k)))


def _checks(outcome: StudyOutcome) -> Table:
    rows, warn = [], []
    for i, w in enumerate(outcome.laws):
        loo, checks = _loo_numbers(w), w.checks or Checks()
        rows.append([w.name, "passed" if w.reliable else "FAILED", _num(loo["p_loo"], 1),
                     f"{loo['n_high_k']} (max {_num(loo['pareto_k_max'])})",
                     _num(checks.loo_pit_pvalue, 3) + ("" if checks.loo_pit_ok else " ⚠"),
                     f"{checks.prior_implausible:.1%}" if math.isfinite(checks.prior_implausible) else "–",
                     checks.prior_sensitivity if w.checks else "–", "; ".join(w.flags) or "–",
                     f"fits/{w.fit_file.name}"])
        if not w.reliable or not w.loo_pit_ok or w.flags:
            warn.append(i)
    header = ["law", "diagnostics", "p_loo", "Pareto k > thr", "LOO-PIT p", "unphysical prior draws",
              "prior sensitivity", "flags", "fit file"]
    return Table("Checks per law. ⚠ = LOO-PIT outside its simultaneous band (miscalibrated).", header, rows, warn)


def _data_lines(outcome: StudyOutcome) -> list[str]:
    st, ds = outcome.study, outcome.data
    noise = st.noise.kind + (f", partial-pooled offsets per {st.noise.group}" if st.noise.group else "")
    return [f"data set: {ds.attrs.get('name')} — {ds.attrs.get('title', '')}",
            f"provenance: {ds.attrs.get('provenance')}; source: {ds.attrs.get('source')}",
            f"{ds.sizes['obs']} observations; selection: {ds.attrs.get('selection', 'all rows')}; "
            f"content hash {ds.attrs.get('data_hash')}",
            f"noise model: {noise}", f"sampler: {st.sampler}"]


def _claim_warnings(outcome: StudyOutcome) -> list[fd.Finding]:
    """The claims' verdicts in the summary: evidence and pipeline checks counted apart."""
    out = []
    for pipeline, what in ((False, "claim(s) of the source paper"),
                           (True, "pipeline check(s) (statements the reconstructed data were built to satisfy)")):
        bad = [r for r in outcome.claims if r.verdict == "not reproduced" and r.claim.pipeline_check == pipeline]
        if bad:
            out.append(fd.plain(f"{len(bad)} {what} NOT reproduced by the posterior (see the claims section).",
                                warning=True))
    checks = sum(r.claim.pipeline_check for r in outcome.claims)
    if checks:
        out.append(fd.plain(f"{checks} of the {len(outcome.claims)} claims are pipeline checks, not evidence: their "
                            "numbers were used to build the reconstructed data, so reproducing them checks the "
                            "reconstruction and the pipeline, not the paper."))
    return out


def build(outcome: StudyOutcome, figures: list[FigureRef], sizing_figures: dict[int, str]) -> Report:
    """The report's content model (``sizing_figures``: question index -> the fan's reference as
    the rendering wants it, a file name or an encoded image)."""
    table = outcome.table
    ranking, order = _ranking(outcome, table)
    by_section: dict[str, list[FigureRef]] = {}
    pair = {}
    for f in figures:
        if f.section.startswith("parameters:"):
            pair[f.section.split(":", 1)[1]] = f
        else:
            by_section.setdefault(f.section, []).append(f)
    findings = fd.findings(outcome, table)
    sizing = []
    summary = fd.summary_block(outcome, table, _claim_warnings(outcome))
    if outcome.sizing is not None:
        headlines = sizing_report.headlines(outcome.sizing)
        findings += headlines
        summary.answers += headlines  # the sizing answer belongs to the decision block too
        sizing = sizing_report.sections(outcome.sizing, sizing_figures)
    rep = Report(
        title=outcome.study.title, banner=provenance_label(outcome.data),
        reconstructed=outcome.data.attrs.get("provenance") == "reconstructed",
        summary=summary, findings=findings,
        claims=_claims(outcome), ranking=ranking,
        ranking_note="Weights exclude fits that failed the diagnostics gate"
                     + (" (the study asked to include them)." if outcome.study.include_failed else "."),
        sensitivity=outcome.ranking_sensitivity, extrapolation=_extrapolation(outcome, table, order),
        laws=_law_sections(outcome, pair), data_lines=_data_lines(outcome), checks=_checks(outcome),
        sizing_intro="Friction opposes motion, so sizing works on magnitudes |T|. Mean function: the law's curve "
                     "with parameter uncertainty only; with noise: plus the fit's observation noise (what a drive "
                     "meets). Every law and point: sizing.csv.",
        sizing_caption="|friction| against the question's input: tested range shaded, each law's median curve and "
                       "5–95 % band with noise (excluded laws dotted), the model average and its required capacity "
                       "(dashed), the asked range or point. Read: how fast the laws' bands spread apart beyond the "
                       "tested range — that spread is the sizing risk.",
        sizing=sizing, figures=by_section,
        footer=f"Generated by bayesfric in {outcome.seconds:.0f} s. Rerun: bayesfric study {outcome.study.path}",
    )
    present = {"claims": rep.claims is not None, "trajectories": bool(by_section.get("trajectories")),
               "sizing": bool(sizing)}
    rep.sections = [(k, h) for k, h in SECTIONS if present.get(k, True)]
    return rep


def ranking_records(outcome: StudyOutcome) -> list[dict]:
    """``ranking.csv``: one row per law (in ranking order), every score of the table in columns,
    with the law's diagnostics and checks."""
    table = outcome.table
    crits = sc.criteria(outcome)
    order = sc.ranking_order(table, [w.name for w in outcome.laws], crits[0] if crits else None)
    laws = {w.name: w for w in outcome.laws}
    records = []
    for name in order:
        w = laws[name]
        rec: dict = {"law": name, "n_params": sum(max(1, math.prod(p.shape)) for p in w.law.params.values()),
                     "diagnostics_passed": w.reliable, "rhat_max": w.verdict.rhat_max,
                     "ess_bulk_min": w.verdict.ess_bulk_min}
        for r in table[table["law"] == name].itertuples():
            key = {"elpd_loo": "elpd_loo", "elpd_cv": f"elpd[{r.scheme}]", "log_evidence": f"log_z_{r.scheme}",
                   "penalty": f"penalty_per_point[{r.scheme}]", "weight": f"weight[{r.scheme}]"}[r.metric]
            rec[key] = r.estimate
            if r.metric in ("elpd_loo", "elpd_cv", "log_evidence"):
                err = {"elpd_loo": "elpd_loo_se", "elpd_cv": f"se[{r.scheme}]"}.get(r.metric, f"{key}_error")
                rec[err] = r.se
            rec[f"reliable[{r.metric} {r.scheme}]".replace(" ]", "]")] = r.reliable
        if w.agreement is not None:
            rec["evidence_disagreement"] = abs(w.agreement.difference)
        checks = w.checks or Checks()
        rec.update(_loo_numbers(w), loo_pit_pvalue=checks.loo_pit_pvalue, loo_pit_ok=checks.loo_pit_ok,
                   flags="; ".join(w.flags))
        records.append(rec)
    return records
