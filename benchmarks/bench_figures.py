"""Cost of a study's report (figures + renderings) against one fit, on a shipped study.

Runs ``STUDY`` (default ``studies/robot_joint.toml``) with ``--quick`` into a temporary folder,
timing :func:`bayesfric.report.study_figures.draw` and the whole
:func:`bayesfric.report.summary.write_reports` against the laws' fit times (the ``fit`` stage of
each law: sampling + DataTree, compilation included). Prints one line per measure::

    .venv/bin/python benchmarks/bench_figures.py [STUDY.toml]
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

from bayesfric.pipeline.runner import run_study
from bayesfric.report import summary


def main(study: str) -> None:
    seen: dict = {}
    real_draw, real_write = summary.draw, summary.write_reports

    def draw(*args, **kwargs):
        t = time.perf_counter()
        result = real_draw(*args, **kwargs)
        seen["figures"] = time.perf_counter() - t
        return result

    def write(tree, *args, **kwargs):
        t = time.perf_counter()
        written = real_write(tree, *args, **kwargs)
        seen["report"] = time.perf_counter() - t
        seen["fits"] = [float(s) for s in tree["diagnostics"]["timing"].sel(stage="fit").values]
        return written

    summary.draw, summary.write_reports = draw, write
    with tempfile.TemporaryDirectory() as tmp:
        run_study(study, out_root=Path(tmp), quick=True)
    fit = statistics.median(seen["fits"])
    print(f"study {study} (--quick): {len(seen['fits'])} laws, median fit {fit:.1f} s")
    print(f"figures {seen['figures']:.1f} s = {seen['figures'] / fit:.2f}x one fit")
    print(f"whole report (figures + md + html + csv) {seen['report']:.1f} s = {seen['report'] / fit:.2f}x one fit")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "studies/robot_joint.toml")
