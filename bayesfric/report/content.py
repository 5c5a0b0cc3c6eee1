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

from bayesfric.report import findings as fd
from bayesfric.report import sizing as sizing_report
from bayesfric.report.blocks import FigureRef, Table
from bayesfric.report.figures import provenance_label
from bayesfric.report.ranking import extrapolation_table, loo_numbers, ranking_records, ranking_table
from bayesfric.report.tables import parameter_rows, retry_note
from bayesfric.report.typeset import fmt, unit
from bayesfric.study.outcome import Checks

if TYPE_CHECKING:
    import xarray as xr

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
    return fmt(x, digits=digits) if isinstance(x, float | int) and math.isfinite(x) else "–"


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


def _law_sections(outcome: StudyOutcome, figures: dict[str, FigureRef]) -> list[LawSection]:
    out = []
    for w in outcome.laws:
        rows = [[r.name, unit(r.unit), fmt(r.mean, r.sd, pm=False), fmt(r.sd, r.sd, pm=False),
                 f"{fmt(r.q05, r.sd, pm=False)} … {fmt(r.q95, r.sd, pm=False)}", f"{r.r_hat:.3f}",
                 f"{r.ess_bulk:.0f}", r.meaning] for r in parameter_rows(w.fit, w.law)]
        table = Table("", ["parameter", "unit", "mean", "sd", "90 % interval", "R-hat", "ESS", "meaning"], rows)
        out.append(LawSection(w.name, w.law.summary, w.law.source, str(w.verdict) + retry_note(w.fit),
                              w.law.notes or "", table,
                              figures.get(w.name)))
    return out


def _checks(outcome: StudyOutcome, tree: xr.DataTree) -> Table:
    rows, warn = [], []
    diag = tree["diagnostics"].to_dataset()
    for i, w in enumerate(outcome.laws):
        loo, checks = loo_numbers(diag.sel(law=w.name)), w.checks or Checks()
        shape = checks.pit_shape.label if checks.pit_shape is not None else "miscalibrated"
        rows.append([w.name, "passed" if w.reliable else "FAILED", _num(loo["p_loo"], 2),
                     f"{loo['n_high_k']} (max {_num(loo['pareto_k_max'])})",
                     _num(checks.loo_pit_pvalue, 2) + ("" if checks.loo_pit_ok else f" ⚠ {shape}"),
                     f"{checks.prior_implausible:.1%}" if math.isfinite(checks.prior_implausible) else "–",
                     checks.prior_sensitivity if w.checks else "–", "; ".join(w.flags) or "–",
                     f"fits/{w.fit_file.name}"])
        if not w.reliable or not w.loo_pit_ok or w.flags:
            warn.append(i)
    header = ["law", "diagnostics", "p_loo", "Pareto k > thr", "LOO-PIT p", "unphysical prior draws",
              "prior sensitivity", "flags", "fit file"]
    return Table("Checks per law. ⚠ = LOO-PIT outside its simultaneous band (miscalibrated), with the direction read "
                 "from the PIT values (bayesfric.compare.pit: too narrow, too wide, biased); each flagged law's "
                 "LOO-PIT figure follows." + checks_note(outcome), header, rows, warn)


def checks_note(outcome: StudyOutcome) -> str:
    """The sample the checks read when it was a subsample of the rows ("" when every row)."""
    n = int(outcome.data.sizes.get("obs", 0))
    read = {len(w.checks.pit) for w in outcome.laws if w.checks is not None and w.checks.pit is not None}
    if not read or max(read) >= n:
        return ""
    return (f" On data this large (N = {n} rows) LOO-PIT and the prior-power ranking sensitivity read a random "
            f"subsample of {max(read)} of the {n} rows (the rows the subsampled PSIS-LOO scores exactly); the "
            "prior predictive check reads every row.")


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
    return out


def build(outcome: StudyOutcome, tree: xr.DataTree, figures: list[FigureRef],
          sizing_figures: dict[int, str]) -> Report:
    """The report's content model (``tree``: the study's result tree, :mod:`bayesfric.study.tree`,
    which the ranking tables read alone; ``sizing_figures``: question index -> the fan's reference
    as the rendering wants it, a file name or an encoded image)."""
    table = outcome.table
    ranking, order = ranking_table(tree)
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
        sensitivity=fd.sensitivity_sentence(outcome.sensitivity), extrapolation=extrapolation_table(tree, order),
        laws=_law_sections(outcome, pair), data_lines=_data_lines(outcome), checks=_checks(outcome, tree),
        sizing_intro="Friction opposes motion, so sizing works on magnitudes |T|. Mean function: the law's curve "
                     "with parameter uncertainty only; with noise: plus the fit's observation noise (what a drive "
                     "meets). Every law and point: sizing.csv.",
        sizing_caption="|friction| against the question's input: tested range shaded, each law's median curve and "
                       "5–95 % band with noise (excluded laws dotted), the model average and its required capacity "
                       "(dashed), the asked range or point. Read: how fast the laws' bands spread apart beyond the "
                       "tested range — that spread is the sizing risk.",
        sizing=sizing, figures=by_section,
        footer=f"Generated by bayesfric in {outcome.seconds:.0f} s{_unit_seconds(outcome)}. Rerun: " + (
            f"bayesfric study {outcome.study.path}" if outcome.study.path.is_file()
            else f"bayesfric.run({outcome.study.path}) from Python"),
    )
    present = {"claims": rep.claims is not None, "trajectories": bool(by_section.get("trajectories")),
               "sizing": bool(sizing)}
    rep.sections = [(k, h) for k, h in SECTIONS if present.get(k, True)]
    return rep


def _unit_seconds(outcome) -> str:
    """``" (units computed in this run: 3 s; reused: 12 units, 812 s of computing saved)"``, from
    the runner's ``unit_seconds``; empty without it."""
    seconds = outcome.unit_seconds
    if seconds is None:
        return ""
    text = f" (units computed in this run: {seconds.computed:.0f} s"
    if seconds.reused:
        text += f"; reused from earlier runs: {seconds.reused} units, {seconds.saved:.0f} s of computing saved"
        if seconds.unknown:
            text += f" ({seconds.unknown} of them stored without their seconds)"
    return text + ")"
