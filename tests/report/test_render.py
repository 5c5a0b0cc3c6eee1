"""summary.md and report.html: one content model, the same sections, every string escaped."""

import re

import pytest

from bayesfric.report.content import SECTIONS
from bayesfric.report.findings import Finding
from bayesfric.study import load_study
from tests.report.fakes import outcome, write_outcome

HOSTILE = '<script>alert(1)</script> **bold** & `code`'


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("render")
    (tmp / "tiny.toml").write_text(
        f'[study]\nname = "tiny"\ntitle = "{HOSTILE}"\nquestion = "Which law? {HOSTILE}"\n'
        '[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\nname = "coulomb_viscous"\n'
        '[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.0\nlabel = "outside"\n'
        f'[[claims]]\ntext = "{HOSTILE}"\nsource = "seed"\nkind = "best"\nlaw = "coulomb"\nmetric = "elpd_loo"\n')
    out = outcome(load_study(tmp / "tiny.toml"), tmp)
    folder = tmp / "report"
    folder.mkdir()
    write_outcome(out, folder)
    return folder


def test_same_sections_in_both_renderings(report):
    md = (report / "summary.md").read_text()
    html = (report / "report.html").read_text()
    md_sections = re.findall(r"^## (.+)$", md, flags=re.M)
    html_ids = re.findall(r'<section id="([a-z]+)"', html)
    expected = [(k, h) for k, h in SECTIONS if k not in ("trajectories", "sizing")]  # no trajectories, no sizing
    assert md_sections == [h for _, h in expected]
    assert html_ids == [k for k, _ in expected]


def test_every_user_string_is_escaped(report):
    html = (report / "report.html").read_text()
    md = (report / "summary.md").read_text()
    assert "<script>" not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "**bold**" not in md and r"\*\*bold\*\*" in md and r"\<script\>" in md


def test_findings_emphasis_is_rendered_not_parsed(report):
    html = (report / "report.html").read_text()
    md = (report / "summary.md").read_text()
    assert "<b>coulomb_viscous</b>" in html and "**coulomb\\_viscous**" in md  # the winner, emphasised
    assert "**coulomb" not in html  # no Markdown markers leak into the HTML


def test_summary_block_answers_recommends_and_ranks(report):
    md = (report / "summary.md").read_text()
    summary = md.split("## What the source paper says")[0]
    assert "**Question.** Which law?" in summary
    assert "Best outside the tested envelope (blocked CV 'outside'): **coulomb\\_viscous**" in summary
    assert "Best inside the tested envelope (PSIS-LOO): **coulomb\\_viscous**" in summary
    assert "Recommended: **coulomb\\_viscous**" in summary
    assert "NOT reproduced" in summary  # the claim 'coulomb is best' fails, and the summary warns


def test_figures_and_csvs_written(report):
    names = {p.name for p in (report / "figures").iterdir()}
    assert {"ranking.png", "penalty.png", "bands_velocity.png", "pairs_coulomb_viscous.png"} <= names
    assert "pairs_coulomb.png" not in names  # one coefficient: no pair plot
    for name in ("ranking.csv", "scores.csv", "claims.csv", "parameters.csv"):
        assert (report / name).stat().st_size > 0
    ranking = (report / "ranking.csv").read_text().splitlines()
    assert ranking[0].startswith("rank,place,law,") and ranking[1].startswith("1,1,coulomb_viscous,")  # first


def test_finding_text_joins_parts():
    f = Finding((("Best: ", False), ("law", True), (".", False)))
    assert f.text == "Best: law."


def test_templates_are_package_data():
    """Every template file matches the package-data globs of bayesfric.report in pyproject.toml
    (the slow wheel test in tests/test_packaging.py installs them for real)."""
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    globs = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    folder = root / "bayesfric" / "report"
    shipped = {p for g in globs["bayesfric.report"] for p in folder.glob(g)}
    assert set((folder / "templates").iterdir()) == shipped and len(shipped) == 2


def test_trajectory_data_get_a_trajectory_figure_and_section(tmp_path):
    """Data with trajectories (ds.attrs['trajectory']) get the measured-vs-predicted panels."""
    import numpy as np

    (tmp_path / "t.toml").write_text(
        '[study]\nname = "t"\n[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\n'
        'name = "coulomb_viscous"\n[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\n'
        'threshold = 1.0\nlabel = "outside"\n')
    out = outcome(load_study(tmp_path / "t.toml"), tmp_path)
    n = out.data.sizes["obs"]
    out.data = out.data.assign_coords(time=("obs", np.tile(np.linspace(0.0, 1.0, n // 4), 4)),
                                      run=("obs", np.repeat(np.arange(4), n // 4)))
    out.data["time"].attrs.update(role="input", units="s")
    out.data["run"].attrs.update(role="group")
    out.data.attrs["trajectory"] = "run"
    folder = tmp_path / "report"
    folder.mkdir()
    write_outcome(out, folder)
    assert (folder / "figures" / "trajectories.png").stat().st_size > 10_000
    assert "## Trajectories: predicted vs measured" in (folder / "summary.md").read_text()
    assert '<section id="trajectories">' in (folder / "report.html").read_text()
