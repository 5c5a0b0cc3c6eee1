"""Report folders: marked, replaced atomically, never someone else's, stale work cleaned, modes
follow the umask, user strings escaped. Fast tests drive :mod:`bayesfric.fsutil` directly; one
slow test kills a real study run and runs the study twice more."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import bayesfric
from bayesfric import fsutil
from bayesfric.cli import main
from bayesfric.inference import save_fit
from bayesfric.pipeline.runner import run_study


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


def _modes(folder: Path) -> set[tuple[str, int]]:
    """{(kind, mode)} of everything under ``folder`` (itself included)."""
    return {("dir" if p.is_dir() else "file", _mode(p)) for p in [folder, *folder.rglob("*")]}


@pytest.fixture
def umask():
    """Set the process umask for a test (restored afterwards)."""
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def _fake_work(root: Path, name: str, token: str, pid: int, study: str | None = None) -> Path:
    work = root / f".{name}.{token}"
    work.mkdir(parents=True)
    marker = {"tool": "bayesfric", "study": study or name, "pid": pid, "host": os.uname().nodename,
              "created": time.time(), "proc_start": fsutil._proc_start(pid)}
    (work / fsutil.MARKER).write_text(json.dumps(marker))
    (work / "big.nc").write_bytes(b"x" * 1000)
    return work


@pytest.mark.parametrize(("mask", "file_mode", "dir_mode"), [(0o022, 0o644, 0o755), (0o027, 0o640, 0o750),
                                                             (0o002, 0o664, 0o775)])
def test_work_folder_and_install_follow_the_umask(tmp_path, umask, mask, file_mode, dir_mode):
    umask(mask)
    root = tmp_path / "reports"
    work = fsutil.create_work_folder(root, "s1")
    (work / "fits").mkdir()
    (work / "fits" / "private.nc").write_bytes(b"")
    os.chmod(work / "fits" / "private.nc", 0o600)  # as tempfile.mkstemp leaves it
    final = fsutil.report_folder(root, "s1")
    fsutil.install_folder(work, final, "s1")
    assert _modes(final) == {("dir", dir_mode), ("file", file_mode)}
    assert _mode(root) == dir_mode


def test_save_fit_file_follows_the_umask(tmp_path, umask):
    umask(0o027)
    dt = xr.DataTree.from_dict({"posterior": xr.Dataset({"a": ("draw", np.arange(3.0))})})
    path = save_fit(dt, tmp_path / "new" / "fit.nc")
    assert _mode(path) == 0o640 and _mode(path.parent) == 0o750
    assert [p.name for p in path.parent.iterdir()] == ["fit.nc"]  # no temporary file left


def test_rerun_replaces_the_marked_folder_atomically(tmp_path):
    root = tmp_path / "reports"
    for content in ("first", "second"):
        work = fsutil.create_work_folder(root, "s1")
        (work / f"{content}.md").write_text(content)
        fsutil.install_folder(work, fsutil.report_folder(root, "s1"), "s1")
    assert sorted(p.name for p in (root / "s1").iterdir()) == [fsutil.MARKER, "second.md"]
    assert [p.name for p in root.iterdir()] == ["s1"]  # neither work nor old folder left


def test_unmarked_or_foreign_report_folder_is_refused_untouched(tmp_path):
    root = tmp_path / "reports"
    (root / "mine").mkdir(parents=True)
    (root / "mine" / "notes.md").write_text("a colleague's")
    other = fsutil.create_work_folder(root, "other")
    (root / "other-study").mkdir()
    (root / "other-study" / fsutil.MARKER).write_text((other / fsutil.MARKER).read_text())  # marked for "other"
    for name in ("mine", "other-study"):
        with pytest.raises(fsutil.PathError, match="not written by bayesfric"):
            fsutil.report_folder(root, name)
        work = fsutil.create_work_folder(root, name)
        with pytest.raises(fsutil.PathError):
            fsutil.install_folder(work, root / name, name)
        assert work.exists()  # the caller removes its own work folder
        fsutil.remove_work_folder(work, name)
    assert (root / "mine" / "notes.md").read_text() == "a colleague's"


def test_stale_work_folders_of_dead_runs_are_cleaned_and_live_ones_kept(tmp_path):
    root = tmp_path / "reports"
    dead = _fake_work(root, "s1", "dead0000", _dead_pid())
    live = _fake_work(root, "s1", "live0000", os.getpid())
    other_study = _fake_work(root, "s1", "x.dead0000", _dead_pid(), study="s1.x")  # ".s1.x.*" is study s1.x
    unmarked = root / ".s1.nomarker"
    unmarked.mkdir()
    removed = fsutil.clean_stale_work(root, "s1")
    assert removed == [dead]
    assert not dead.exists() and live.exists() and other_study.exists() and unmarked.exists()


@pytest.mark.parametrize("name", [".", "..", "", "/etc", "../x", "a/b", "a b", "a\x00b", ".h", "x" * 65, "ok\n"])
def test_report_folder_refuses_names_that_are_not_slugs(tmp_path, name):
    with pytest.raises(fsutil.PathError):
        fsutil.report_folder(tmp_path, name)


STUDY = """[study]
name = "tiny"
title = "<script>alert(1)</script> *not bold* | # [link](javascript:x)"
question = "- a list? 1. no"
[data]
dataset = "robot_joint"
select = {{ series = [1, 2] }}
[sampler]
{sampler}
[[laws]]
name = "coulomb"
[compare]
loo = true
evidence = false
[[compare.blocked]]
axis = "velocity"
threshold = 0.5
label = "<b>train</b> | low *speeds*"
"""


def _kill_a_run_mid_way(folder: Path) -> Path:
    """Start the study in a subprocess, SIGKILL it once its work folder exists; return that folder."""
    env = dict(os.environ, PYTHONPATH=str(Path(bayesfric.__file__).parents[1]))
    proc = subprocess.Popen([sys.executable, "-m", "bayesfric", "study", "s.toml", "--out", "reports"], cwd=folder,
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            found = [p for p in (folder / "reports").glob(".tiny.*") if (p / fsutil.MARKER).exists()]
            if found:
                proc.send_signal(signal.SIGKILL)
                break
            time.sleep(0.1)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    return found[0]


@pytest.mark.slow
def test_killed_run_is_cleaned_rerun_replaces_modes_follow_umask_and_text_is_escaped(tmp_path, umask):
    (tmp_path / "s.toml").write_text(STUDY.format(sampler="draws = 200\ntune = 200\nchains = 2"))
    stale = _kill_a_run_mid_way(tmp_path)
    live = _fake_work(tmp_path / "reports", "tiny", "live0000", os.getpid())  # a concurrent run: kept

    umask(0o027)
    folder = run_study(tmp_path / "s.toml", out_root=tmp_path / "reports")
    assert not stale.exists() and live.exists()
    assert _modes(folder) == {("dir", 0o750), ("file", 0o640)}
    assert fsutil.is_marked(folder, "tiny")
    summary = (folder / "summary.md").read_text()
    html = (folder / "report.html").read_text()
    assert "<script>" not in summary and "\\<script\\>" in summary and "<b>train" not in summary
    assert "<script>alert" not in html and "&lt;script&gt;" in html and "<b>train" not in html
    assert "**Question.** - a list? 1. no" in summary  # inline text: no list, nothing to escape
    (folder / "extra.txt").write_text("from the first run")

    umask(0o022)  # rerun with emcee and --quick: replaces the marked folder
    (tmp_path / "s.toml").write_text(STUDY.format(sampler='name = "emcee"\ndraws = 600\ntune = 300\nwalkers = 8'))
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        assert main(["study", "s.toml", "--out", "reports", "--quick"]) == 0
    finally:
        os.chdir(cwd)
    assert not (folder / "extra.txt").exists()
    assert _modes(folder) == {("dir", 0o755), ("file", 0o644)}
    assert "QUICK MODE: sampler draws=600, tune=300, thin=10" in (folder / "summary.md").read_text()
    assert sorted(p.name for p in (tmp_path / "reports").iterdir()) == [".store", live.name, "tiny"]  # + run store
