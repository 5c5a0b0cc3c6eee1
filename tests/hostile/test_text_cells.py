"""User text in CSV, Markdown and HTML cells and in figures (issue 27).

Every CSV bayesfric writes goes through :func:`bayesfric.csvout.write_csv`, which neutralises a
text cell starting with ``=``, ``+``, ``-``, ``@``, tab or carriage return (OWASP, CSV injection)
and leaves numbers alone; a ``|`` or a line break in a label cannot break a ``summary.md`` table;
``report.html`` escapes everything; a ``$`` in a figure's text is a dollar, not mathtext. Fast tests
drive the writer and the Markdown escaping; one slow
test runs a study whose labels, title, claim and sizing texts are all hostile and reads back every
file it wrote.
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import bayesfric
from bayesfric.csvout import FORMULA_START, neutralise, write_csv
from bayesfric.pipeline.runner import run_study
from bayesfric.report.summary import md_text
from bayesfric.report.tables import format_table

INJECTIONS = ["=cmd|' /C calc'!A0", "+1+1", "-2+3", "@SUM(1+1)", "\t=1", "\r=1", "=HYPERLINK(\"http://x\",\"y\")"]
NUMBERS = ["-0.5", "-1e3", "+2", "-0.500", "12.345", "-.5"]


def _cells(path: Path) -> list[str]:
    with path.open(newline="", encoding="utf-8") as fh:
        return [cell for row in csv.reader(fh) for cell in row]


def _inert(cell: str) -> bool:
    """What a spreadsheet will not evaluate: no formula start, or a plain decimal number."""
    return not cell.startswith(FORMULA_START) or re.fullmatch(r"[-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?", cell)


@pytest.mark.parametrize("text", INJECTIONS)
def test_text_starting_a_formula_gets_a_quote(text):
    assert neutralise(text) == "'" + text


@pytest.mark.parametrize("value", NUMBERS + [-0.5, 3, True, math.nan, -math.inf, "plain", "a=b", "", None])
def test_numbers_and_plain_text_are_unchanged(value):
    assert neutralise(value) is value


@pytest.mark.parametrize("form", ["records", "rows", "frame"])
def test_every_writer_form_neutralises_text_and_keeps_numbers(tmp_path, form):
    table = {"label": INJECTIONS, "estimate": [-0.5 * i for i in range(len(INJECTIONS))]}
    header = list(table)
    rows = [list(r) for r in zip(*table.values(), strict=True)]
    data = {"records": [dict(zip(header, r, strict=True)) for r in rows], "rows": rows,
            "frame": pd.DataFrame(table)}[form]
    path = write_csv(tmp_path / "t.csv", data, header=header if form == "rows" else None)
    with path.open(newline="", encoding="utf-8") as fh:
        back = list(csv.DictReader(fh))
    assert [r["label"] for r in back] == ["'" + t for t in INJECTIONS]
    assert [float(r["estimate"]) for r in back] == table["estimate"]  # -0.5 stays a number
    assert all(_inert(c) for c in _cells(path))


def test_a_column_name_is_a_cell_too(tmp_path):
    write_csv(tmp_path / "t.csv", [{"=1+1": 1.0, "penalty/pt -x": 2.0}])
    assert _cells(tmp_path / "t.csv")[:2] == ["'=1+1", "penalty/pt -x"]


def test_no_module_writes_csv_but_csvout():
    """One writer: no other module of the package calls a CSV writer of its own."""
    root = Path(bayesfric.__file__).parent
    pattern = re.compile(r"\.to_csv\(|csv\.writer\(|csv\.DictWriter\(|np\.savetxt\(")
    offenders = [str(p.relative_to(root)) for p in root.rglob("*.py")
                 if p.name != "csvout.py" and pattern.search(p.read_text(encoding="utf-8"))]
    assert offenders == []


@pytest.mark.parametrize("label", ["a | b", "line\nbreak", "a \\| b", "x|y\r\n|z|", "`|`"])
def test_markdown_cells_cannot_break_a_table(label):
    table = format_table([md_text(h, inline=True) for h in ["law", label]],
                         [[md_text(label, inline=True), md_text("1.0", inline=True)]], markdown=True)
    lines = table.splitlines()
    assert len(lines) == 3  # header, rule, one row: no line break escaped the cell
    counts = {len(re.findall(r"(?<!\\)\|", line)) for line in lines}
    assert counts == {len(re.findall(r"(?<!\\)\|", lines[1]))}  # every line has the rule's column bars


STUDY = """[study]
name = "tiny"
title = "=HYPERLINK(\\"http://x\\",\\"y\\") | t\\nwo <img src=x onerror=alert(1)>"
question = "@SUM(1+1) | a | b |\\nnew row"
[data]
dataset = "bench.csv"
[sampler]
draws = 200
tune = 200
chains = 2
[[laws]]
name = "coulomb"
[[laws]]
name = "coulomb_viscous"
[compare]
loo = true
evidence = false
[[compare.blocked]]
axis = "velocity"
threshold = 1.5
label = "=cmd|' /C calc'!A0 | x\\nnext <b>bold</b> $x^$"
[[sizing]]
label = "-2+3 @SUM(A1) | y $\\\\frac$"
at = { velocity = "1..3 rad/s" }
capacity = "40 N*m"
[[claims]]
text = "@SUM(1+1)*cmd|' /C calc'!A0"
source = "+1 | row\\nbreak"
kind = "best"
law = "coulomb_viscous"
metric = "elpd_loo"
"""
META = """[dataset]
name = "bench"
provenance = "simulated"
source = "=1+1 | test"
[columns.speed]
role = "input"
quantity = "velocity"
unit = "rad/s"
[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
"""


@pytest.mark.slow
def test_a_study_with_hostile_text_writes_inert_csv_intact_markdown_and_escaped_html(tmp_path):
    v = np.linspace(0.1, 2.0, 40)
    y = 2.0 + 0.5 * v + np.random.default_rng(0).normal(0, 0.05, v.size)
    (tmp_path / "bench.csv").write_text("speed,torque\n" + "".join(f"{a},{b}\n" for a, b in zip(v, y, strict=True)))
    (tmp_path / "bench.toml").write_text(META)
    (tmp_path / "s.toml").write_text(STUDY)
    folder = run_study(tmp_path / "s.toml", out_root=tmp_path / "reports")
    written = sorted(p.name for p in folder.glob("*.csv"))
    assert {"scores.csv", "ranking.csv", "parameters.csv", "timings.csv", "claims.csv", "sizing.csv"} <= set(written)
    for name in written:
        bad = [c for c in _cells(folder / name) if not _inert(c)]
        assert bad == [], f"{name}: {bad[:3]}"
    cells = {c for name in written for c in _cells(folder / name)}
    assert "'@SUM(1+1)*cmd|' /C calc'!A0" in cells and "'+1 | row\nbreak" in cells  # claims.csv
    assert any(c.startswith("'=cmd|' /C calc'!A0") for c in cells)  # the blocked label (scores, timings)
    summary = (folder / "summary.md").read_text(encoding="utf-8")
    for block in re.findall(r"(?:^\|.*\n)+", summary, flags=re.M):  # every Markdown table
        bars = {len(re.findall(r"(?<!\\)\|", line)) for line in block.splitlines()}
        assert len(bars) == 1, block
    html = (folder / "report.html").read_text(encoding="utf-8")
    assert "<img src=x" not in html and "<b>bold</b>" not in html and "&lt;img src=x" in html
    frame = pd.read_csv(io.StringIO((folder / "scores.csv").read_text(encoding="utf-8")))
    assert pd.api.types.is_float_dtype(frame["estimate"])  # numbers stay numbers
