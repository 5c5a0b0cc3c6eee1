"""Write a study's reports: summary.md, ranking.csv, parameters.csv, sizing.csv (when the study asks
sizing questions) and a self-contained report.html.

Every string that comes from the user, the data or a law (titles, questions, labels, findings,
names, units, sources) is written as literal text: Markdown-escaped in ``summary.md``
(:func:`md_text`, :func:`md_code`) and HTML-escaped in ``report.html`` (Jinja autoescape).
"""

from __future__ import annotations

import base64
import csv
import io
import math
import re
from pathlib import Path
from urllib.parse import quote

import jinja2

from bayesfric.report import sizing as sizing_report
from bayesfric.report.figures import provenance_label
from bayesfric.report.tables import format_table, parameter_rows
from bayesfric.study.outcome import StudyOutcome

__all__ = ["ranking_rows", "write_reports", "md_text", "md_code"]

_MD_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
_MD_SPECIAL = re.compile(r"([\\`*_\[\]<>&|#~])")
_MD_BLOCK_START = re.compile(r"^(\s*)(\d+(?=[.)])|[-+=])")


def md_text(value: object, inline: bool = False) -> str:
    """``value`` as literal Markdown text on one line.

    Control characters (newlines included) become spaces; the characters that start inline
    markup, HTML or entities (``\\ ` * _ [ ] < > & | # ~``) are backslash-escaped; unless
    ``inline`` (a table cell), a leading ``-``, ``+``, ``=`` or ``1.`` that would start a list or
    heading is escaped too.
    """
    text = _MD_SPECIAL.sub(r"\\\1", _MD_CONTROL.sub(" ", str(value)))
    if inline:
        return text
    match = _MD_BLOCK_START.match(text)
    if match and match.group(2).isdigit():  # "1." or "1)": escape the delimiter
        end = match.end()
        return text[:end] + "\\" + text[end:]
    return _MD_BLOCK_START.sub(r"\1\\\2", text, count=1) if match else text


def md_code(value: object) -> str:
    """``value`` as a Markdown code span (fence longer than any backtick run inside it)."""
    text = _MD_CONTROL.sub(" ", str(value))
    fence = "`" * (max((len(r) for r in re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") else ""
    return f"{fence}{pad}{text}{pad}{fence}"


def _md_finding(text: str) -> str:
    """A finding: literal text except its ``**bold**`` markers (the runner's only markup)."""
    return "**".join(md_text(part, inline=i > 0) for i, part in enumerate(text.split("**")))


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    return format_table([md_text(h, inline=True) for h in header],
                        [[md_text(c, inline=True) for c in r] for r in rows], markdown=True)


def _num(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}f}" if isinstance(x, float | int) and math.isfinite(x) else "–"


def ranking_rows(out: StudyOutcome) -> tuple[list[str], list[list[str]], list[dict]]:
    """The ranking table: header, formatted rows, and raw records (for CSV).

    Rows are ordered by the first blocked-extrapolation scheme (the question the study asks),
    falling back to LOO; unreliable fits sink to the bottom and are marked.
    """
    estimators = sorted({k for w in out.laws for k in w.evidence})
    weight_keys = sorted({k for w in out.laws for k in w.weights})
    header = ["law", "k", "diagnostics"]
    header += [f"log Z ({e})" for e in estimators] + (["|ΔlogZ|"] if len(estimators) > 1 else [])
    header += ["elpd LOO", "p_loo", "Pareto k>thr"]
    for s in out.schemes:
        header.append(f"elpd {s}")
        if s in out.blocked:
            header.append(f"penalty/pt {s}")
    header += [f"weight {k}" for k in weight_keys] + ["flags"]

    key = out.blocked[0] if out.blocked else None

    def sort_key(w):
        value = w.cv[key].value if key and key in w.cv else w.loo.value
        return (not w.reliable, -(value if math.isfinite(value) else -1e300))

    rows, records = [], []
    for w in sorted(out.laws, key=sort_key):
        k = sum(max(1, math.prod(p.shape)) for p in w.law.params.values())
        row = [w.name, str(k), "passed" if w.reliable else "FAILED"]
        rec: dict = {"law": w.name, "n_params": k, "diagnostics_passed": w.reliable,
                     "rhat_max": w.verdict.rhat_max, "ess_bulk_min": w.verdict.ess_bulk_min}
        for e in estimators:
            est = w.evidence.get(e)
            row.append(est.fmt(3) if est else "–")
            rec[f"log_z_{e}"], rec[f"log_z_{e}_error"] = (est.value, est.error) if est else (math.nan, math.nan)
        if len(estimators) > 1:
            row.append(_num(abs(w.evidence_disagreement), 3))
            rec["evidence_disagreement"] = abs(w.evidence_disagreement)
        row += [w.loo.fmt(1), _num(w.p_loo, 1), f"{w.n_high_k} (max {_num(w.pareto_k_max)})"]
        rec.update(elpd_loo=w.loo.value, elpd_loo_se=w.loo.error, p_loo=w.p_loo, n_high_k=w.n_high_k,
                   pareto_k_max=w.pareto_k_max)
        for s in out.schemes:
            est = w.cv.get(s)
            text = est.fmt(1) if est else "–"
            if est and not w.cv_reliable.get(s, True):
                text += " ⚠"
            row.append(text)
            rec[f"elpd[{s}]"], rec[f"se[{s}]"] = (est.value, est.error) if est else (math.nan, math.nan)
            if s in out.blocked:
                row.append(_num(w.penalty.get(s, math.nan), 3))
                rec[f"penalty_per_point[{s}]"] = w.penalty.get(s, math.nan)
        for kw in weight_keys:
            row.append(_num(w.weights.get(kw, math.nan), 3))
            rec[f"weight[{kw}]"] = w.weights.get(kw, math.nan)
        row.append("; ".join(w.flags) or "–")
        rec["flags"] = "; ".join(w.flags)
        rows.append(row)
        records.append(rec)
    return header, rows, records


def _parameter_records(out: StudyOutcome) -> list[dict]:
    records = []
    for w in out.laws:
        for r in parameter_rows(w.fit, w.law):
            records.append({"law": w.name, "parameter": r.name, "unit": r.unit, "mean": r.mean, "sd": r.sd,
                            "q05": r.q05, "q95": r.q95, "r_hat": r.r_hat, "ess_bulk": r.ess_bulk,
                            "diagnostics_passed": w.reliable, "meaning": r.meaning})
    return records


def _write_csv(path: Path, records: list[dict]) -> None:
    if not records:
        path.write_text("")
        return
    fields = list(dict.fromkeys(k for r in records for k in r))
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        writer.writerows(records)


def _markdown(out: StudyOutcome, header, rows, figures: list[Path]) -> str:
    st = out.study
    ds = out.data
    md = md_text
    lines = [f"# {md(st.title)}", "", f"> **{md(provenance_label(ds), inline=True)}**", ""]
    if st.question:
        lines += [f"**Question.** {md(st.question, inline=True)}", ""]
    lines += ["## Data", "",
              f"- data set: {md_code(ds.attrs.get('name'))} — {md(ds.attrs.get('title', ''), inline=True)}",
              f"- provenance: **{md(ds.attrs.get('provenance'), inline=True)}**; source: "
              f"{md(ds.attrs.get('source'), inline=True)}",
              f"- {ds.sizes['obs']} observations; selection: {md(ds.attrs.get('selection', 'all rows'), inline=True)}; "
              f"content hash {md(ds.attrs.get('data_hash'), inline=True)}",
              f"- noise model: {md(st.noise.kind, inline=True)}"
              + (f", partial-pooled offsets per {md_code(st.noise.group)}" if st.noise.group else ""),
              f"- sampler: {md(st.sampler, inline=True)}", ""]
    lines += ["## Findings", ""] + [f"- {_md_finding(f)}" for f in out.findings] + [""]
    lines += ["## Ranking", "",
              "Ordered by the first blocked-extrapolation scheme (elpd on held-out points outside the "
              "training envelope; higher is better). *penalty/pt* = (elpd_LOO − elpd_blocked) per held-out "
              "point, on the same points: how much worse the law predicts outside the tested envelope than "
              "inside it. Weights exclude fits that failed the diagnostics gate"
              + (" (the study asked to include them)" if st.include_failed else "") + ". ⚠ = a fold failed the gate.",
              "", _md_table(header, rows), ""]
    if out.ranking_sensitivity:
        lines += [f"**Prior sensitivity of the ranking.** {md(out.ranking_sensitivity, inline=True)}", ""]
    lines += ["## Parameters", ""]
    for w in out.laws:
        lines += [f"### {md(w.name)} — {md(w.law.summary, inline=True)}", "",
                  f"source: {md(w.law.source, inline=True)}; diagnostics: {md(w.verdict, inline=True)}", ""]
        if w.law.notes:
            lines += [f"*Identifiability:* {md(w.law.notes, inline=True)}", ""]
        prow = [[r.name, r.unit, f"{r.mean:.4g}", f"{r.sd:.3g}", f"{r.q05:.4g} … {r.q95:.4g}", f"{r.r_hat:.3f}",
                 f"{r.ess_bulk:.0f}"] for r in parameter_rows(w.fit, w.law)]
        lines += [_md_table(["parameter", "unit", "mean", "sd", "90 % interval", "R-hat", "ESS"], prow), ""]
        extras = []
        if math.isfinite(w.prior_implausible):
            extras.append(f"prior draws with unphysical friction: {w.prior_implausible:.1%}")
        if math.isfinite(w.loo_pit_pvalue):
            extras.append(f"LOO-PIT uniformity p = {w.loo_pit_pvalue:.3f}")
        if w.prior_sensitivity:
            extras.append(f"prior sensitivity: {w.prior_sensitivity}")
        if w.high_k_handling:
            extras.append(w.high_k_handling)
        lines += [f"- {md(e)}" for e in extras] + [f"- fit file: {md_code('fits/' + w.fit_file.name)}", ""]
    if out.sizing is not None:
        lines += _sizing_markdown(out, figures)
    others = [p for p in figures if p not in _sizing_figures(out, figures).values()]
    lines += ["## Figures", ""] + [f"![{md(p.stem, inline=True)}](figures/{quote(p.name)})" for p in others] + [""]
    lines += [f"*Generated by bayesfric in {out.seconds:.0f} s. Rerun: {md_code(f'bayesfric study {st.path}')}.*", ""]
    return "\n".join(lines)


def _sizing_figures(out: StudyOutcome, figures: list[Path]) -> dict[int, Path]:
    """Question index -> its fan figure (``figures/sizing_<i + 1>.png``, drawn by the runner)."""
    if out.sizing is None:
        return {}
    by_name = {p.name: p for p in figures}
    names = {i: f"sizing_{i + 1}.png" for i in range(len(out.sizing.answers))}
    return {i: by_name[name] for i, name in names.items() if name in by_name}


def _sizing_markdown(out: StudyOutcome, figures: list[Path]) -> list[str]:
    md = md_text
    names = {i: p.name for i, p in _sizing_figures(out, figures).items()}
    lines = ["## Sizing", "",
             "Friction opposes motion, so sizing works on magnitudes |T|. *Mean function*: the law's curve with "
             "parameter uncertainty only; *with noise*: plus the fit's observation noise (what a drive meets). "
             "Per-point values for every law and point: `sizing.csv`.", ""]
    for sec in sizing_report.sections(out.sizing, names):
        lines += [f"### {md(sec.title)}", ""]
        lines += [f"- {md(line)}" for line in sec.lines]
        lines += [f"- **WARNING:** {md(w, inline=True)}" for w in sec.warnings] + [""]
        for caption, header, rows in sec.tables:
            lines += [f"*{md(caption, inline=True)}*", "", _md_table(header, rows), ""]
        if sec.figure:
            lines += [f"![{md(sec.title, inline=True)}](figures/{quote(sec.figure)})", ""]
    return lines


_HTML = jinja2.Template("""<!doctype html><html><head><meta charset="utf-8"><title>{{ title }}</title>
<style>body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em}
table{border-collapse:collapse;font-size:12px;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 6px}
th{background:#f0f0f0}.banner{background:#fff3cd;border:1px solid #e0c060;padding:.6em;font-weight:bold}
img{max-width:100%}</style></head><body>
<h1>{{ title }}</h1><div class="banner">{{ banner }}</div>
{% if question %}<p><b>Question.</b> {{ question }}</p>{% endif %}
<h2>Findings</h2><ul>{% for f in findings %}<li>{{ f }}</li>{% endfor %}</ul>
<h2>Ranking</h2><table><tr>{% for h in header %}<th>{{ h }}</th>{% endfor %}</tr>
{% for r in rows %}<tr>{% for c in r %}<td>{{ c }}</td>{% endfor %}</tr>{% endfor %}</table>
<h2>Parameters</h2>{% for law in laws %}<h3>{{ law.name }}</h3><p>{{ law.text }}</p>
<table><tr>{% for h in pheader %}<th>{{ h }}</th>{% endfor %}</tr>
{% for r in law.rows %}<tr>{% for c in r %}<td>{{ c }}</td>{% endfor %}</tr>{% endfor %}</table>{% endfor %}
{% if sizing %}<h2>Sizing</h2><p>{{ sizing_intro }}</p>{% for sec in sizing %}<h3>{{ sec.title }}</h3>
<ul>{% for line in sec.lines %}<li>{{ line }}</li>{% endfor %}
{% for w in sec.warnings %}<li class="warn"><b>WARNING:</b> {{ w }}</li>{% endfor %}</ul>
{% for t in sec.tables %}<p><i>{{ t[0] }}</i></p><table><tr>{% for h in t[1] %}<th>{{ h }}</th>{% endfor %}</tr>
{% for r in t[2] %}<tr>{% for c in r %}<td>{{ c }}</td>{% endfor %}</tr>{% endfor %}</table>{% endfor %}
{% if sec.figure %}<p><img src="data:image/png;base64,{{ sec.figure }}"></p>{% endif %}{% endfor %}{% endif %}
<h2>Figures</h2>{% for f in figures %}<p><img src="data:image/png;base64,{{ f }}"></p>{% endfor %}
</body></html>""", autoescape=True)


def write_reports(out: StudyOutcome, folder: Path, figures: list[Path]) -> None:
    """Write summary.md, ranking.csv, parameters.csv, sizing.csv (with sizing questions) and
    report.html into ``folder``."""
    header, rows, records = ranking_rows(out)
    (folder / "summary.md").write_text(_markdown(out, header, rows, figures))
    _write_csv(folder / "ranking.csv", records)
    _write_csv(folder / "parameters.csv", _parameter_records(out))
    sizing_sections = []
    fans = _sizing_figures(out, figures)
    if out.sizing is not None:
        _write_csv(folder / "sizing.csv", sizing_report.records(out.sizing))
        encoded_fans = {i: base64.b64encode(p.read_bytes()).decode() for i, p in fans.items()}
        sizing_sections = sizing_report.sections(out.sizing, encoded_fans)
    pheader = ["parameter", "unit", "mean", "sd", "5 %", "95 %", "R-hat", "ESS"]
    laws = [{"name": w.name, "text": f"{w.law.summary} — {w.law.source}. Diagnostics: {w.verdict}",
             "rows": [[r.name, r.unit, f"{r.mean:.4g}", f"{r.sd:.3g}", f"{r.q05:.4g}", f"{r.q95:.4g}",
                       f"{r.r_hat:.3f}", f"{r.ess_bulk:.0f}"] for r in parameter_rows(w.fit, w.law)]}
            for w in out.laws]
    encoded = []
    for p in (p for p in figures if p not in fans.values()):
        buf = io.BytesIO(p.read_bytes())
        encoded.append(base64.b64encode(buf.getvalue()).decode())
    html = _HTML.render(title=out.study.title, banner=provenance_label(out.data), question=out.study.question,
                        findings=out.findings, header=header, rows=rows, pheader=pheader, laws=laws,
                        figures=encoded, sizing=sizing_sections,
                        sizing_intro="Friction opposes motion, so sizing works on magnitudes |T|. Mean function: the "
                                     "law's curve with parameter uncertainty only; with noise: plus the fit's "
                                     "observation noise (what a drive meets). Every law and point: sizing.csv.")
    (folder / "report.html").write_text(html)
