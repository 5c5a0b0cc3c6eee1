"""Studies: TOML files under studies/ that run comparisons and write reports/<study>/."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from bayesfric.builtin import builtin_folder
from bayesfric.study.config import Study, StudyError, load_study

__all__ = ["Study", "StudyError", "load_study", "run_study", "run_flagship", "STUDIES_DIR"]

#: The seed studies: ``studies/`` of the repository, shipped as package data (bayesfric.builtin).
STUDIES_DIR = builtin_folder("bayesfric.builtin_studies", "studies")


def __getattr__(name: str) -> Any:
    # The runner pulls in every comparison, report and sizing module; commands that only read
    # the study schema (``bayesfric fit``) should not pay for importing them.
    if name == "run_study":
        from bayesfric.study.runner import run_study

        return run_study
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def run_flagship(out_root: str | Path = "reports", quick: bool = False, *, fresh: bool = False, workers: int = 0,
                 scheduler: str | None = None) -> list[Path]:
    """The main job: run every study in ``studies/`` (one per seed experiment) and write reports.

    ``fresh``, ``workers`` and ``scheduler`` as in :func:`run_study` (one Dask cluster serves
    every study). Prints one per-stage timing table over all studies and the total wall time.
    """
    from bayesfric.study.executor import open_client, timing_table
    from bayesfric.study.runner import run_study

    start = time.perf_counter()
    folders = []
    files = sorted(STUDIES_DIR.glob("*.toml"))
    if not files:
        raise StudyError(f"{STUDIES_DIR}: no study files")
    timings: list = []
    with open_client(workers, scheduler) as client:
        for path in files:
            folders.append(run_study(path, out_root=out_root, quick=quick, fresh=fresh, client=client,
                                     timings=timings))
    print("\n" + timing_table(timings, "main job: time per stage over all studies"))
    print(f"\nmain job: {len(folders)} studies in {time.perf_counter() - start:.0f} s")
    for folder in folders:
        print(f"  {folder / 'summary.md'}")
    return folders
