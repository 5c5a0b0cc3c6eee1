"""Bad input, third round: ``--out`` onto a command's own input, units where they enter, stateful
laws across restarts, group columns, memory and size checks, one-line errors naming the option.

Each refused case runs the CLI in-process through :func:`tests.hostile.harness.assert_user_error`:
exit status 2, one line ``bayesfric: error: ...`` naming the file or option and the problem, no
traceback, and nothing under the case's tree created, changed or removed (sizes, modification
times and modes before and after). The accepted cases check what is printed or written. The tree
holds a tiny bench data set and study, a log, fits made by hand (no sampling), a study's report
folder made by hand and a stateful law's fit with a log whose loops restart without a trajectory
column.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.fsutil import MARKER
from bayesfric.inference import save_fit
from tests.hostile.harness import assert_user_error, run_cli
from tests.sizing_helpers import hand_fit, write_basis

V = np.linspace(0.1, 2.0, 10)
CV = {"T_C": np.array([[1.0, 1.2]]), "c_v": np.array([[0.5, 0.7]]), "sigma": np.array([[0.1, 0.2]])}
BENCH = ('[dataset]\nname = "bench"\nprovenance = "simulated"\nsource = "test"\n'
         '[columns.speed]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n'
         '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n'
         '[columns.series]\nrole = "group"\n')
STUDY = ('[study]\nname = "tiny"\n[data]\ndataset = "bench.csv"\n{data}[sampler]\ndraws = 100\ntune = 100\n'
         'chains = 1\n[[laws]]\nname = "coulomb_viscous"\n{law}[compare]\nloo = true\nevidence = false\n'
         '[[compare.blocked]]\naxis = "velocity"\nthreshold = {threshold}\n{extra}')


def study(data: str = "", law: str = "", threshold: str = "1.0", extra: str = "") -> str:
    """The tiny study with lines added to ``[data]``, its ``[[laws]]`` entry and the end."""
    return STUDY.format(data=data, law=law, threshold=threshold, extra=extra)


def _log(folder: Path, name: str, header: str, rows: list, meta: str) -> Path:
    (folder / f"{name}.csv").write_text(header + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    (folder / f"{name}.toml").write_text(meta)
    return folder / f"{name}.csv"


def _loops_meta(trajectory: bool, time: bool = True) -> str:
    meta = '[dataset]\nname = "loops"\nprovenance = "simulated"\nsource = "test"\n'
    meta += 'trajectory = "loop"\n' if trajectory else ""
    meta += '[columns.loop]\nrole = "group"\n'
    meta += '[columns.t]\nrole = "input"\nquantity = "time"\nunit = "s"\n' if time else ""
    return meta + ('[columns.phi]\nrole = "input"\nquantity = "angle"\nunit = "rad"\n'
                   '[columns.load]\nrole = "input"\nquantity = "preload"\nunit = "N"\n'
                   '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n')


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    rows = [[round(v, 3), round(1 + 0.5 * v, 4), 1 + i % 3] for i, v in enumerate(np.linspace(0.1, 2.0, 30))]
    _log(tmp_path, "bench", "speed,torque,series", rows, BENCH)
    _log(tmp_path, "new", "speed,torque", [[0.5, 1.35], [1.0, 2.6], [1.5, 2.3]],
         BENCH.replace('[columns.series]\nrole = "group"\n', "").replace('"bench"', '"new"'))
    save_fit(hand_fit("coulomb_viscous", CV, {"velocity": V}), tmp_path / "fit.nc")
    report = tmp_path / "reports" / "tiny"  # a study's report folder, made by hand
    (report / "fits").mkdir(parents=True)
    (report / MARKER).write_text(json.dumps({"tool": "bayesfric", "study": "tiny"}))
    save_fit(hand_fit("coulomb_viscous", CV, {"velocity": V}), report / "fits" / "coulomb_viscous.nc")
    write_basis(report, ["coulomb_viscous"])
    (tmp_path / "s.toml").write_text(study())
    os.link(tmp_path / "new.csv", tmp_path / "hard.csv")  # a second name of the log
    # a stateful law: Dahl fitted on two loops; a log of two loops, time restarting, no trajectory column
    draws = {"F_c0": np.array([[0.5, 0.6]]), "gamma": np.array([[0.5, 0.4]]), "x_c0": np.array([[0.02, 0.03]]),
             "i": np.array([[1.0, 1.5]]), "sigma": np.array([[0.05, 0.05]])}
    angle = np.concatenate([np.linspace(0, 0.2, 20), np.linspace(0.2, -0.1, 30)])
    save_fit(hand_fit("dahl", draws, {"angle": angle, "preload": np.full(50, 90.0)}), tmp_path / "dahl.nc")
    loop = np.concatenate([np.linspace(0, 0.15, 15), np.linspace(0.15, -0.15, 25)])
    rows = [[k, round(0.1 * j, 2), round(x, 5), 120.0, 0.1] for k in (1, 2) for j, x in enumerate(loop)]
    _log(tmp_path, "loops", "loop,t,phi,load,torque", rows, _loops_meta(trajectory=False))
    _log(tmp_path, "loops_nt", "loop,phi,load,torque", [r[:1] + r[2:] for r in rows],
         _loops_meta(trajectory=False, time=False))
    _log(tmp_path, "loops_ok", "loop,t,phi,load,torque", rows, _loops_meta(trajectory=True))
    return tmp_path


PREDICT = ("predict", "fit.nc", "new.csv")
REPORT = ("predict", "reports/tiny", "new.csv")

# -- 1. no command writes onto a file it reads -----------------------------------------------------
OVERWRITE = [
    ("predict-onto-log", (*PREDICT, "--out", "new.csv"), ("--out new.csv", "would overwrite", "the data file")),
    ("predict-onto-sidecar", (*PREDICT, "--out", "new.toml"), ("--out new.toml", "sidecar")),
    ("predict-onto-hard-link", (*PREDICT, "--out", "hard.csv"), ("--out hard.csv", "would overwrite")),
    ("predict-onto-fit", (*PREDICT, "--out", "fit.nc"), ("--out fit.nc", "the fit or study result")),
    ("predict-onto-results", (*REPORT, "--out", "reports/tiny/results.nc"),
     ("--out reports/tiny/results.nc", "inside reports/tiny", "the report folder")),
    ("predict-into-report", (*REPORT, "--out", "reports/tiny/fits/p.csv"), ("--out", "the report folder")),
    ("predict-results-into-its-folder", ("predict", "reports/tiny/results.nc", "new.csv", "--out",
                                         "reports/tiny/p.csv"), ("--out reports/tiny/p.csv", "report folder")),
    ("score-onto-fit", ("score", "fit.nc", "new.csv", "--out", "fit.nc"), ("--out fit.nc", "would overwrite")),
    ("score-onto-log", ("score", "fit.nc", "new.csv", "--out", "new.csv"), ("--out new.csv", "data file")),
    ("fit-onto-data", ("fit", "bench.csv", "coulomb", "--out", "bench.csv"), ("--out bench.csv", "the data file")),
    ("fit-onto-sidecar", ("fit", "bench.csv", "coulomb", "--out", "bench.toml"), ("--out bench.toml", "sidecar")),
    ("reduce-onto-hard-link", ("data", "reduce", "new.csv", "--out", "hard.csv"),
     ("--out hard.csv", "would overwrite", "the source log")),
    ("out-under-a-file", (*PREDICT, "--out", "new.csv/p.csv"), ("--out", "is not a folder")),
]


@pytest.mark.parametrize(("argv", "mentions"), [c[1:] for c in OVERWRITE], ids=[c[0] for c in OVERWRITE])
def test_no_command_writes_onto_a_file_it_reads(tree, argv, mentions):
    assert_user_error(argv, tree, mentions)


def test_a_study_whose_data_lie_inside_the_report_folder_it_replaces_is_refused(tree):
    (tree / "reports" / "tiny" / "bench.csv").write_bytes((tree / "bench.csv").read_bytes())
    (tree / "reports" / "tiny" / "bench.toml").write_bytes((tree / "bench.toml").read_bytes())
    (tree / "s.toml").write_text(study().replace('"bench.csv"', '"reports/tiny/bench.csv"'))
    assert_user_error(("study", "s.toml", "--out", "reports"), tree,
                      ("s.toml", "[data] dataset", "lies inside the report folder"))


def test_predict_creates_the_missing_parent_folders_of_out(tree):
    code, out, err = run_cli([*PREDICT, "--out", "deep/er/p.csv"], tree)
    assert code == 0, err
    assert (tree / "deep" / "er" / "p.csv").is_file()
    code, out, err = run_cli(["score", "fit.nc", "new.csv", "--out", "s/s.csv"], tree)
    assert code == 0 and (tree / "s" / "s.csv").is_file(), err


# -- 2. units converted where they enter -----------------------------------------------------------
UNITS = [
    ("horizon-rpm", ("size", "fit.nc", "--at", "velocity=1 rad/s", "--capacity", "5 N*m", "--horizon", "20000 rpm"),
     ("--horizon", "'20000 rpm'", "dimension", "not a service time")),
    ("horizon-unknown-unit", ("size", "fit.nc", "--at", "velocity=1 rad/s", "--capacity", "5 N*m", "--horizon",
                              "20000 fortnights_x"), ("--horizon", "unknown unit")),
    ("study-horizon-rpm", None, ("s.toml", "sizing[0].horizon", "dimension")),
    ("threshold-wrong-dimension", None, ("s.toml", "compare.blocked[0].threshold", "'0.5 m'")),
    ("threshold-no-number", None, ("s.toml", "compare.blocked[0].threshold")),
]
STUDIES = {
    "study-horizon-rpm": study(law='trend = { series = ["T_C"] }\n',
                               extra='[[sizing]]\nat = { velocity = "1 rad/s" }\ncapacity = "5 N*m"\n'
                                     'horizon = "20000 rpm"\n'),
    "threshold-wrong-dimension": study(threshold='"0.5 m"'),
    "threshold-no-number": study(threshold='"fast rad/s"'),
}


@pytest.mark.parametrize(("case", "argv", "mentions"), UNITS, ids=[c[0] for c in UNITS])
def test_a_quantity_in_the_wrong_dimension_is_refused_where_it_enters(tree, case, argv, mentions):
    if argv is None:
        (tree / "s.toml").write_text(STUDIES[case])
        argv = ("study", "s.toml", "--out", "reports")
    assert_user_error(argv, tree, mentions)


def test_the_blocked_threshold_takes_units_and_plain_numbers_stay_si(tree):
    from bayesfric.study import load_study

    for text, si in (('"0.5 rad/s"', 0.5), ('"300 rpm"', 300 * 2 * np.pi / 60), ("0.5", 0.5), ('"30 deg/s"',
                                                                                                np.pi / 6)):
        (tree / "s.toml").write_text(study(threshold=text))
        assert load_study(tree / "s.toml").blocked[0].threshold == pytest.approx(si, rel=1e-12)


def test_a_study_horizon_is_converted_into_the_service_columns_unit_before_any_fit(tree):
    """A horizon whose unit cannot be expressed in the column's (km against h) is refused by the
    plan, naming the file and key, before anything is fitted or written."""
    meta = BENCH.replace('[columns.series]\nrole = "group"\n', '[columns.series]\nrole = "group"\nunit = "h"\n')
    (tree / "bench.toml").write_text(meta)
    (tree / "s.toml").write_text(study(law='trend = { series = ["T_C"] }\n',
                                       extra='[[sizing]]\nat = { velocity = "1 rad/s" }\ncapacity = "5 N*m"\n'
                                             'horizon = "20000 km"\n'))
    assert_user_error(("study", "s.toml", "--out", "reports"), tree,
                      ("s.toml", "sizing[0].horizon", "'20000 km' cannot be expressed in 'h'", "column 'series'"))


@pytest.fixture(scope="module")
def trend_fit_file(tmp_path_factory):
    """A small fit (sampled) of a law whose T_C follows a trend over service hours, saved."""
    from bayesfric import inference
    from bayesfric.datasets.synthetic import simulate_campaigns
    from bayesfric.laws import get_law

    ds, _ = simulate_campaigns(get_law("coulomb_viscous"), {"velocity": np.linspace(0.1, 2.0, 8)},
                               {"T_C": lambda t: 2.0 * (1 + t / 6000.0), "c_v": 1.0}, [0, 1000, 2000, 3000],
                               {"T_C": 0.03}, sigma=0.05, seed=1)
    fit = inference.fit(get_law("coulomb_viscous").trend("hours", "T_C"), ds, draws=150, tune=150, chains=1, seed=0)
    return inference.save_fit(fit, tmp_path_factory.mktemp("trend") / "trend.nc")


def test_a_horizon_in_seconds_is_answered_in_the_service_columns_hours(trend_fit_file):
    """72 000 000 s is 20 000 h: the same answer, printed in hours (it used to be the hours' numbers
    labelled seconds, 3600 times too early); a horizon in rpm is refused in Python too."""
    import bayesfric

    at, cap = ("--at", "velocity=1 rad/s"), ("--capacity", "5 N*m")
    folder = trend_fit_file.parent
    code, seconds, err = run_cli(["size", trend_fit_file.name, *at, *cap, "--horizon", "72000000 s"], folder)
    assert code == 0, err
    code, hours, err = run_cli(["size", trend_fit_file.name, *at, *cap, "--horizon", "20000 h"], folder)
    assert code == 0, err
    assert seconds == hours and " h" in hours and " s;" not in hours and " s –" not in hours
    out = bayesfric.time_to_exceed(trend_fit_file, {"velocity": "1 rad/s"}, capacity="5 N*m", horizon=(72e6, "s"))
    assert out.attrs["horizon"] == pytest.approx(20000.0) and out.attrs["unit"] == "h"
    with pytest.raises(UserError, match=r"horizon: '20000 rpm': 'rpm' is of dimension 1 / \[time\]"):
        bayesfric.time_to_exceed(trend_fit_file, {"velocity": "1 rad/s"}, capacity="5 N*m", horizon="20000 rpm")


# -- 3. stateful laws do not run across a restart --------------------------------------------------
STATEFUL = [
    ("predict-time-back", ("predict", "dahl.nc", "loops.csv", "--out", "p.csv"),
     ("loops.csv", "row 41", "time goes from 3.9 s back to 0 s", "trajectory")),
    ("score-time-back", ("score", "dahl.nc", "loops.csv"), ("loops.csv", "time goes", "law 'dahl' is stateful")),
    ("predict-position-jump", ("predict", "dahl.nc", "loops_nt.csv", "--out", "p.csv"),
     ("loops_nt.csv", "row 41", "angle jumps from -0.15 to 0 rad", "[dataset] trajectory")),
    ("fit-time-back", ("fit", "loops.csv", "dahl", "--quiet"), ("loops.csv", "time goes", "trajectory")),
]


@pytest.mark.parametrize(("argv", "mentions"), [c[1:] for c in STATEFUL], ids=[c[0] for c in STATEFUL])
def test_a_stateful_law_is_refused_on_a_log_that_restarts_without_a_trajectory_column(tree, argv, mentions):
    assert_user_error(argv, tree, mentions)


def test_with_its_trajectory_column_the_same_log_is_predicted(tree):
    code, out, err = run_cli(["predict", "dahl.nc", "loops_ok.csv", "--out", "p.csv"], tree)
    assert code == 0, err


# -- 4. a group column must look like one ----------------------------------------------------------
GROUPS = [
    ("vary-by-an-input", dict(law='vary_by = { velocity = ["c_v"] }\n'),
     ("s.toml", "laws[0].vary_by", "'velocity' is an input (30 distinct values), not a group column")),
    ("trend-over-an-input", dict(law='trend = { velocity = ["T_C"] }\n'),
     ("s.toml", "laws[0].trend", "'velocity' is an input")),
    ("vary-by-a-csv-column", dict(law='vary_by = { speed = ["c_v"] }\n'),
     ("s.toml", "laws[0].vary_by", "'speed' is the CSV column of input 'velocity'",
      "group columns of the data: series")),
    ("grouped-by-an-input", dict(extra="grouped = \"velocity\"\n"), ("s.toml", "[compare] grouped", "is an input")),
    ("select-an-absent-level", dict(data="select = { series = [1, 7] }\n"),
     ("s.toml", "[data] select", "series = 7", "no row", "1, 2, 3")),
    ("select-an-empty-list", dict(data="select = { series = [] }\n"),
     ("s.toml", "[data] select.series", "got an empty array")),
    ("capacity-an-empty-array", dict(extra='[[sizing]]\nat = { velocity = "1 rad/s" }\ncapacity = []\n'),
     ("s.toml", "sizing[0].capacity", "got an empty array")),
]


@pytest.mark.parametrize(("changes", "mentions"), [c[1:] for c in GROUPS], ids=[c[0] for c in GROUPS])
def test_a_group_column_must_look_like_one(tree, changes, mentions):
    text = study(**{k: v for k, v in changes.items() if k != "extra"})
    if "extra" in changes:  # a [compare] key goes before [[compare.blocked]]; a table at the end
        extra = changes["extra"]
        text = text.replace("[[compare.blocked]]", extra + "[[compare.blocked]]") if not extra.startswith("[[") \
            else text + extra
    (tree / "s.toml").write_text(text)
    assert_user_error(("study", "s.toml", "--out", "reports"), tree, mentions)


def _many_levels(tree: Path, levels: int = 1000) -> None:
    rows = [[round(0.1 + 0.0019 * (i % 1000), 4), round(1 + 0.1 * (i % 7), 3), i // 2] for i in range(2 * levels)]
    _log(tree, "bench", "speed,torque,series", rows, BENCH)


def test_a_group_column_with_a_thousand_levels_asks_for_confirmation_with_its_cost(tree):
    _many_levels(tree)
    (tree / "s.toml").write_text(study(law='vary_by = { series = ["c_v"] }\n'))
    line = assert_user_error(("study", "s.toml", "--out", "reports"), tree,
                             ("s.toml", "laws[0].vary_by", "'series' has 1000 levels", "max_levels = 100",
                              "1000 × 1 = 1000 refits", "set [data] max_levels = 1000"))
    assert "vary_by samples 1000 × 1 level values" in line


def test_max_levels_confirms_them(tree):
    from bayesfric.study import load_study
    from bayesfric.study.plan import _check_groups, load_study_data

    _many_levels(tree)
    (tree / "s.toml").write_text(study(data="max_levels = 1000\n", law='vary_by = { series = ["c_v"] }\n'))
    confirmed = load_study(tree / "s.toml")
    _check_groups(confirmed, load_study_data(confirmed))  # no error


def test_predict_and_score_say_how_far_outside_the_fitted_envelope_each_input_lies(tree):
    _log(tree, "far", "speed,torque", [[0.5, 1.35], [6.0, 4.2], [38.0, 20.0]],
         BENCH.replace('[columns.series]\nrole = "group"\n', "").replace('"bench"', '"far"'))
    for argv in (["predict", "fit.nc", "far.csv", "--out", "p.csv"], ["score", "fit.nc", "far.csv"]):
        code, out, err = run_cli(argv, tree)
        assert code == 0, err
        assert "outside the fitted envelope" in out and "velocity: 2 of 3 rows, up to 18.9 tested ranges" in out
    code, out, err = run_cli(["score", "fit.nc", "new.csv"], tree)
    assert "outside the fitted envelope" not in out


# -- 5. memory and size checks, one-line errors naming the option -----------------------------------
def test_predict_checks_the_memory_a_log_needs_before_any_work(tree, monkeypatch):
    from bayesfric import limits

    draws = {k: np.full((1, 1000), v[0, 0]) for k, v in CV.items()}
    save_fit(hand_fit("coulomb_viscous", draws, {"velocity": V}), tree / "big.nc")
    monkeypatch.setattr(limits, "available_memory", lambda: 10_000)  # the log loads; 1000 draws do not fit
    assert_user_error(("predict", "big.nc", "new.csv", "--out", "p.csv"), tree,
                      ("new.csv", "3 rows × 1000 draws of 1 law", "available", "split or thin the log"))


def test_thinning_below_the_laws_parameters_is_refused_before_any_store_write(tree):
    (tree / "s.toml").write_text(study(data="every = 1000000000\n"))
    assert_user_error(("study", "s.toml", "--out", "reports"), tree,
                      ("s.toml", "[data] every", "leaves 1 row", "fewer than the 3 parameters", "coulomb_viscous"))


OPTIONS = [
    ("quantiles-twice", (*PREDICT, "--out", "p.csv", "--quantiles", "0.5", "0.5"), ("--quantiles", "0.5 is given "
                                                                                                    "twice")),
    ("seed-negative", (*PREDICT, "--out", "p.csv", "--seed", "-1"), ("--seed", "got integer -1")),
    ("score-seed-negative", ("score", "fit.nc", "new.csv", "--seed", "-1"), ("--seed",)),
    ("log-missing", ("predict", "fit.nc", "gone.csv", "--out", "p.csv"), ("gone.csv", "no such file")),
]


@pytest.mark.parametrize(("argv", "mentions"), [c[1:] for c in OPTIONS], ids=[c[0] for c in OPTIONS])
def test_option_errors_name_the_option(tree, argv, mentions):
    line = assert_user_error(argv, tree, mentions)
    assert "results.nc" not in line and "fit.nc" not in line


def test_an_empty_list_of_quantiles_is_an_error_naming_the_argument(tree):
    import bayesfric

    with pytest.raises(UserError, match=r"^quantiles: no quantile level given"):
        bayesfric.predict(tree / "fit.nc", tree / "new.csv", quantiles=[])
    with pytest.raises(UserError, match=r"^seed: must be an integer"):
        bayesfric.score(tree / "fit.nc", tree / "new.csv", seed=-1)


def test_reducing_an_all_standstill_log_suggests_keep_standstill(tree):
    rows = [[round(0.01 * i, 2), 0.0, round(0.2 + 0.001 * (i % 5), 4)] for i in range(300)]
    _log(tree, "rest", "t,speed,torque", rows,
         BENCH.replace('[columns.series]\nrole = "group"\n', "").replace('"bench"', '"rest"')
         + '[columns.t]\nrole = "input"\nquantity = "time"\nunit = "s"\n')
    line = assert_user_error(("data", "reduce", "rest.csv"), tree, ("rest.csv", "at standstill", "--keep-standstill"))
    assert "--rtol" not in line and "--min-samples" not in line


# -- 6. the report's rerun line keeps --out ---------------------------------------------------------
def test_the_rerun_line_keeps_the_out_it_was_run_with():
    from bayesfric.report.content import _footer

    attrs = {"seconds": 3.0, "study_file": "studies/x.toml", "study_file_exists": 1}
    assert _footer(attrs | {"rerun_options": " --out /tmp/r"}).endswith("Rerun: bayesfric study studies/x.toml "
                                                                         "--out /tmp/r")
    assert _footer(attrs).endswith("Rerun: bayesfric study studies/x.toml")


def test_the_results_of_a_report_folder_read_by_predict_are_unchanged(tree):
    """The refused cases above leave ``results.nc`` readable (the harness compares the whole tree)."""
    with xr.open_datatree(tree / "reports" / "tiny" / "results.nc", engine="h5netcdf") as opened:
        assert "sizing_basis" in opened.children
