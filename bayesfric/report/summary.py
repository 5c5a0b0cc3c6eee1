"""Write a study's reports: summary.md, report.html (self-contained), ranking.csv, scores.csv,
parameters.csv, sizing.csv (when the study asks sizing questions) and the figures.

Both documents render one content model (:func:`bayesfric.report.content.build`) through the
jinja2 templates in ``bayesfric/report/templates``: they show the same sections and cannot drift.
Every string that comes from the user, the data or a law (titles, questions, labels, findings,
names, units, sources, claims) is written as literal text: Markdown-escaped in ``summary.md``
(:func:`md_text`, :func:`md_code`: a ``|`` or a line break in a table cell cannot break the table),
HTML-escaped in ``report.html`` (jinja2 autoescape), and neutralised in every CSV file
(:func:`bayesfric.csvout.write_csv`: a cell starting with ``=``, ``+``, ``-``, ``@`` is not a formula).
Findings are structured (:class:`bayesfric.report.findings.Finding`): their emphasis is rendered
as ``**…**`` in Markdown and ``<b>`` in HTML, never parsed back from text.
"""

from __future__ import annotations

import base64
import contextlib
import os
import re
import secrets
import shutil
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import quote

import jinja2
import xarray as xr
from markupsafe import Markup, escape

from bayesfric.csvout import write_csv
from bayesfric.errors import UserError
from bayesfric.fsutil import PathError, apply_umask, check_output_folder
from bayesfric.report import service as service_report
from bayesfric.report import sizing as sizing_report
from bayesfric.report.content import Table, TreeView, build, claim_records, parameter_records, ranking_records
from bayesfric.report.findings import Finding
from bayesfric.report.results import RESULTS, result_tree, write_results
from bayesfric.report.stored import (
    LAYOUT,
    content_node,
    figures_node,
    open_results,
    read_content,
    read_figures,
    stored_layout,
    table_records,
)
from bayesfric.report.study_figures import draw
from bayesfric.report.tables import format_table

if TYPE_CHECKING:
    from collections.abc import Mapping

    from bayesfric.sizing.result import SizingAnswer
    from bayesfric.study.claimspec import ClaimResult

__all__ = ["write_reports", "render_report", "rerender", "render", "md_text", "md_code"]

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


def _md_finding(f: Finding) -> str:
    return "".join(f"**{md_text(t, inline=True)}**" if bold else md_text(t, inline=i > 0)
                   for i, (t, bold) in enumerate(f.parts))


def _html_finding(f: Finding) -> Markup:
    return Markup("").join(Markup("<b>{}</b>").format(t) if bold else escape(t) for t, bold in f.parts)


def _md_plain_table(header: list[str], rows: list[list[str]]) -> str:
    return format_table([md_text(h, inline=True) for h in header],
                        [[md_text(c, inline=True) for c in r] for r in rows], markdown=True)


def _md_table(t: Table) -> str:
    rows = [[("⚠ " if i in t.warn and j == 0 and not c.startswith("⚠") else "") + c for j, c in enumerate(r)]
            for i, r in enumerate(t.rows)]
    text = _md_plain_table(t.header, rows)
    return (f"*{md_text(t.caption, inline=True)}*\n\n" + text) if t.caption else text


def _md_figure(f) -> str:
    return f"![{md_text(f.alt, inline=True)}]({quote(f.path)})\n\n*{md_text(f.caption, inline=True)}*\n"


def _environment(markdown: bool, folder: Path) -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.PackageLoader("bayesfric.report", "templates"),
                             autoescape=not markdown, keep_trailing_newline=True, undefined=jinja2.StrictUndefined)
    if markdown:
        env.filters.update(md=md_text, mdi=lambda v: md_text(v, inline=True), mdcode=md_code, finding=_md_finding,
                           urlpath=quote)
        env.globals.update(table=_md_table, plain_table=_md_plain_table, figure=_md_figure)
    else:
        def src(path: str) -> str:  # figures are embedded: the report is one self-contained file
            return "data:image/png;base64," + base64.b64encode((folder / path).read_bytes()).decode()

        env.filters.update(finding=_html_finding, src=src)
    return env


def render(content, folder: Path, markdown: bool) -> str:
    """``summary.md`` (``markdown``) or ``report.html`` text of a content model; figure paths are
    relative to ``folder`` (embedded in the HTML)."""
    name = "summary.md.j2" if markdown else "report.html.j2"
    text = _environment(markdown, folder).get_template(name).render(r=content)
    return re.sub(r"\n{3,}", "\n\n", text) if markdown else text


def write_reports(tree: xr.DataTree, folder: Path, data: xr.Dataset, fits: Mapping[str, xr.DataTree],
                  claims: list[ClaimResult] | None = None, sizing: SizingAnswer | None = None) -> xr.DataTree:
    """Write ``folder/results.nc`` (the study's results as one DataTree,
    :mod:`bayesfric.report.results`, with the report's content, figures and tables) and render
    the report from that file alone (:func:`render_report`): figures, summary.md, report.html,
    ranking.csv, scores.csv, parameters.csv, claims.csv (with ``[[claims]]``) and sizing.csv (with
    sizing questions). ``folder`` is the runner's work folder, installed atomically afterwards.

    Parameters
    ----------
    tree : xarray.DataTree
        The study's result tree (:func:`bayesfric.study.tree.study_tree`, with the run's
        :func:`~bayesfric.study.tree.run_attrs`): every text, table and finding reads it.
    folder : Path
        The report folder (the runner's work folder).
    data : xarray.Dataset
        The study's data set: the figures' points and provenance banner.
    fits : mapping of str to xarray.DataTree
        Each law's full fit: the figures' predictive bands read its posterior-predictive draws,
        which the tree does not keep.
    claims, sizing
        The claims' results (:func:`bayesfric.study.claims.evaluate_claims`) and the sizing
        result, when the study has them.

    Returns
    -------
    xarray.DataTree
        The tree saved as ``results.nc``, with the report's nodes. Every file is rendered from it
        by :func:`render_report`, the function ``bayesfric report results.nc`` calls on the saved
        tree, so a re-rendering gives the same bytes (tested file by file).
    """
    view = TreeView(tree)
    figures, fans = draw(view, data, fits, folder, sizing)
    service = tree["service"] if "service" in tree.children else None
    served = {i: f"figures/{p.name}" for i, p in service_report.draw(service, data, folder).items()}
    parameters, claimed = parameter_records(view), claim_records(claims or [])
    content = build(view, parameters, figures, {i: f"figures/{p.name}" for i, p in fans.items()}, claimed, sizing,
                    (service_report.sections(service, served, len(sizing.answers) if sizing is not None else 0),
                     service_report.headlines(service)))
    tables: dict = {"ranking": ranking_records(view), "parameters": parameters}
    if claimed:
        tables["claims"] = claimed
    if sizing is not None:
        tables["sizing"] = sizing_report.records(sizing)
    tables["score_rows"] = view.table  # law by law, each law's rows in its scorers' order (study.tree._merged)
    extra = {"report": content_node(content), "report/figures": figures_node(folder)}
    tree = result_tree(tree, tables, extra)
    write_results(tree, folder)
    render_report(tree, folder)  # from the tree in memory; the file renders the same (tests/report/test_rerender.py)
    return tree


def render_report(tree: xr.DataTree, folder: Path) -> list[Path]:
    """Render a study's report from its result tree alone into ``folder`` (which must exist): the
    figure files, summary.md, report.html and every CSV table node (:data:`stored.CSV_FILES`).
    Returns the files written.

    Parameters
    ----------
    tree : xarray.DataTree
        A result tree with a stored report (:func:`bayesfric.report.stored.open_results`).
    folder : Path
        The report folder; figures go under ``folder/figures``.
    """
    folder = Path(folder)
    written = []
    for rel, blob in read_figures(tree["report/figures"].to_dataset()).items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_bytes(blob)
        written.append(folder / rel)
    content = read_content(tree["report"].to_dataset())
    for name, markdown in (("summary.md", True), ("report.html", False)):
        (folder / name).write_text(render(content, folder, markdown=markdown), encoding="utf-8")
        written.append(folder / name)
    for node in tree.children.values():
        csv_file = node.attrs.get("csv_file")
        if csv_file:  # every CSV: text cells neutralised (bayesfric.csvout)
            written.append(write_csv(folder / str(csv_file), table_records(node.to_dataset())))
    return written


def rerender(results: str | Path | xr.DataTree, out: str | Path) -> Path:
    """``bayesfric report RESULTS.nc --out FOLDER``: render a study's report again from its
    result tree alone (``results``: its ``results.nc``, or the tree in memory) into the new folder
    ``out`` (with the tree saved as ``results.nc``), atomically: the files go into a hidden folder
    beside ``out``, renamed to ``out`` when complete.

    Raises
    ------
    UserError
        ``results`` is not a result tree with a stored report, or ``out`` exists and is not an
        empty folder, or cannot be created.
    """
    tree = results if isinstance(results, xr.DataTree) else open_results(results)
    if isinstance(results, xr.DataTree) and stored_layout(tree) != LAYOUT:
        raise UserError("the result tree has no stored report (no /report node of layout "
                        f"{LAYOUT}): pass a study's result (bayesfric.run), not a fit")
    out = Path(out)
    try:
        check_output_folder(out)
    except PathError as exc:
        raise UserError(f"--out {exc}") from None
    if out.is_symlink():  # never write through a link (it may lead out of the folder the user sees)
        raise UserError(f"--out {out}: is a link; name a new folder")
    if out.is_dir() and any(out.iterdir()):
        raise UserError(f"--out {out}: exists and is not empty; name a new folder")
    created = [p for p in out.absolute().parents if not p.exists()]  # innermost first: removed on failure
    out.parent.mkdir(parents=True, exist_ok=True)
    work = out.parent / f".{out.name}.{secrets.token_hex(4)}"
    work.mkdir()
    try:
        render_report(tree, work)
        if isinstance(results, xr.DataTree):
            write_results(results, work)
        else:
            shutil.copyfile(results, work / RESULTS)
        apply_umask(work)
        if out.is_dir():
            out.rmdir()  # empty, checked above
        os.rename(work, out)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        for folder in created:  # only the folders this call made, and only while empty
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    return out
