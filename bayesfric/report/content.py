"""The content model of a study report: every section of ``summary.md`` and ``report.html`` as
plain data, built once from the study's result tree (:mod:`bayesfric.study.tree`, read through
:class:`~bayesfric.report.view.TreeView`), the claims' results and the sizing result; the two
templates (``templates/summary.md.j2``, ``templates/report.html.j2``) only lay it out. Nothing here
computes a statistic: numbers come from the tree's nodes or the fits' posterior summaries
(:func:`bayesfric.report.tables.parameter_rows` of ``/fits/<law>``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from bayesfric import identifiability
from bayesfric.report import findings as fd
from bayesfric.report import sizing as sizing_report
from bayesfric.report.blocks import FigureRef, Table
from bayesfric.report.figures import provenance_text
from bayesfric.report.ranking import extrapolation_table, law_flags, loo_numbers, ranking_records, ranking_table
from bayesfric.report.tables import parameter_rows, retry_note
from bayesfric.report.typeset import fmt, unit
from bayesfric.report.view import TreeView
from bayesfric.study.tree import sensitivity_of

if TYPE_CHECKING:
    from bayesfric.sizing.result import SizingAnswer
    from bayesfric.study.claimspec import ClaimResult

__all__ = ["Table", "FigureRef", "LawSection", "Report", "build", "SECTIONS", "ranking_records", "parameter_records",
           "claim_records", "TreeView"]

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
    structure: Table | None = None
    identifiability: Table | None = None


def _num(x: Any, digits: int = 2) -> str:
    return fmt(x, digits=digits) if isinstance(x, float | int) and math.isfinite(x) else "–"


def _text(value: Any) -> str:
    """A text cell of a claim record: an empty cell read back from the tree (NaN) is ``""``."""
    return value if isinstance(value, str) else ""


def _claims(records: list[dict]) -> Table | None:
    """The claims table from the claims' records (``claims.csv``, the tree's ``/claims``)."""
    if not records:
        return None
    rows, warn = [], []
    for i, r in enumerate(records):
        pct = r["kind"] == "ratio"

        def show(x: float, pct: bool = pct) -> str:
            if math.isinf(x):
                return "+∞" if x > 0 else "−∞"
            return "–" if not math.isfinite(x) else (f"{x:+.0%}" if pct else f"{x:.3g}")

        if r["kind"] == "best":
            winner = _text(r["winner"])
            claimed, says = f"best: {r['law']}", (f"best: {winner}" if winner else "–")
        else:
            claimed = f"{show(r['expect_low'])} … {show(r['expect_high'])}"
            interval = "90 % interval" if r["kind"] != "score" else "± 1 se"
            says = (f"{show(r['value'])} ({interval} {show(r['low'])} … {show(r['high'])})"
                    if math.isfinite(r["low"]) else show(r["value"]))
        why = _text(r["why"])
        basis = "evidence" if r["evidence"] else "pipeline check, not evidence"
        rows.append([r["claim"], _text(r["source"]), basis, claimed, says, r["verdict"] + (f": {why}" if why else "")])
        if r["verdict"] != "reproduced":
            warn.append(i)
    caption = ("Each claim is declared in the study file ([[claims]]) and computed from the posterior: ratios are "
               "mean-function predictions of the fitted law (posterior median, 90 % interval); the claimed range is "
               "the study author's reading of the paper. Verdict: reproduced when the posterior median (or the "
               "winner) is in the claimed range. Basis: a \"pipeline check, not evidence\" is a statement the "
               "reconstructed data were built to satisfy — its verdict checks the reconstruction and the pipeline, "
               "not the paper; \"evidence\" was not used to build the data.")
    return Table(caption, ["claim", "source", "basis", "claimed", "posterior says", "verdict"], rows, warn)


def claim_records(claims: list[ClaimResult]) -> list[dict]:
    """The rows of ``claims.csv`` (the tree's ``/claims``), one per claim with its result; the
    claims table and the summary's claim warnings read the same rows."""
    return [{"claim": r.claim.text, "source": r.claim.source, "basis": r.claim.basis or "evidence",
             "evidence": not r.claim.pipeline_check, "kind": r.claim.kind, "law": r.claim.law,
             "reference": r.claim.reference,
             "expect_low": r.claim.expect[0], "expect_high": r.claim.expect[1], "value": r.value, "low": r.lo,
             "high": r.hi, "winner": r.winner, "verdict": r.verdict, "why": r.why} for r in claims]


def parameter_records(t: TreeView) -> list[dict]:
    """The rows of ``parameters.csv``: every law's posterior summary per scalar parameter
    (:func:`bayesfric.report.tables.parameter_rows` of ``/fits/<law>``), computed once; the law
    sections lay out the same rows."""
    records = []
    for name in t.laws:
        for r in parameter_rows(t.fit(name), t.law_object(name)):
            records.append({"law": name, "parameter": r.name, "unit": r.unit, "mean": r.mean, "sd": r.sd,
                            "q05": r.q05, "q95": r.q95, "r_hat": r.r_hat, "ess_bulk": r.ess_bulk,
                            "diagnostics_passed": t.passed(name), "meaning": r.meaning})
    return records


def _law_sections(t: TreeView, parameters: list[dict], figures: dict[str, FigureRef]) -> list[LawSection]:
    out = []
    for name in t.laws:
        rows = [[r["parameter"], unit(r["unit"]), fmt(r["mean"], r["sd"], pm=False), fmt(r["sd"], r["sd"], pm=False),
                 f"{fmt(r['q05'], r['sd'], pm=False)} … {fmt(r['q95'], r['sd'], pm=False)}", f"{r['r_hat']:.3f}",
                 f"{r['ess_bulk']:.0f}", r["meaning"]] for r in parameters if r["law"] == name]
        table = Table("", ["parameter", "unit", "mean", "sd", "90 % interval", "R-hat", "ESS", "meaning"], rows)
        law = t.law_object(name)
        out.append(LawSection(name, law.summary, law.source, t.flag(name, "verdict") + retry_note(t.fit(name)),
                              law.notes or "", table, figures.get(name)))
    return out


def _checks(t: TreeView) -> Table:
    rows, warn = [], []
    for i, name in enumerate(t.laws):
        loo, c = loo_numbers(t.law(name)), t.checks.sel(law=name)
        checked, pit_ok, flags = bool(c["checked"]), bool(c["loo_pit_ok"]), law_flags(t.law(name))
        shape = str(c["loo_pit_direction"].values) or "miscalibrated"
        psense = str(c["psense"].values)
        sensitivity = ("psense flags " + psense if psense else "no parameter flagged by power-scaling (psense)")
        implausible = float(c["prior_implausible"])
        rows.append([name, t.gate(name), _num(loo["p_loo"], 2),
                     f"{loo['n_high_k']} (max {_num(loo['pareto_k_max'])})",
                     _num(float(c["loo_pit_pvalue"]), 2) + ("" if pit_ok else f" ⚠ {shape}"),
                     f"{implausible:.1%}" if math.isfinite(implausible) else "–",
                     sensitivity if checked else "–", "; ".join(flags) or "–", str(t.fit(name).attrs["fit_file"])])
        if not t.passed(name) or not pit_ok or flags:
            warn.append(i)
    header = ["law", "diagnostics", "p_loo", "Pareto k > thr", "LOO-PIT p", "unphysical prior draws",
              "prior sensitivity", "flags", "fit file"]
    return Table("Checks per law. LOO-PIT: two tests of whether each point's leave-one-out predictive is calibrated; "
                 "⚠ = the PIT values' ECDF leaves its simultaneous 99 % band (the test that decides, sensitive to a "
                 "local departure), with the direction read from the PIT values (bayesfric.compare.pit: too narrow, "
                 "too wide, biased); 'LOO-PIT p' is the Kolmogorov–Smirnov p-value of the same values, for reference "
                 "(a whole-curve test: a ⚠ beside p > 0.05 means the band caught what KS averaged out). Each flagged "
                 "law's LOO-PIT figure follows. Unphysical prior draws: the share of draws from the priors whose "
                 "friction has the wrong sign or is not finite somewhere on the data or the tested envelope (a "
                 "weakly informative prior allows some; a large share means the priors, not the data, may shape "
                 "extrapolation)." + checks_note(t), header, rows, warn)


def _structure(t: TreeView) -> Table | None:
    """Every residual-structure test of every law (:mod:`bayesfric.compare.structure`); None
    when none was run (a tree made before them, a data set with no other column)."""
    rows, warn = [], []
    for name in t.laws:
        for c in t.structure(name):
            tested = c.df > 0 and math.isfinite(c.p_value)
            p = ("< 1e-16" if c.p_value <= 0 else f"{c.p_value:.2g}") if tested else (
                "not testable: " + ("spanned by the law's inputs" if not c.df else "too few rows"))
            if c.flagged:
                warn.append(len(rows))
            size = (f"{fmt(c.effect)} {unit(c.unit)}".strip(), fmt(c.effect_sd, digits=2)) if tested else ("–", "–")
            rows.append([name, c.column, c.kind, *size,
                         p, f"{c.threshold:.2g}", "yes" if c.flagged else "no", c.suggestion if c.flagged else ""])
    if not rows:
        return None
    header = ["law", "column", "kind", "effect", "effect (noise sd)", "F-test p", "flag below", "flagged",
              "what would model it"]
    return Table("Residual structure: each law's residuals against every group column and every recorded input it "
                 "does not read, at the same operating point (F-test over a smooth basis of the law's inputs, "
                 "AR(1)-prewhitened along trajectories; flagged below 5 % / columns tested). ⚠ = the response "
                 "differs between the groups, or trends with the column, beyond the noise model.", header, rows, warn)


def _identifiability_rows(t: TreeView) -> list[dict[str, str]]:
    node = t.tree["identifiability"].to_dataset() if "identifiability" in t.tree.children else None
    return identifiability.checks_of(node)


def _identifiability(t: TreeView) -> Table | None:
    """What the data can determine of each stateful law, measured before fitting
    (:mod:`bayesfric.identifiability`); None without a stateful law."""
    rows = _identifiability_rows(t)
    if not rows:
        return None
    return Table("Identifiability from the data, measured before fitting: what each stateful law's parameters "
                 "need of the data (its notes) against what the data hold, at the law's prior medians on these data. "
                 "⚠ = the data do not determine those parameters (the posterior keeps their prior along a ridge, or "
                 "has several modes); where a reduced variant exists the study ranks it as a companion entry "
                 "([compare] companions).",
                 ["law", "parameters", "needs", "status", "measured", "companion"],
                 [[r["law"], r["params"], r["needs"], r["status"], r["measured"], r["companion"]] for r in rows],
                 [i for i, r in enumerate(rows) if r["status"] == "failed"])


def _identifiability_findings(t: TreeView) -> list[fd.Finding]:
    """One finding per law whose parameters the data do not determine, naming its companion."""
    out = []
    rows = [r for r in _identifiability_rows(t) if r["status"] == "failed"]
    for law in dict.fromkeys(r["law"] for r in rows):
        own = [r for r in rows if r["law"] == law]
        companion = own[0]["companion"]
        out.append(fd.plain(f"{law}: the data do not determine " + "; ".join(f"{r['params']} ({r['measured']})"
                                                                             for r in own)
                            + (f"; its reduced variant {companion} is ranked beside it." if companion else ".")))
    return out


def checks_note(t: TreeView) -> str:
    """The sample the checks read when it was a subsample of the rows ("" when every row)."""
    n = int(t.attrs.get("n_obs", 0))
    pit = np.asarray(t.checks["pit"].values, dtype=float).reshape(len(t.laws), -1)
    read = {int(k) for k in np.isfinite(pit).sum(axis=1) if k > 0}
    if not read or max(read) >= n:
        return ""
    return (f" On data this large (N = {n} rows) LOO-PIT and the prior-power ranking sensitivity read a random "
            f"subsample of {max(read)} of the {n} rows (the rows the subsampled PSIS-LOO scores exactly); the "
            "prior predictive check reads every row.")


def _data_lines(t: TreeView) -> list[str]:
    d, a = t.data, t.attrs
    return [f"data set: {d.get('name')} — {d.get('title', '')}",
            f"provenance: {d.get('provenance')}; source: {d.get('source')}",
            f"{a['n_obs']} observations; selection: {d.get('selection', 'all rows')}; "
            f"content hash {d.get('data_hash')}",
            f"noise model: {a['noise']}", f"sampler: {a['sampler']}"]


def _claim_warnings(records: list[dict]) -> list[fd.Finding]:
    """The claims' verdicts in the summary: evidence and pipeline checks counted apart."""
    out = []
    for pipeline, what in ((False, "claim(s) of the source paper"),
                           (True, "pipeline check(s) (statements the reconstructed data were built to satisfy)")):
        bad = [r for r in records if r["verdict"] == "not reproduced" and (not r["evidence"]) == pipeline]
        if bad:
            out.append(fd.plain(f"{len(bad)} {what} NOT reproduced by the posterior (see the claims section).",
                                warning=True))
    return out


def build(t: TreeView, parameters: list[dict], figures: list[FigureRef], sizing_figures: dict[int, str],
          claims: list[dict] | None = None, sizing: SizingAnswer | None = None,
          service: tuple[list, list] | None = None) -> Report:
    """The report's content model, from the study's result tree (``t``: ranking, findings, checks,
    law sections, data lines and footer read it alone, :mod:`bayesfric.study.tree`), the
    parameter and claim rows the tree keeps as ``/parameters`` and ``/claims``
    (:func:`parameter_records`, :func:`claim_records`), the figures drawn and the sizing result
    (``sizing_figures``: question index -> the fan's reference as the rendering wants it, a file
    name or an encoded image); ``service`` the time-to-exceed questions' sections and headlines."""
    claims = claims or []
    ranking, order = ranking_table(t)
    by_section: dict[str, list[FigureRef]] = {}
    pair = {}
    for f in figures:
        if f.section.startswith("parameters:"):
            pair[f.section.split(":", 1)[1]] = f
        else:
            by_section.setdefault(f.section, []).append(f)
    findings = fd.findings(t) + _identifiability_findings(t)
    sections = []
    summary = fd.summary_block(t, sizing, _claim_warnings(claims))
    if sizing is not None:
        headlines = sizing_report.headlines(sizing)
        findings += headlines
        summary.answers += headlines  # the sizing answer belongs to the decision block too
        sections = sizing_report.sections(sizing, sizing_figures)
    if service is not None:  # time-to-exceed questions (bayesfric.report.service): (sections, headlines)
        sections += service[0]
        findings += service[1]
        summary.answers += service[1]
    rep = Report(
        title=str(t.attrs["title"]), banner=provenance_text(t.data),
        reconstructed=t.data.get("provenance") == "reconstructed",
        summary=summary, findings=findings,
        claims=_claims(claims), ranking=ranking,
        ranking_note="Weights exclude fits that failed the diagnostics gate"
                     + (" (the study asked to include them)." if t.attrs["include_failed"] else "."),
        sensitivity=fd.sensitivity_sentence(sensitivity_of(t.tree)), extrapolation=extrapolation_table(t, order),
        laws=_law_sections(t, parameters, pair), data_lines=_data_lines(t), checks=_checks(t),
        sizing_intro="Friction opposes motion, so sizing works on magnitudes |T|. Mean function: the law's curve "
                     "with parameter uncertainty only; with noise: plus the fit's observation noise (what a drive "
                     "meets). Every law and point: sizing.csv.",
        sizing_caption="|friction| against the question's input: tested range shaded, each law's median curve and "
                       "5–95 % band with noise (excluded laws dotted), the model average and its required capacity "
                       "(dashed), the asked range or point. Read: how fast the laws' bands spread apart beyond the "
                       "tested range — that spread is the sizing risk.",
        sizing=sections, figures=by_section, footer=_footer(t.attrs), structure=_structure(t),
        identifiability=_identifiability(t),
    )
    present = {"claims": rep.claims is not None, "trajectories": bool(by_section.get("trajectories")),
               "sizing": bool(sections)}
    rep.sections = [(k, h) for k, h in SECTIONS if present.get(k, True)]
    return rep


def _footer(attrs: dict) -> str:
    """``Generated by bayesfric in 12 s (units computed in this run: 3 s; reused: 12 units, 812 s
    of computing saved). Rerun: ...`` from the tree's root attrs (:func:`bayesfric.study.tree.run_attrs`)."""
    text = f"Generated by bayesfric in {attrs.get('seconds', math.nan):.0f} s"
    if "units_computed_s" in attrs:
        text += f" (units computed in this run: {attrs['units_computed_s']:.0f} s"
        if attrs["units_reused"]:
            text += (f"; reused from earlier runs: {attrs['units_reused']} units, {attrs['units_saved_s']:.0f} s of "
                     "computing saved")
            if attrs["units_unknown"]:
                text += f" ({attrs['units_unknown']} of them stored without their seconds)"
        text += ")"
    path = attrs["study_file"]
    return text + ". Rerun: " + (f"bayesfric study {path}{attrs.get('rerun_options', '')}" if attrs["study_file_exists"]
                                 else f"bayesfric.run({path}) from Python")
