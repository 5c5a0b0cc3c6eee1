"""The main job: a folder of studies run side by side in processes gives what a serial run gives."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bayesfric.cli import main
from bayesfric.pipeline.mainjob import run_flagship, study_order
from bayesfric.study import StudyError
from bayesfric.study.store import STORE_ENV
from tests.test_study import data_csv, study_text, write_bench_data  # noqa: F401 -- the fixture is used by name

ONE_LAW = '[[laws]]\nname = "coulomb_viscous"\n'


@pytest.fixture
def studies(tmp_path, data_csv):  # noqa: F811
    """Two small studies of the same data in one folder (one law each, quick-sized sampling)."""
    return _write_studies(tmp_path)


def _write_studies(tmp_path: Path) -> Path:
    """The two study files of :func:`studies`, next to the data ``tmp_path`` holds."""
    folder = tmp_path / "studies"  # only study files: the data stays next to it
    folder.mkdir()
    for name, law in (("alpha", ONE_LAW), ("beta", '[[laws]]\nname = "coulomb"\n')):
        text = study_text(law).replace('name = "tiny"', f'name = "{name}"').replace('"bench.csv"', '"../bench.csv"')
        (folder / f"{name}.toml").write_text(text.replace("draws = 1000\ntune = 500", "draws = 300\ntune = 300"))
    return folder


@pytest.fixture(scope="module")
def main_command(tmp_path_factory) -> tuple[Path, Path, subprocess.CompletedProcess]:
    """``bayesfric main --jobs 2`` on the two studies, run once as a user runs it (its own store
    under --out): (studies folder, reports folder, the finished command). Two tests read it."""
    root = tmp_path_factory.mktemp("main")
    write_bench_data(root)
    studies = _write_studies(root)
    env = {k: v for k, v in os.environ.items() if k != STORE_ENV}
    done = subprocess.run([sys.executable, "-m", "bayesfric", "main", "--studies", str(studies), "--jobs", "2",
                           "--out", str(root / "reports")], capture_output=True, text=True, timeout=600, env=env)
    return studies, root / "reports", done


def test_studies_in_two_processes_give_the_serial_numbers(tmp_path, main_command, monkeypatch):
    """Same units, inputs and seeds in a spawned process (``main --jobs 2``): ranking.csv and
    parameters.csv equal a serial run's byte for byte; the closing table covers both studies' units."""
    studies, reports, done = main_command
    assert done.returncode == 0, done.stderr[-2000:]
    monkeypatch.delenv(STORE_ENV, raising=False)  # the serial run computes every unit itself
    serial = run_flagship(tmp_path / "serial", studies=studies, jobs=1)
    parallel = sorted(p for p in reports.iterdir() if not p.name.startswith("."))
    assert [f.name for f in serial] == [f.name for f in parallel] == ["alpha", "beta"]
    for one, two in zip(serial, parallel, strict=True):
        for name in ("ranking.csv", "parameters.csv"):
            assert (one / name).read_bytes() == (two / name).read_bytes(), (one.name, name)
    out = done.stdout
    assert "main job: 2 studies in" in out and "(2 at a time, one process each)" in out
    fit_row = next(line for line in out.split("main job: time per stage")[-1].splitlines()
                   if line.split()[:1] == ["fit"])
    assert fit_row.split()[1] == "2"  # both studies' fits counted in the closing table


def test_an_unchanged_rerun_starts_no_process(tmp_path, studies, capsys, monkeypatch):
    """Current reports are recognised before any process starts (a spawned process spends
    seconds importing); a changed study is rerun, in this process when it is the only one."""
    from bayesfric.pipeline import mainjob

    first = run_flagship(tmp_path / "reports", studies=studies, jobs=2)
    capsys.readouterr()

    def no_processes(*args, **kwargs):
        raise AssertionError("an unchanged rerun started study processes")

    monkeypatch.setattr(mainjob, "_run_parallel", no_processes)
    assert run_flagship(tmp_path / "reports", studies=studies, jobs=2) == first
    out = capsys.readouterr().out
    assert out.count("unchanged: the report in") == 2
    beta = studies / "beta.toml"
    beta.write_text(beta.read_text().replace("seed = 0", "seed = 1") if "seed = 0" in beta.read_text()
                    else beta.read_text().replace("[sampler]\n", "[sampler]\nseed = 1\n"))
    run_flagship(tmp_path / "reports", studies=studies, jobs=2)
    out = capsys.readouterr().out
    assert "[alpha] unchanged" in out and "[beta] unchanged" not in out and "[beta] report written" in out


def test_longest_study_starts_first(tmp_path, studies):
    """Order by the previous report's unit seconds, then by the number of laws."""
    files = sorted(studies.glob("*.toml"))
    out = tmp_path / "reports"
    assert [f.stem for f in study_order(files, out)] == ["alpha", "beta"]  # one law each: file order
    (out / "beta").mkdir(parents=True)
    (out / "beta" / "timings.csv").write_text("study,law,stage,label,status,seconds,stored_seconds\n"
                                              "beta,coulomb,fit,fit,computed,9.0,nan\n"
                                              "beta,coulomb,loo,loo,reused,0,2.5\n")
    assert [f.stem for f in study_order(files, out)] == ["beta", "alpha"]


def test_a_study_not_run_before_counts_grouped_laws_as_several(tmp_path):
    """With no previous report, a law with group or trend terms counts GROUPED_COST laws: the
    seed studies' weighted counts are drum_campaigns 3 x 4 = 12, robot_joint 6 + 4 = 10,
    dahl_duplex 6, pitch_bearing 6, unwinder 5, drum_rollout 2 (ties keep file order)."""
    from bayesfric.study import STUDIES_DIR

    files = sorted(STUDIES_DIR.glob("*.toml"))
    order = [f.stem for f in study_order(files, tmp_path / "reports")]
    assert order == ["drum_campaigns", "robot_joint", "dahl_duplex", "pitch_bearing", "unwinder", "drum_rollout"]


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_bad_study_file_stops_the_main_job_before_anything_runs(tmp_path, studies, jobs):
    """Every study file is read and checked first: one bad file, one line, nothing written."""
    (studies / "gamma.toml").write_text(study_text('[[laws]]\nname = "no_such_law"\n').replace("bench", "../bench"))
    with pytest.raises(StudyError, match="gamma.toml: laws\\[0\\].name: unknown law"):
        run_flagship(tmp_path / "reports", studies=studies, jobs=jobs)
    assert not (tmp_path / "reports").exists()


@pytest.mark.parametrize(("argv", "message"), [
    (["main", "--jobs", "0"], "--jobs: must be a number of studies ≥ 1, got 0"),
    (["main", "--jobs", "2", "--workers", "2"], "--jobs and --workers/--scheduler: give one"),
])
def test_jobs_option_errors_are_one_line(tmp_path, capsys, argv, message):
    assert main(argv + ["--out", str(tmp_path / "reports")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"bayesfric: error: {message}") and err.count("\n") == 1
    assert not (tmp_path / "reports").exists()


def test_the_main_command_returns_when_its_study_processes_are_done(main_command):
    """``bayesfric main`` leaves with ``os._exit``: its study processes must have exited by then,
    or they would wait for work forever and keep its output pipes open (the run would never end:
    :func:`main_command` gives it 600 s)."""
    _, reports, done = main_command
    assert done.returncode == 0, done.stderr[-2000:]
    assert "main job: 2 studies in" in done.stdout
    assert sorted(p.name for p in reports.iterdir() if not p.name.startswith(".")) == ["alpha", "beta"]


def test_a_studies_folder_that_is_not_one_is_a_one_line_error(tmp_path, capsys):
    assert main(["main", "--studies", str(tmp_path / "nope"), "--out", str(tmp_path / "reports")]) == 2
    assert capsys.readouterr().err == f"bayesfric: error: --studies {tmp_path / 'nope'}: not a folder\n"
    assert not (tmp_path / "reports").exists()


@pytest.mark.parametrize(("cores", "gib", "studies", "jobs"), [
    (2, 24, 5, 2),  # the development machine: one per core
    (16, 24, 5, 5),  # at most one per study
    (8, 8, 5, 3),  # (8 - 2 GiB reserved) / 2 GiB per study process
    (8, 3, 5, 1),  # never below 1
])
def test_default_jobs_is_bounded_by_cores_memory_and_studies(monkeypatch, cores, gib, studies, jobs):
    from bayesfric.pipeline import mainjob

    monkeypatch.setattr(mainjob.os, "cpu_count", lambda: cores)
    monkeypatch.setattr(mainjob, "_memory_bytes", lambda: gib * 1024**3)
    assert mainjob.default_jobs(studies) == jobs


@pytest.mark.parametrize(("jobs", "cpus", "threads"),
                         [(2, 2, 1), (1, 2, 2), (4, 2, 1), (2, 16, 2), (3, 7, 2), (5, 1, 1)])
def test_study_processes_share_the_cores_for_compiling(jobs, cpus, threads):
    from bayesfric.pipeline.mainjob import compile_threads_per_study

    assert compile_threads_per_study(jobs, cpus) == threads
