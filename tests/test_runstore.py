"""The run store: unit keys, atomic entries, corrupt = miss, resume after kill -9, Dask = serial."""

import csv
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayesfric.study import load_study
from bayesfric.study.plan import _fold_schemes, _run_settings, load_study_data
from bayesfric.study.store import STORE_ENV, RunStore
from bayesfric.study.units import make_job, plan_law
from tests.hostile.harness import assert_user_error
from tests.test_study import data_csv, study_text, write_bench_data  # noqa: F401 - the fixture is used by name

REPO = Path(__file__).resolve().parents[1]
LAWS = '[[laws]]\nname = "coulomb"\n[[laws]]\nname = "coulomb_viscous"\n'


def _units(path: Path):
    """(fit unit, later units) of the study's first law, as a run would key them."""
    study = load_study(path)
    ds = load_study_data(study)
    config, kfold = _run_settings(study, quick=True)
    job = make_job(study.laws[0], study.noise, ds, config)
    fit, rest = plan_law(job, study, _fold_schemes(study, ds, study.sampler["seed"], kfold))
    return fit, {u.label: u.key for u in rest}


def test_unit_keys_change_with_every_input_and_only_then(tmp_path, data_csv):  # noqa: F811
    path = tmp_path / "s.toml"
    path.write_text(study_text(LAWS))
    fit, rest = _units(path)
    assert _units(path) == (fit, rest)  # unchanged study: same keys (reused)
    variants = {
        "prior": study_text('[[laws]]\nname = "coulomb"\npriors = { T_C = { dist = "HalfNormal", scale = 3.0 } }\n'),
        "seed": study_text(LAWS).replace("chains = 2\n", "chains = 2\nseed = 1\n"),
        "sampler": study_text(LAWS).replace("chains = 2", "chains = 1"),  # draws are capped by --quick
        "noise": study_text(LAWS) + '[noise]\nkind = "student_t"\n',
        "selection": study_text(LAWS).replace('"bench.csv"\n', '"bench.csv"\nselect = { series = 0 }\n'),
    }
    for what, text in variants.items():
        path.write_text(text)
        assert _units(path)[0].key != fit.key, what
    path.write_text(study_text(LAWS).replace("threshold = 1.0", "threshold = 1.5"))
    fit2, rest2 = _units(path)
    assert fit2.key == fit.key and rest2["loo"] == rest["loo"]  # another fold changes only its own unit
    assert set(rest2.values()) - set(rest.values()) == {rest2[next(k for k in rest2 if "1.5" in k)]}
    path.write_text(study_text(LAWS))
    lines = data_csv.read_text().splitlines()
    lines[5] = lines[5].split(",")[0] + ",9.5," + lines[5].split(",")[2]  # one response value changed
    data_csv.write_text("\n".join(lines) + "\n")
    assert _units(path)[0].key != fit.key


def test_store_entries_round_trip_and_a_damaged_entry_is_a_miss(tmp_path):
    store = RunStore(tmp_path / "store")
    key = "a" * 32
    result = xr.Dataset({"x": ("obs", np.arange(3.0)), "handling": "none", "refitted": True},
                        attrs={"key": key, "compute_s": 1.5})
    store.put(key, "unit.nc", result)
    back = store.get(key, "unit.nc")
    xr.testing.assert_identical(back, result)  # values, dtypes (a bool stays a bool) and attrs
    assert RunStore(tmp_path / "store", read=False).get(key, "unit.nc") is None  # --fresh
    other = "b" * 32
    store.put(other, "unit.nc", result)  # an entry under another key's name: not trusted
    assert store.get(other, "unit.nc") is None
    payload = store.path(key, "unit.nc").read_bytes()
    store.path(key, "unit.nc").write_bytes(payload[: len(payload) // 2])  # truncated
    assert store.get(key, "unit.nc") is None
    store.path(key, "nc").write_bytes(b"not a NetCDF file")
    assert store.get(key, "nc") is None
    assert store.get("c" * 32, "unit.nc") is None  # absent


def test_clean_removes_temporary_files_of_dead_writers_only(tmp_path):
    store = RunStore(tmp_path)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    host = os.uname().nodename
    stale = tmp_path / f".{'a' * 32}.npz.{host}.{int(dead.stdout)}.0123abcd.tmp"
    live = tmp_path / f".{'b' * 32}.npz.{host}.{os.getpid()}.0123abcd.tmp"
    foreign = tmp_path / f".{'c' * 32}.npz.otherhost.1.0123abcd.tmp"
    for p in (stale, live, foreign):
        p.write_bytes(b"partial")
    assert store.clean() == [stale]
    assert live.exists() and foreign.exists() and not stale.exists()


@pytest.mark.parametrize(("argv", "mention"), [
    (["--workers", "-2"], "--workers"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler"),
    (["--scheduler", "no-port"], "--scheduler no-port"),
])
def test_executor_options_are_one_line_errors(tmp_path, data_csv, argv, mention):  # noqa: F811
    (tmp_path / "s.toml").write_text(study_text(LAWS))
    assert_user_error(["study", "s.toml", "--out", "reports", *argv], tmp_path, [mention], cwd=tmp_path)


def test_failed_fits_takes_skip_or_run(tmp_path, data_csv):  # noqa: F811
    from bayesfric.study import StudyError

    path = tmp_path / "s.toml"
    path.write_text(study_text(LAWS, extra=""))
    assert load_study(path).failed_fits == "skip"
    path.write_text(study_text(LAWS).replace("loo = true", 'loo = true\nfailed_fits = "run"'))
    assert load_study(path).failed_fits == "run"
    path.write_text(study_text(LAWS).replace("loo = true", 'loo = true\nfailed_fits = "maybe"'))
    with pytest.raises(StudyError, match=r"\[compare\] failed_fits"):
        load_study(path)


# -- whole runs (subprocesses, as a user runs them) --------------------------------------------------
def _study(tmp_path: Path) -> Path:
    """Two cheap laws, LOO + one blocked fold, every stage run (quick fits may miss the ESS gate)."""
    path = tmp_path / "s.toml"
    path.write_text(study_text(LAWS).replace("loo = true", 'loo = true\nfailed_fits = "run"'))
    return path


def _run(path: Path, out: Path, *extra: str, quick: bool = True) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != STORE_ENV}  # the store under --out
    return subprocess.Popen([sys.executable, "-m", "bayesfric", "study", str(path), "--out", str(out),
                             *(["--quick"] if quick else []), *extra], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=env, start_new_session=True,
                            preexec_fn=_interruptible)


def _interruptible() -> None:
    """In the child before exec: SIGINT as a terminal would deliver it. A suite started as a
    shell's background job inherits SIGINT ignored, and Python then installs no handler for it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _entries(store: Path) -> list[Path]:
    """Finished store entries (not temporary files of writes in progress)."""
    return sorted(p for p in store.glob("*") if not p.name.startswith(".") and p.suffix == ".nc")


def _finish(proc: subprocess.Popen) -> str:
    out, _ = proc.communicate(timeout=600)
    assert proc.returncode == 0, out[-3000:]
    return out


def _statuses(folder: Path) -> list[str]:
    with (folder / "timings.csv").open() as fh:
        return [row["status"] for row in csv.DictReader(fh)]


@pytest.fixture(scope="module")
def serial_run(tmp_path_factory) -> tuple[Path, Path]:
    """(study file, report folder) of one uninterrupted serial run of :func:`_study`: the reference
    that the killed-and-resumed run and the Dask run must equal (one subprocess, ~20 s, for both)."""
    folder = tmp_path_factory.mktemp("serial")
    write_bench_data(folder)
    path = _study(folder)
    _finish(_run(path, folder / "ref"))
    return path, folder / "ref" / "tiny"


@pytest.mark.slow
def test_kill_minus_nine_then_rerun_equals_an_uninterrupted_run(tmp_path, serial_run):
    path, reference = serial_run
    expected = (reference / "ranking.csv").read_text()

    proc = _run(path, tmp_path / "out")
    store = tmp_path / "out" / ".store" / "tiny"
    deadline = time.monotonic() + 300
    def past_a_fit() -> bool:
        return any(p.name.endswith(".unit.nc") for p in _entries(store))

    while not past_a_fit() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)  # kill right after the first unit past a fit landed: mid-run
    assert proc.poll() is None, "the run ended before it could be killed"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate()
    done_before = len(_entries(store))
    assert not (tmp_path / "out" / "tiny").exists()  # no report: the run never finished

    out = _finish(_run(path, tmp_path / "out"))
    folder = tmp_path / "out" / "tiny"
    assert (folder / "ranking.csv").read_text() == expected
    statuses = _statuses(folder)
    assert statuses.count("reused") == done_before >= 2 and "computed" in statuses, out[-2000:]
    leftovers = [p for p in (tmp_path / "out").rglob("*") if p.name.endswith(".tmp") or
                 (p.parent == tmp_path / "out" and p.name.startswith(".tiny."))]
    assert not leftovers  # no temporary file or work folder of the killed run is left

    # an unchanged rerun finds the report current: nothing recomputed, the report left as it is
    before = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    assert "unchanged" in _finish(_run(path, tmp_path / "out"))
    assert {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == before

    # one damaged entry is recomputed, not trusted; everything else is reused
    victim = [p for p in _entries(store) if p.name.endswith(".unit.nc")][0]
    victim.write_bytes(victim.read_bytes()[:100])
    shutil.rmtree(folder)  # without the report, the rerun rebuilds it from the store
    _finish(_run(path, tmp_path / "out"))
    assert (folder / "ranking.csv").read_text() == expected
    assert _statuses(folder).count("computed") == 1

    # --fresh recomputes every unit, with the same numbers
    _finish(_run(path, tmp_path / "out", "--fresh"))
    assert set(_statuses(folder)) == {"computed"}
    assert (folder / "ranking.csv").read_text() == expected


@pytest.mark.slow
def test_two_worker_local_cluster_equals_serial(tmp_path, serial_run):
    pytest.importorskip("distributed")  # the dask extra (installed by make test's bootstrap)
    path, serial = serial_run
    _finish(_run(path, tmp_path / "dask", "--workers", "2"))
    for name in ("ranking.csv", "parameters.csv"):
        assert (tmp_path / "dask" / "tiny" / name).read_text() == (serial / name).read_text()
    assert set(_statuses(tmp_path / "dask" / "tiny")) == {"computed"}


@pytest.mark.slow
def test_a_failed_fit_skips_cv_and_evidence_unless_asked(tmp_path, data_csv):  # noqa: F811
    """40 draws per chain cannot pass the ESS gate: CV and evidence are skipped, and the report says so
    (not under --quick, which runs every stage as a smoke test)."""
    text = (study_text('[[laws]]\nname = "coulomb_viscous"\n').replace("draws = 1000", "draws = 40")
            .replace("tune = 500", "tune = 40").replace("evidence = false", "evidence = true"))
    path = tmp_path / "s.toml"
    path.write_text(text)
    _finish(_run(path, tmp_path / "skip", quick=False))
    folder = tmp_path / "skip" / "tiny"
    with (folder / "timings.csv").open() as fh:
        rows = {row["stage"]: row["status"] for row in csv.DictReader(fh)}
    assert rows == {"fit": "computed", "loo": "computed", "cv": "skipped", "bridge": "skipped",
                    "importance": "skipped", "checks": "computed"}
    summary = (folder / "summary.md").read_text()
    assert "failed the diagnostics gate, so" in summary and "were not computed" in summary
    path.write_text(text.replace("evidence = true", 'evidence = true\nfailed_fits = "run"'))
    _finish(_run(path, tmp_path / "skip", quick=False))
    assert "skipped" not in _statuses(folder)
    # the fit and checks do not depend on the option; LOO does (a failed fit's exact refits only under "run")
    assert _statuses(folder).count("reused") == 2


def test_progress_lines_without_a_terminal_and_the_stage_table(tmp_path):
    import io

    from bayesfric.study.executor import Progress, Timing, timing_table, write_timings
    from bayesfric.study.units import Unit

    stream = io.StringIO()  # not a TTY: plain lines, no bar
    progress = Progress(3, "tiny", stream)
    progress.step(Unit("coulomb", "fit", "fit", "k1"), "computed", 2.5)
    progress.step(Unit("coulomb", "cv", "blocked v", "k2"), "reused", 0.0)
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("[tiny] 1/3 coulomb fit: computed in 2.5 s (elapsed ")
    assert lines[1].startswith("[tiny] 2/3 coulomb blocked v: reused (elapsed ") and "left)" in lines[1]
    rows = [Timing("tiny", "coulomb", "fit", "fit", "computed", 2.5, 2.5),
            Timing("tiny", "stribeck", "fit", "fit", "reused", 0.0, 4.0),
            Timing("tiny", "stribeck", "cv", "blocked v", "skipped", 0.0, float("nan"))]
    table = timing_table(rows).splitlines()
    assert table[2].split() == ["fit", "1", "1", "0", "2.5"] and table[3].split() == ["cv", "0", "0", "1", "0.0"]
    assert table[-1].split() == ["total", "1", "1", "1", "2.5"]
    text = write_timings(rows, tmp_path / "timings.csv").read_text().splitlines()
    assert text[0] == "study,law,stage,label,status,seconds,stored_seconds" and len(text) == 4


def test_a_stored_fit_reads_back_identical_to_the_computed_one(tmp_path):
    """A study hands the fit it computed to the law's units and to its outcome as it is, and a
    resumed run reads it back from the store: sound only because the two are identical (values,
    dimensions, dtypes, attributes), which this checks; what is read back is fully in memory."""
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.inference import fit
    from bayesfric.laws import get_law

    law = get_law("coulomb_viscous")
    ds = simulate(law, {"velocity": np.linspace(-2, 2, 16)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.05, seed=0)
    dt = fit(law, ds, draws=60, tune=60, chains=2)
    store = RunStore(tmp_path / "store")
    key = "f" * 32
    store.put(key, "nc", dt)
    opened = store.get(key, "nc")
    assert sorted(opened.children) == sorted(dt.children) and opened.attrs == dt.attrs
    for node in dt.subtree:
        other = opened[node.path]
        xr.testing.assert_identical(node.to_dataset(), other.to_dataset())
        for name, var in node.variables.items():
            assert isinstance(var.values, np.ndarray) and var.dtype == other[name].dtype, (node.path, name)
    store.path(key, "nc").unlink()  # fully loaded: nothing of it is read from the file any more
    xr.testing.assert_identical(opened, dt)


# -- a store keyed by content, not by place (issue 48 item 4) ----------------------------------------
def _law_file_study(folder: Path) -> Path:
    """The run-store study with a law of the user's own (a law file and the helper it imports)."""
    write_bench_data(folder)
    for name in ("my_laws.py", "shapes.py"):
        shutil.copyfile(REPO / "examples" / "own_law" / name, folder / name)
    path = folder / "s.toml"
    path.write_text(study_text('[[laws]]\nname = "coulomb"\n[[laws]]\nname = "smooth_stribeck"\n')
                    .replace('name = "tiny"\n', 'name = "tiny"\nmodules = ["my_laws.py"]\n'))
    return path


def test_unit_keys_hold_no_absolute_path_and_do_not_move(tmp_path, monkeypatch):
    """Every part of every unit key of a study with a data file and a law file is free of the
    folder it lies in, so the same study in another folder has the same keys (that one keyed in
    another process: one process declares a law file's laws once)."""
    import json

    from bayesfric import fingerprint
    from bayesfric.study import units

    parts: list[str] = []

    def spy(**given):
        parts.append(json.dumps(fingerprint.canonical(given), sort_keys=True, default=str))
        return fingerprint.unit_key(**given)

    monkeypatch.setattr(units, "unit_key", spy)
    here, there = tmp_path / "here", tmp_path / "elsewhere" / "there"
    for folder in (here, there):
        folder.mkdir(parents=True)
        _law_file_study(folder)
    keys = _all_keys(here / "s.toml")
    assert parts and all(str(tmp_path) not in p for p in parts), next(p for p in parts if str(tmp_path) in p)
    assert not any(v.startswith(os.sep) for p in parts for v in _strings(json.loads(p)))
    assert load_study_data(load_study(here / "s.toml")).attrs["csv_file"].startswith(str(here))  # kept out
    script = f"from tests.test_runstore import _all_keys; print(_all_keys({str(there / 's.toml')!r}))"
    done = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == str(keys)


def _all_keys(path: Path) -> list[str]:
    """The key of every unit of every law of the study at ``path`` (quick settings), in order."""
    study = load_study(path)
    ds = load_study_data(study)
    config, kfold = _run_settings(study, quick=True)
    out = []
    for spec in study.laws:
        job = make_job(spec, study.noise, ds, config)
        fit, rest = plan_law(job, study, _fold_schemes(study, ds, study.sampler["seed"], kfold))
        out += [fit.key, *(u.key for u in rest)]
    return out


def _strings(value) -> list[str]:
    """Every string inside a JSON value."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, dict):
        return [s for k, v in value.items() for s in (k, *_strings(v))]
    if isinstance(value, list):
        return [s for v in value for s in _strings(v)]
    return []


@pytest.mark.slow
def test_a_project_moved_with_its_reports_reuses_every_unit(tmp_path, serial_run):
    """The study's folder (study file, data, reports with the run store) copied to another absolute
    path: its report is current there, and rebuilt without it every unit is reused."""
    path, reference = serial_run
    moved = tmp_path / "clone" / "project"
    shutil.copytree(path.parent, moved, symlinks=True)
    assert "unchanged" in _finish(_run(moved / path.name, moved / "ref"))
    shutil.rmtree(moved / "ref" / "tiny")
    out = _finish(_run(moved / path.name, moved / "ref"))
    assert set(_statuses(moved / "ref" / "tiny")) == {"reused"}, out[-2000:]
    assert (moved / "ref" / "tiny" / "ranking.csv").read_text() == (reference / "ranking.csv").read_text()


@pytest.mark.slow
def test_a_moved_project_with_a_law_file_reuses_every_unit(tmp_path):
    """A law file's fits record where it was; moved, the project's own copy stands for it."""
    first = tmp_path / "first"
    first.mkdir()
    path = _law_file_study(first)
    _finish(_run(path, first / "reports"))
    moved = tmp_path / "moved"
    first.rename(moved)  # the old place is gone
    shutil.rmtree(moved / "reports" / "tiny")
    out = _finish(_run(moved / "s.toml", moved / "reports"))
    assert set(_statuses(moved / "reports" / "tiny")) == {"reused"}, out[-2000:]


def _tree(root: Path) -> set[str]:
    """Every path below ``root`` but the run store's finished entries (a stopped run keeps those
    for the next one; new ones appear where the code changed since the earlier run)."""
    return {p.relative_to(root).as_posix() for p in root.rglob("*")
            if not (".store" in p.parts and not p.name.startswith(".") and p.name.endswith((".nc", ".nc.json")))}


@pytest.mark.slow
@pytest.mark.parametrize(("signum", "status"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_mid_run_leaves_nothing_behind(tmp_path, serial_run, signum, status):
    """SIGTERM or SIGINT while units are computed: the run removes its work folder and temporary
    files, exits with 128 + the signal's number in one line (no traceback), and leaves alone what
    it did not create (the earlier report, the store, a folder that looks like a work folder)."""
    path, _ = serial_run
    project = tmp_path / "project"
    shutil.copytree(path.parent, project, symlinks=True)
    decoy = project / "ref" / ".tiny.0badc0de"  # named like a work folder, not made by bayesfric
    decoy.mkdir()
    (decoy / "keep.txt").write_text("not bayesfric's")
    before = _tree(project)
    start = time.time()
    proc = _run(project / path.name, project / "ref", "--fresh")
    store = project / "ref" / ".store" / "tiny"
    deadline = time.monotonic() + 300
    while proc.poll() is None and time.monotonic() < deadline and not any(
            p.stat().st_mtime > start for p in _entries(store)):
        time.sleep(0.05)  # signal right after the first unit of this run landed: mid-run
    assert proc.poll() is None, "the run ended before the signal"
    assert any(p.name.startswith(".tiny.") and p != decoy for p in (project / "ref").iterdir())  # its work folder
    os.kill(proc.pid, signum)
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == status, out[-2000:]
    assert "Traceback" not in out and out.strip().splitlines()[-1].startswith("bayesfric: interrupted")
    assert _tree(project) == before  # its work folder and temporary files removed, nothing else
    assert not list(store.glob(".*.tmp"))
    assert (decoy / "keep.txt").read_text() == "not bayesfric's"
