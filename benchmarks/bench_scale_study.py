"""A whole 3-law study as the data grow: peak memory and seconds per stage (issue 30, item 3).

Usage::

    .venv/bin/python benchmarks/bench_scale_study.py [--rows 10000 100000] [--chains 4]
        [--draws 1000] [--tune 1000] [--no-evidence] [--trace]

Data: SIMULATED steady-state Stribeck friction, the rows of ``bench_scale_rows.dataset`` (T_C = 2,
dT_s = 1, v_s = 0.1 rad/s, δ = 0.8, σ = 0.1 N·m; speeds log-uniform on 0.01–4 rad/s both ways).
Study: the laws ``coulomb``, ``coulomb_viscous`` and ``stribeck``; PSIS-LOO, 5-fold CV, one blocked
scheme (train ≤ 1 rad/s, score above), evidence (bridge sampling and Laplace importance
sampling), the checks; report written as ``bayesfric study`` writes it, every unit computed
(``fresh``, a new store per run).

Each size runs in a fresh child process under ``/usr/bin/time -v``: its wall seconds and peak RSS
("Maximum resident set size") are the whole study's, report assembly included. Per-stage
seconds are the sums over laws of the report's ``timings.csv``, with its units counted by status
(a law whose full fit fails the diagnostics gate skips its folds and evidence). With ``--trace``
the child also reports the resident memory per stage (``benchmarks/stage_memory.py``: on entry,
on exit, sampled inside, and each stage's share of the rise of the high-water mark). Writes
``reports/benchmarks/bench_scale_study.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "reports" / "benchmarks" / "bench_scale_study.json"
LAWS = ["coulomb", "coulomb_viscous", "stribeck"]
SIDECAR = """[dataset]
name = "scale_study"
provenance = "simulated"
source = "benchmarks/bench_scale_study.py"
description = "SIMULATED steady-state Stribeck friction (benchmarks/bench_scale_rows.py dataset)"

[columns.velocity]
role = "input"
quantity = "velocity"
unit = "rad/s"

[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"
"""


def child(rows: int, out: Path, draws: int, tune: int, chains: int, evidence: bool, trace: bool = False) -> None:
    """Run the study on ``rows`` rows into ``out`` (the child's whole work); with ``trace``, print
    the resident memory per stage (:mod:`stage_memory`) as a ``STAGE_MEMORY`` JSON line."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    from bench_scale_rows import dataset

    import bayesfric

    if trace:
        import stage_memory

        stop = stage_memory.start()

    ds = dataset(rows)
    csv_path = out / f"scale_{rows}.csv"
    csv_path.write_text("velocity,torque\n" + "".join(
        f"{float(v)!r},{float(t)!r}\n" for v, t in zip(ds["velocity"].values, ds["torque"].values, strict=True)))
    csv_path.with_suffix(".toml").write_text(SIDECAR)
    study = bayesfric.Study(
        f"scale_{rows}", str(csv_path), laws=LAWS,
        sampler={"draws": draws, "tune": tune, "chains": chains, "seed": 0},
        compare={"loo": True, "kfold": 5, "evidence": evidence,
                 "blocked": [{"axis": "velocity", "threshold": 1.0, "direction": "upper",
                              "label": "train ≤ 1 rad/s, score above"}]})
    start = time.perf_counter()
    bayesfric.run(study, out=out, fresh=True)
    print(f"STUDY_SECONDS {time.perf_counter() - start:.1f}", flush=True)
    if trace:
        stop.set()
        print("STAGE_MEMORY " + json.dumps(stage_memory.report()), flush=True)


def stages(folder: Path) -> tuple[dict[str, float], dict[str, dict[str, int]]]:
    """Seconds per stage (summed over laws) from a report's ``timings.csv``, and the units of
    each stage by status (computed, skipped: a full fit failed the gate, ...)."""
    total: dict[str, float] = defaultdict(float)
    status: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    with (folder / "timings.csv").open(newline="") as fh:
        for row in csv.DictReader(fh):
            total[row["stage"]] += float(row["seconds"] or "nan")
            status[row["stage"]][row["status"]] += 1
    return {k: round(v, 1) for k, v in total.items()}, {k: dict(v) for k, v in status.items()}


def measure(rows: int, args: argparse.Namespace) -> dict:
    """One size in a fresh process under ``/usr/bin/time -v``."""
    with tempfile.TemporaryDirectory(prefix="bench_study_") as tmp:
        cmd = ["/usr/bin/time", "-v", sys.executable, __file__, "--child", str(rows), "--out", tmp,
               "--draws", str(args.draws), "--tune", str(args.tune), "--chains", str(args.chains)]
        cmd += ["--no-evidence"] if args.no_evidence else []
        cmd += ["--trace"] if args.trace else []
        start = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - start
        rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
        study = re.search(r"STUDY_SECONDS ([\d.]+)", proc.stdout)
        folder = Path(tmp) / f"scale_{rows}"
        result = {"rows": rows, "returncode": proc.returncode, "wall_s": round(wall, 1),
                  "study_s": float(study.group(1)) if study else None,
                  "peak_rss_gb": round(int(rss.group(1)) / 1024**2, 2) if rss else None,
                  "stages_s": {}, "units": {},
                  "settings": {"draws": args.draws, "tune": args.tune, "chains": args.chains,
                               "evidence": not args.no_evidence}}
        traced = re.search(r"STAGE_MEMORY (.*)", proc.stdout)
        if traced:
            result["stage_memory"] = json.loads(traced.group(1))
        if (folder / "timings.csv").exists():
            result["stages_s"], result["units"] = stages(folder)
        if (folder / "ranking.csv").exists():
            with (folder / "ranking.csv").open(newline="") as fh:
                result["ranking"] = [{k: r.get(k) for k in ("law", "elpd_loo", "elpd_loo_se",
                                                            "elpd_loo_subsampling_se", "loo_rows_scored")}
                                     for r in csv.DictReader(fh)]
        if proc.returncode:
            result["stderr_tail"] = proc.stderr[-3000:]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--chains", type=int, default=4)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--tune", type=int, default=1000)
    parser.add_argument("--no-evidence", action="store_true")
    parser.add_argument("--trace", action="store_true",
                        help="resident memory per stage (benchmarks/stage_memory.py; sampled every 0.1 s)")
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.out, args.draws, args.tune, args.chains, not args.no_evidence, args.trace)
        return
    results = []
    for rows in args.rows:
        results.append(measure(rows, args))
        print(json.dumps(results[-1]), flush=True)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
