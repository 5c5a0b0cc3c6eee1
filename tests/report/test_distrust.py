"""What the report tells a reader to distrust (issue 28 Deliver 7, issue 29 Deliver 5): a law
whose fold failed keeps its place with ⚠ and the reason, the winner it would have been is named,
the penalty's standard error, the inside/outside table's columns, the LOO-PIT figure of a
miscalibrated law with its direction, numbers rounded to their errors and units typeset."""

import csv
import re
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import norm

from bayesfric.study import load_study
from tests.report.fakes import checks, cv_result, outcome, write_outcome

STUDY = ('[study]\nname = "tiny"\n[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\n'
         'name = "coulomb_viscous"\n[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\n'
         'threshold = 1.0\nlabel = "outside"\n')
REASON = "its only fold failed the diagnostics gate (R-hat 1.2 > 1.01)"
MD_REASON = REASON.replace(">", "\\>")  # Markdown-escaped


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """coulomb_viscous scores best outside but its blocked fold failed; coulomb's LOO-PIT is too
    narrow (PIT of a predictive half as wide as the scatter); penalties carry standard errors."""
    tmp = tmp_path_factory.mktemp("distrust")
    (tmp / "tiny.toml").write_text(STUDY)
    out = outcome(load_study(tmp / "tiny.toml"), tmp)
    label = out.blocked[0]
    cv, cvv = out.laws
    y = np.random.default_rng(3).standard_normal(cv.fit["posterior_predictive"]["response"].shape[-1] * 10)
    pit = norm.cdf(y / 0.5)
    band = np.stack([np.linspace(0, 1, 11), np.linspace(0, 1, 11) - 0.05, np.linspace(0, 1, 11) + 0.05])
    cv = replace(cv, penalty_se={label: 0.1234}, checks=checks(1e-6, ok=False, ci_prob=0.99, pit=pit, band=band))
    old = cvv.cv[label]
    cvv = replace(cvv, penalty_se={label: 0.0456},
                  cv={label: cv_result(cvv.name, label, old.elpd, old.se, old.heldout, reliable=False)})
    out.laws = [cv, cvv]
    path = tmp / "report"
    path.mkdir()
    write_outcome(out, path)
    return path


def _ranking_rows(md: str) -> list[list[str]]:
    block = md.split("## Ranking")[1].split("\n\n")
    table = next(b for b in block if b.startswith("| rank"))
    return [[c.strip() for c in line.strip("|").split(" | ")] for line in table.splitlines()[2:]]


def test_failed_fold_keeps_its_place_with_the_reason(folder):
    md = (folder / "summary.md").read_text()
    rows = _ranking_rows(md)
    assert rows[0][1] == "coulomb\\_viscous" and rows[0][0] == "⚠ not ranked (scored 1st): " + MD_REASON
    assert rows[1][0] == "1" and rows[1][1] == "coulomb"  # the ranked winner is numbered 1
    html = (folder / "report.html").read_text()
    assert "<td>⚠ not ranked (scored 1st): " + REASON.replace(">", "&gt;") + "</td>" in html
    records = list(csv.DictReader((folder / "ranking.csv").open()))
    assert [(r["rank"], r["place"], r["law"]) for r in records] == [
        ("⚠ not ranked (scored 1st): " + REASON, "1", "coulomb_viscous"), ("1", "2", "coulomb")]


def test_summary_says_the_winner_would_differ(folder):
    summary = (folder / "summary.md").read_text().split("## Ranking")[0]
    warning = next(line for line in summary.splitlines() if "would differ" in line)
    assert "if **coulomb\\_viscous** were counted" in warning and "the ranked winner coulomb has" in warning
    assert MD_REASON in warning
    assert "would differ if <b>coulomb_viscous</b> were counted" in (folder / "report.html").read_text()


def test_penalty_standard_error_is_shown(folder):
    md = (folder / "summary.md").read_text()
    assert "15.00 ± 0.12" in md and "0.50 ± 0.05" in md  # coulomb 15 ± 0.1234, coulomb_viscous 0.5 ± 0.0456
    records = {r["law"]: r for r in csv.DictReader((folder / "ranking.csv").open())}
    assert float(records["coulomb"]["penalty_se[outside]"]) == 0.1234


def test_inside_outside_columns_hold_what_their_headers_say(folder):
    md = (folder / "summary.md").read_text()
    block = md.split("## Inside vs outside the tested envelope")[1].split("![")[0]
    header = next(line for line in block.splitlines() if line.startswith("| law"))
    assert "trained on them (LOO)" in header and "not trained on them (blocked)" in header
    row = next(line for line in block.splitlines() if line.startswith("| coulomb |"))
    loo, blocked, penalty = [c.strip() for c in row.strip("|").split(" | ")][1:]
    # fakes: LOO elpd_i = -90/40 per point, 8 held-out points (|v| > 1) -> -18 (se 0); blocked -160 ± 2
    assert loo == "-18" and blocked == "-160.0 ± 2.0" and penalty == "15.00 ± 0.12"


def test_miscalibrated_law_gets_a_pit_figure_with_its_direction(folder):
    assert (folder / "figures" / "loo_pit_coulomb.png").stat().st_size > 10_000
    assert not (folder / "figures" / "loo_pit_coulomb_viscous.png").exists()  # calibrated: no figure
    md = (folder / "summary.md").read_text()
    data = md.split("## Data and checks")[1]
    assert "![LOO-PIT coulomb](figures/loo_pit_coulomb.png)" in data
    assert "predictive intervals too narrow: the observations scatter 2.0× as widely as predicted" in data
    assert "⚠ too narrow" in data  # in the checks table
    assert "LOO-PIT miscalibrated (see the LOO-PIT figures under Data and checks): coulomb (too narrow)" in md


def test_numbers_are_rounded_and_units_typeset(folder):
    for name in ("summary.md", "report.html"):
        text = (folder / name).read_text()
        assert not re.search(r"± 0\.0(?![0-9])", text)  # no "± 0.0"
        assert not re.search(r"\d\.?\d*e[-+]\d", text.split("data:image")[0] if name == "summary.md" else
                             re.sub(r"data:image/png;base64,[^\"]+", "", text))  # no 5.505e-10
        assert "N*m" not in text
    assert "| T\\_C | N·m |" in (folder / "summary.md").read_text()


def test_direction_asymmetry_is_rounded_to_its_sd():
    from bayesfric.compare.asymmetry import Asymmetry
    from bayesfric.report.findings import _asymmetry

    a = Asymmetry(law="x", parameter="T_C", unit="N*m", mean=5.505e-4, sd=2.1e-5, low=5.16e-4, high=5.85e-4,
                  prob=0.9, p_positive=1.0, draws=400)
    assert _asymmetry(a) == "T_C_pos − T_C_neg = 5.50 × 10⁻⁴ N·m [5.16 × 10⁻⁴, 5.85 × 10⁻⁴] (90%), P(> 0) = 1.00"
