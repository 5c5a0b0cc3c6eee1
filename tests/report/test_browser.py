"""The report as a reader sees it: headless Chromium at 1280 px, no console errors, every image
loaded, every section present, no horizontal overflow, the ranking on the first screen.

Chromium comes from the distribution (``scripts/bootstrap.sh`` installs it when missing). Outside
CI a machine without it skips these tests with the command to install it; in CI (``CI`` set, as
``.ci/run`` runs) a missing browser FAILS them: the page check is a deliverable, and a green CI
that silently skipped it would hide that nobody looked at the page.
"""

import os
import re
import shutil
from pathlib import Path

import pytest

from bayesfric.pipeline.runner import run_study
from bayesfric.study import load_study
from tests.report.browser import PHONE, WIDTH, find_chromium, inspect_page
from tests.report.fakes import outcome, write_bench_study, write_outcome

INSTALL = "apt-get install -y chromium (`make test` does it when missing: scripts/bootstrap.sh --browser)"


def chromium() -> str:
    """The system Chromium, or fail in CI / skip elsewhere."""
    path = find_chromium()
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        path = None
    if path is None:
        message = f"no Chromium or no playwright: {INSTALL}; pip install -e '.[test]'"
        if os.environ.get("CI"):
            pytest.fail("CI must run the browser test: " + message)
        pytest.skip(message)
    return path


def check(folder: Path, screenshot: Path) -> None:
    html = folder / "report.html"
    page = inspect_page(html, screenshot, chromium())
    assert page.console_errors == []
    assert page.n_images == len(re.findall(r"<img ", html.read_text())) > 0
    assert page.broken_images == []
    md_sections = re.findall(r"^## (.+)$", (folder / "summary.md").read_text(), flags=re.M)
    assert len(page.section_ids) == len(md_sections) and {"summary", "ranking", "claims"} <= set(page.section_ids)
    assert page.scroll_width <= WIDTH
    assert "Recommended:" in page.first_screen_text  # the decision is on the first screen
    assert page.ranking_figure_top < 900  # and the ranking plot starts on it
    assert screenshot.stat().st_size > 10_000  # a real full-page PNG


def test_fake_outcome_report_in_chromium(tmp_path):
    """A report rendered from an outcome with drawn (not sampled) posteriors: fast, every section."""
    (tmp_path / "tiny.toml").write_text(
        '[study]\nname = "tiny"\ntitle = "A long title that should wrap, not overflow: ' + "x" * 150 + '"\n'
        '[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\nname = "coulomb_viscous"\n'
        '[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.0\nlabel = "outside"\n'
        '[[claims]]\ntext = "c"\nsource = "seed"\nkind = "best"\nlaw = "coulomb_viscous"\nmetric = "elpd_loo"\n')
    out = outcome(load_study(tmp_path / "tiny.toml"), tmp_path)
    folder = tmp_path / "report"
    folder.mkdir()
    write_outcome(out, folder)
    check(folder, tmp_path / "screenshot.png")


def test_ranking_figure_reads_on_a_phone(tmp_path):
    """At 390 px the page does not scroll sideways and the ranking figure is scaled to the
    screen's width from at most 600 px, so its 13-point text stays about 10 px high (the figure
    module's layout: bayesfric.report.ranking_figure)."""
    (tmp_path / "tiny.toml").write_text(
        '[study]\nname = "tiny"\n[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\n'
        'name = "coulomb_viscous"\n[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\n'
        'threshold = 1.0\nlabel = "outside"\n')
    out = outcome(load_study(tmp_path / "tiny.toml"), tmp_path)
    folder = tmp_path / "report"
    folder.mkdir()
    write_outcome(out, folder)
    page = inspect_page(folder / "report.html", tmp_path / "phone.png", chromium(), width=PHONE)
    assert page.console_errors == [] and page.broken_images == []
    assert page.scroll_width <= PHONE  # wide tables scroll inside their own box
    shown, natural = page.ranking_figure_width
    assert PHONE * 0.75 <= shown <= PHONE and natural <= 600
    assert natural / shown < 1.8  # scaled down by less than 1.8: 13 pt at 110 dpi stays ≥ 10 px


@pytest.mark.slow
def test_small_study_report_in_chromium(tmp_path):
    """A real small study with a sizing question (NUTS 2 × 700 draws — --quick's 2 × 300 fail the ESS gate, and a report
    without a recommendation would test less — LOO, blocked CV, claims) on simulated data, opened
    in Chromium;
    the screenshot is kept in reports/ci-screenshots when CI sets BAYESFRIC_SCREENSHOTS."""
    study = write_bench_study(tmp_path)
    folder = run_study(study, out_root=tmp_path / "reports")
    check(folder, tmp_path / "screenshot.png")
    html = (folder / "report.html").read_text()
    assert '<section id="sizing">' in html and html.count("<img ") == len(list((folder / "figures").iterdir()))
    if keep := os.environ.get("BAYESFRIC_SCREENSHOTS"):
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copy(tmp_path / "screenshot.png", Path(keep) / "quick_study.png")
