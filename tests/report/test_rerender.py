"""`bayesfric report results.nc --out FOLDER`: the report rendered again from the result tree
alone gives the same bytes as the study run's report (issue 31 item 1, Done-when)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayesfric.cli import main
from bayesfric.compare import RankingSensitivity
from bayesfric.pipeline.runner import run_study
from bayesfric.study import load_study
from bayesfric.study.claims import evaluate_claims
from tests.report.fakes import checks, outcome, tree_of, write_bench_study, write_outcome

#: The files the Done-when names, plus the other CSV tables and the figures.
NAMED = ("report.html", "summary.md", "ranking.csv", "scores.csv", "parameters.csv")
HOSTILE = '=cmd|\' /C calc\'!A0 <script>x</script> **b** `c`'


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _rerender_matches(folder: Path, other: Path, capsys) -> dict[str, bytes]:
    """Re-render ``folder/results.nc`` into ``other`` through the CLI; every file byte-identical."""
    assert main(["report", str(folder / "results.nc"), "--out", str(other)]) == 0
    capsys.readouterr()
    before, after = _files(folder), _files(other)
    # not re-rendered: the run's markers, the fit files and the run store's timings.csv
    runner = {k for k in before if k.startswith((".", "fits/")) or k == "timings.csv"}
    assert sorted(after) == sorted(set(before) - runner)
    for name, blob in after.items():
        assert blob == before[name], f"{name} differs after re-rendering"
    return after


@pytest.fixture(scope="module")
def fake_report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rerender")
    (tmp / "tiny.toml").write_text(
        f'[study]\nname = "tiny"\ntitle = "{HOSTILE}"\nquestion = "Which law?"\n'
        '[data]\ndataset = "robot_joint"\n[[laws]]\nname = "coulomb"\n[[laws]]\nname = "coulomb_viscous"\n'
        '[compare]\nevidence = false\n[[compare.blocked]]\naxis = "velocity"\nthreshold = 1.0\nlabel = "outside"\n'
        f'[[claims]]\ntext = "{HOSTILE}"\nsource = "@seed"\nkind = "best"\nlaw = "coulomb"\nmetric = "elpd_loo"\n')
    out = outcome(load_study(tmp / "tiny.toml"), tmp)
    out.sensitivity = RankingSensitivity(  # coulomb's reweighting at α = 2 is unreliable (k̂ 0.9)
        elpd={1.0: {"coulomb_viscous": 9.0, "coulomb": -90.0}, 0.5: {"coulomb_viscous": 8.0, "coulomb": -80.0},
              2.0: {"coulomb_viscous": -95.0, "coulomb": -85.0}},
        ranking={1.0: ["coulomb_viscous", "coulomb"], 0.5: ["coulomb_viscous", "coulomb"],
                 2.0: ["coulomb", "coulomb_viscous"]},
        max_pareto_k={1.0: {"coulomb_viscous": 0.2, "coulomb": 0.3}, 0.5: {"coulomb_viscous": 0.2, "coulomb": 0.4},
                      2.0: {"coulomb_viscous": 0.5, "coulomb": 0.9}}, changed=True)
    pit = np.linspace(0.01, 0.99, out.data.sizes["obs"])
    out.laws[0] = replace(out.laws[0], timings={"fit": 1.5, "loo": 0.25}, checks=checks(0.4, pit=pit))
    folder = tmp / "report"
    folder.mkdir()
    write_outcome(out, folder)
    return folder, out


def test_fake_study_rerenders_byte_identically(fake_report, tmp_path, capsys):
    after = _rerender_matches(fake_report[0], tmp_path / "again", capsys)
    assert set(NAMED) | {"claims.csv", "results.nc"} <= set(after)
    assert any(k.startswith("figures/") for k in after)
    assert b"'=cmd" in after["claims.csv"]  # neutralised once, not twice
    with xr.open_datatree(tmp_path / "again" / "results.nc") as tree:
        assert tree["ranking"].sizes["row"] == 2 and tree["ranking"]["place"].dtype.kind == "i"
        assert tree["ranking"]["elpd_loo"].dtype.kind == "f"  # numbers stay numbers in the tree


def test_the_tree_holds_verdicts_flags_timings_and_pit(fake_report):
    folder, out = fake_report
    with xr.open_datatree(folder / "results.nc") as tree:
        diag, checks = tree["diagnostics"].to_dataset(), tree["checks"].to_dataset()
        for w in out.laws:
            d = diag.sel(law=w.name)
            assert str(d.verdict.values) == str(w.verdict)
            assert str(d.flags.values) == str(w.result()["flags"].values) == ""  # nothing failed in these fakes
            assert float(d.p_loo) == w.loo.p_loo and int(d.n_high_k) == w.loo.n_high_k
            np.testing.assert_array_equal(tree["pointwise"]["pareto_k"].sel(law=w.name).values, w.loo.pareto_k)
        np.testing.assert_array_equal(checks.pit.sel(law=out.laws[0].name).values, out.laws[0].checks["pit"].values)
        assert np.isnan(checks.pit.sel(law=out.laws[1].name).values).all()  # no PIT values: all NaN
        assert float(diag.timing.sel(law=out.laws[0].name, stage="loo")) == 0.25
        assert np.isnan(float(diag.timing.sel(law=out.laws[1].name, stage="fit")))
        sens = tree["ranking_sensitivity"].to_dataset()
        assert tree.attrs["ranking_changed"] == 1 and sens.attrs["changed"] == 1
        assert sens["place"].sel(alpha=2.0).values.tolist() == [2, 1]  # laws in the α = 1 order
        assert float(sens["elpd"].sel(alpha=0.5, law="coulomb")) == -80.0
        assert float(sens["max_pareto_k"].sel(alpha=2.0, law="coulomb")) == 0.9
    summary = (folder / "summary.md").read_text().replace("\\", "")  # markdown escapes removed
    assert ("LOO ranking coulomb_viscous > coulomb; under prior powers α = 0.5 and 2 it CHANGES: α=0.5: "
            "coulomb_viscous > coulomb; α=2.0: coulomb > coulomb_viscous (PSIS reweighting, no refits); approximate "
            "for coulomb (α = 2): Pareto k̂ above 0.7.") in summary
    assert "The LOO ranking CHANGES when the priors are scaled" in summary


def test_bad_targets_are_one_line_errors_and_write_nothing(fake_report, tmp_path, capsys):
    fake_report = fake_report[0]
    other = tmp_path / "other"
    plain = tmp_path / "plain.nc"
    xr.Dataset({"x": ("i", np.arange(3.0))}).to_netcdf(plain, engine="h5netcdf")
    victim, link = tmp_path / "victim", tmp_path / "link"
    victim.mkdir()
    link.symlink_to(victim)
    cases = [(tmp_path / "missing.nc", other, "missing.nc: no such file"),
             (fake_report / "summary.md", other, "summary.md: not a readable result tree"),
             (plain, other, "plain.nc: not a bayesfric result tree with a stored report"),
             (fake_report / "results.nc", fake_report, "exists and is not empty"),
             (fake_report / "results.nc", link, "is a link; name a new folder"),  # to an empty folder elsewhere
             (fake_report / "results.nc", plain, "exists and is not a folder")]
    for target, out, fragment in cases:
        assert main(["report", str(target), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert fragment in err and err.count("\n") == 1 and "Traceback" not in err
    assert not other.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert link.is_symlink() and not any(victim.iterdir()) and plain.is_file()


def test_a_failed_rendering_removes_the_folders_it_created_and_nothing_else(fake_report, tmp_path, monkeypatch):
    from bayesfric.report import summary

    def broken(tree, folder):
        (Path(folder) / "half.md").write_text("half")
        raise RuntimeError("disk full")

    monkeypatch.setattr(summary, "render_report", broken)
    kept = tmp_path / "kept"
    kept.mkdir()
    with pytest.raises(RuntimeError, match="disk full"):
        summary.rerender(fake_report[0] / "results.nc", kept / "a" / "b" / "out")
    assert list(kept.iterdir()) == []  # a/ and a/b/ were made by the call, so they went; kept/ stays


@pytest.mark.slow
def test_real_study_with_sizing_and_claims_rerenders_byte_identically(tmp_path, capsys):
    """A real small study (NUTS 2 × 700, LOO, blocked CV, a claim, a sizing question): report.html,
    summary.md, ranking.csv, sizing.csv, scores.csv, parameters.csv and the figures again, same bytes."""
    study = write_bench_study(tmp_path, capacity="40 N*m")
    folder = run_study(study, out_root=tmp_path / "reports")
    capsys.readouterr()
    after = _rerender_matches(folder, tmp_path / "again", capsys)
    assert set(NAMED) | {"sizing.csv", "claims.csv"} <= set(after)
    assert any(k.startswith("figures/sizing_") for k in after)


def test_claims_read_the_saved_tree_alone(fake_report, tmp_path):
    """Claims read the result tree only (issue 31 item 1): evaluated on ``results.nc`` copied
    alone into an empty folder (no outcome, no fit files), every kind gives the run's result."""
    import math
    import shutil

    from bayesfric.study.claims import make_claim
    from bayesfric.study.config import CLAIM
    from bayesfric.study.schema import parse

    folder, out = fake_report
    claims = [make_claim(parse(CLAIM, {"text": "t", "source": "s", **entry})) for entry in (
        {"kind": "ratio", "law": "coulomb_viscous", "at": {"velocity": "3 rad/s"},
         "reference_at": {"velocity": "0.5 rad/s"}, "expect": [0.8, 0.9]},
        {"kind": "ratio", "law": "coulomb_viscous", "fixed": {"c_v": 4.0}, "at": {"velocity": "3 rad/s"},
         "reference": "coulomb", "expect": [1.0, 2.0]},
        {"kind": "parameter", "law": "coulomb_viscous", "parameter": "c_v", "expect": [1.5, 2.5]},
        {"kind": "score", "law": "coulomb", "reference": "coulomb_viscous", "metric": "elpd_loo",
         "expect": [-math.inf, 0.0]},
        {"kind": "score", "law": "coulomb", "metric": "penalty", "scheme": "outside", "expect": [1.0, math.inf]},
        {"kind": "best", "law": "coulomb", "metric": "elpd_cv", "scheme": "outside"})]
    in_memory = evaluate_claims(claims, tree_of(out))
    shutil.copyfile(folder / "results.nc", tmp_path / "results.nc")
    with xr.open_datatree(tmp_path / "results.nc", engine="h5netcdf") as tree:
        saved = evaluate_claims(claims, tree.load())
    fields = ("verdict", "value", "lo", "hi", "winner", "why")
    np.testing.assert_equal([[getattr(r, f) for f in fields] for r in saved],  # exact, NaN = NaN
                            [[getattr(r, f) for f in fields] for r in in_memory])
    assert [r.verdict for r in saved] == ["reproduced", "reproduced", "reproduced", "reproduced", "reproduced",
                                          "not reproduced"]


def test_the_saved_tree_alone_builds_the_same_report_content(fake_report):
    """Every text, table and finding of the report comes from the result tree (the sizing result
    aside, passed as an object; this study asks no sizing question): the content model built from
    the saved ``results.nc`` alone, its claims read from ``/claims``, is the one the run stored,
    field for field."""
    from bayesfric.report.content import build, parameter_records
    from bayesfric.report.stored import content_node, read_content, table_frame
    from bayesfric.report.view import TreeView

    folder, out = fake_report
    with xr.open_datatree(folder / "results.nc") as tree:
        assert "claims" in tree.children and "sizing" not in tree.children
        stored = read_content(tree["report"].to_dataset())
        figures = [f for refs in stored.figures.values() for f in refs] + [s.figure for s in stored.laws if s.figure]
        view = TreeView(tree)
        claims = table_frame(tree["claims"].to_dataset()).to_dict("records")
        rebuilt = build(view, parameter_records(view), figures, {}, claims)  # no sizing question
        assert content_node(rebuilt).attrs["content"] == tree["report"].attrs["content"]
    assert stored.checks.rows[0][0] == "coulomb" and stored.laws[1].table.rows  # not an empty model
    assert stored.claims is not None and stored.claims.rows[0][3:] == ["best: coulomb", "best: coulomb_viscous",
                                                                        "not reproduced"]
