"""Wall time of the main job: cold compilation cache, warm cache, and an unchanged rerun.

Run: ``.venv/bin/python benchmarks/bench_main.py [--jobs N] [--workers 0] [--phases cold warm rerun]``

Each phase is one ``python -m bayesfric main`` process, timed from start to exit by this
process, with its output in a fresh temporary folder and its own ``BAYESFRIC_CACHE_DIR``
(JAX's persistent compilation cache):

1. ``cold``: an empty compilation cache and an empty run store (what a fresh clone does, the
   virtual environment aside);
2. ``warm``: the same cache, ``--fresh`` (every unit of work recomputed, nothing compiled that
   the cold phase compiled already): what a changed study costs once its code is compiled;
3. ``rerun``: the same cache and output folder, unchanged inputs: the run store answers and
   the reports are left as they are.

``--jobs N`` passes ``--jobs N`` to each phase (studies side by side, one process each; default:
the main job's own default, one per core); ``--workers N`` passes ``--workers N`` (Dask
``LocalCluster``, units of one study at a time; 0: not used).
Targets of the engine issue: ≤ 10 min cold, ≤ 3 min warm. The per-stage table each phase
prints at its end is kept. Timings on the shared machine drift: compare phases of one run.
Writes ``reports/benchmarks/bench_main.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / "reports" / "benchmarks" / "bench_main.json"
PHASES = ("cold", "warm", "rerun")
#: A study's closing line: "[name] report written to FOLDER (N s)".
STUDY_DONE = re.compile(r"^\[([^\]]+)\] report written to .* \((\d+) s\)$", re.MULTILINE)


def run_phase(phase: str, cache: Path, out: Path, workers: int, jobs: int | None) -> dict:
    """One ``bayesfric main`` process; its wall seconds, exit code and closing table."""
    cmd = [sys.executable, "-m", "bayesfric", "main", "--out", str(out)]
    if phase == "warm":
        cmd.append("--fresh")
    if workers:
        cmd += ["--workers", str(workers)]
    if jobs is not None:
        cmd += ["--jobs", str(jobs)]
    env = dict(os.environ, BAYESFRIC_CACHE_DIR=str(cache))
    start = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    tail = done.stdout[done.stdout.rfind("main job: time per stage"):] if "main job" in done.stdout else ""
    studies = dict(STUDY_DONE.findall(done.stdout))
    return {"phase": phase, "seconds": round(seconds, 1), "returncode": done.returncode,
            "table": tail.strip(), "study_seconds": {k: float(v) for k, v in studies.items()},
            "stderr_tail": done.stderr[-2000:] if done.returncode else ""}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=None)
    parser.add_argument("--json", type=Path, default=OUT, help=f"where to write the record (default {OUT})")
    parser.add_argument("--phases", nargs="+", choices=PHASES, default=list(PHASES))
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory(prefix="bench_main_") as tmp:
        cache, out = Path(tmp) / "cache", Path(tmp) / "reports"
        for phase in args.phases:
            load = os.getloadavg()[0]
            result = run_phase(phase, cache, out, args.workers, args.jobs) | {"load_before": round(load, 2)}
            results.append(result)
            print(f"{phase}: {result['seconds']:.1f} s (exit {result['returncode']}, load before {load:.2f})",
                  flush=True)
            if result["returncode"]:
                print(result["stderr_tail"], file=sys.stderr)
                break
    record = {"workers": args.workers, "jobs": args.jobs, "phases": results, "cpu_count": os.cpu_count(),
              "python": platform.python_version(), "when": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(record, indent=2))
    print(f"written {args.json}")


if __name__ == "__main__":
    main()
