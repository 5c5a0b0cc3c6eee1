"""The main job: every study in a folder (the seed studies by default), several at once.

Each study runs in its own process (``spawn``: a fresh interpreter, no JAX state forked), at
most ``jobs`` at a time; the studies are independent (their own data, units, run store and
report folder), so running them side by side changes no number: every unit has the same inputs
and seeds as in a serial run. A law's fit, folds and evidence stay in one process, so a law is
compiled (or read from the persistent cache) once, as in a serial run.

Why processes: one study keeps about 1.4 of the 2 cores busy (its chains run on two threads,
but tracing, report figures and sizing are single-threaded Python), so a second study in
parallel uses the rest. Measured on the 2-core machine, ``benchmarks/bench_main.py`` with
``--jobs 1`` and with the default (2) one after the other: 429 → 346 s with an empty
compilation cache, 234 → 184 s with a warm one (0.81× and 0.79×). Each process holds its own
compiled programs (1.3-1.7 GB peak per study process), hence the memory bound of
:func:`default_jobs`. A rerun whose reports are all current starts no process: the reports are
checked here first (:func:`bayesfric.pipeline.runner.current_report`).

The longest studies start first (largest total of the previous report's ``timings.csv``; for a
study not run before, its number of laws, a law with group or trend terms counting
:data:`GROUPED_COST`), so the last one to finish is a short one. Progress
lines from the processes interleave, each prefixed by its study; the per-stage table at the end
covers all of them.
"""

from __future__ import annotations

import contextlib
import csv
import math
import multiprocessing
import os
import time
from concurrent.futures import FIRST_EXCEPTION, Future, ProcessPoolExecutor, wait
from pathlib import Path

from bayesfric.limits import max_processes, physical_memory
from bayesfric.study.config import Study, StudyError, load_study

__all__ = ["run_flagship", "default_jobs", "study_order", "compile_threads_per_study"]


def _memory_bytes() -> int | None:
    return physical_memory()


def default_jobs(studies: int) -> int:
    """Studies run at once by default: one per CPU core, as many as the memory holds
    (:func:`bayesfric.limits.max_processes`: 2 GiB each, 2 GiB left, the bound ``--jobs`` and
    ``--workers`` are checked against too), at most ``studies``; 1 on an accelerator (each
    process would claim most of its memory)."""
    import jax

    if jax.default_backend() != "cpu":
        return 1
    memory = _memory_bytes()
    by_memory = studies if memory is None else max_processes(memory)
    return int(max(1, min(studies, os.cpu_count() or 1, by_memory)))


#: A law with group or trend terms in the order of studies not run before, in ordinary laws: in a
#: cold main job drum_campaigns' trend laws took 42-98 s (fit and folds), its neighbours' laws
#: 10-30 s; with each law counting one, the study ran last and alone.
GROUPED_COST = 4


def _expected_seconds(study: Study, out_root: Path) -> tuple[float, int]:
    """(seconds of the previous report's units, the laws' weighted count): the order key of a study."""
    seconds = 0.0
    with contextlib.suppress(OSError, ValueError, KeyError):  # no previous report, or another format
        with (out_root / study.name / "timings.csv").open(newline="") as fh:
            for row in csv.DictReader(fh):
                value = float(row["seconds"]) if row["status"] == "computed" else float(row["stored_seconds"] or 0)
                seconds += 0.0 if math.isnan(value) else value  # NaN stored_seconds: fits read back
    return seconds, sum(GROUPED_COST if spec.vary_by or spec.trend else 1 for spec in study.laws)


def study_order(files: list[Path], out_root: Path) -> list[Path]:
    """``files`` longest first (see the module notes); ties keep their order.

    Raises
    ------
    StudyError
        A study file that does not load (every file is read here, before any study runs).
    """
    keys = {path: _expected_seconds(load_study(path), out_root) for path in files}
    return sorted(files, key=lambda path: (-keys[path][0], -keys[path][1]))


def _current_reports(files: list[Path], out_root: Path, quick: bool) -> dict[Path, Path]:
    """The studies whose report an unchanged rerun would leave as it is, and their folders:
    checked here, so a rerun starts no process (each would spend seconds importing). Each study
    to run checks again in its own process; this pass cost 0.47 s for the five seed studies with
    no reports (imports included, 0.05 s on a second pass), against ~2.5 s to start a process."""
    from bayesfric.pipeline.runner import current_report

    return {path: folder for path in files if (folder := current_report(path, out_root, quick)) is not None}


def compile_threads_per_study(jobs: int, cpus: int | None = None) -> int:
    """Background compilation threads of each of ``jobs`` study processes side by side: their
    share of the ``cpus`` cores (default: this machine's), at least one, at most the default
    (:data:`bayesfric.exported.COMPILE_THREADS`; see :func:`bayesfric.exported.set_compile_threads`)."""
    from bayesfric.exported import COMPILE_THREADS

    cpus = (os.cpu_count() or 1) if cpus is None else cpus
    return max(1, min(COMPILE_THREADS, cpus // max(1, jobs)))


def _run_in_child(path: Path, out_root: Path, quick: bool, fresh: bool, compile_threads: int) -> tuple[Path, list]:
    """One study in a spawned process: its report folder and timing rows."""
    from bayesfric.exported import set_compile_threads
    from bayesfric.pipeline.runner import run_study

    set_compile_threads(compile_threads)
    rows: list = []
    folder = run_study(path, out_root=out_root, quick=quick, fresh=fresh, timings=rows, live_progress=False)
    return folder, rows


def _run_parallel(files: list[Path], jobs: int, out_root: Path, quick: bool, fresh: bool) -> tuple[dict, list]:
    """Every study of ``files`` in up to ``jobs`` processes, started in that order; (folder by
    study file, timing rows)."""
    folders: dict[Path, Path] = {}
    timings: list = []
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"))
    try:
        threads = compile_threads_per_study(jobs)
        futures: dict[Future, Path] = {pool.submit(_run_in_child, path, out_root, quick, fresh, threads): path
                                       for path in files}
        done, pending = wait(futures, return_when=FIRST_EXCEPTION)
        for future in done:  # the first error, if any, is raised here; studies still running finish
            folders[futures[future]], rows = future.result()
            timings += rows
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    # Every result is in; wait for the processes to exit (their interpreter teardown, under a
    # second): one left waiting for work would outlive this process and hold its output pipes.
    pool.shutdown(wait=True)
    return folders, timings


def run_flagship(out_root: str | Path = "reports", quick: bool = False, *, fresh: bool = False, workers: int = 0,
                 scheduler: str | None = None, jobs: int | None = None, studies: Path | None = None) -> list[Path]:
    """The main job: run every study in ``studies/`` (one per seed experiment) and write reports.

    Parameters
    ----------
    out_root, quick, fresh, workers, scheduler
        As in :func:`bayesfric.pipeline.runner.run_study`; one Dask cluster serves every study, and with
        ``workers`` or ``scheduler`` the studies run one after the other (Dask spreads the units).
    jobs : int, optional
        Studies run at once, each in its own process (see the module notes); default
        :func:`default_jobs`. 1 runs them one after the other in this process. The processes
        are spawned (they import the calling script again): a script that calls this with
        ``jobs`` > 1 must do so under ``if __name__ == "__main__":``, as for any
        :mod:`multiprocessing` code.
    studies : Path, optional
        Folder of the study files (default: the seed studies, ``STUDIES_DIR``).

    Returns
    -------
    list of Path
        The report folders, in the order of the study files.

    Prints one per-stage timing table over all studies and the total wall time.
    """
    from bayesfric.pipeline.runner import run_study
    from bayesfric.study import STUDIES_DIR
    from bayesfric.study.executor import open_client, timing_table

    start = time.perf_counter()
    folder = STUDIES_DIR if studies is None else Path(studies)
    files = sorted(folder.glob("*.toml"))
    if not files:
        raise StudyError(f"{folder}: no study files")
    order = study_order(files, Path(out_root))  # every study file checked before anything runs
    if jobs is None:
        jobs = 1 if (workers or scheduler) else default_jobs(len(files))
    timings: list = []
    if jobs > 1 and not (workers or scheduler):
        by_file = _current_reports(files, Path(out_root), quick) if not fresh else {}
        to_run = [path for path in order if path not in by_file]
        if len(to_run) > 1:
            ran, timings = _run_parallel(to_run, min(jobs, len(to_run)), Path(out_root), quick, fresh)
        else:  # one study left: no process to start
            ran = {path: run_study(path, out_root=out_root, quick=quick, fresh=fresh, timings=timings)
                   for path in to_run}
        folders = [(by_file | ran)[path] for path in files]
    else:
        with open_client(workers, scheduler) as client:
            folders = [run_study(path, out_root=out_root, quick=quick, fresh=fresh, client=client, timings=timings)
                       for path in files]
    print("\n" + timing_table(timings, "main job: time per stage over all studies"))
    print(f"\nmain job: {len(folders)} studies in {time.perf_counter() - start:.0f} s"
          + (f" ({jobs} at a time, one process each)" if jobs > 1 and not (workers or scheduler) else ""))
    for report in folders:
        print(f"  {report / 'summary.md'}")
    return folders
