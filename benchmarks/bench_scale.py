"""Scale of a study grid: serial against a 2-worker Dask cluster, per-unit cost, store-hit rerun.

Run: ``.venv/bin/python benchmarks/bench_scale.py [--datasets 4] [--workers 2]``

Grid: ``--datasets`` simulated data sets (``coulomb_viscous`` at 40 speeds in both directions,
each with its own coefficients and noise seed; SIMULATED data) × the laws ``coulomb``,
``coulomb_viscous`` and ``stribeck``, one study per data set, run with ``--quick`` settings
(NUTS 300 draws × 2 chains; PSIS-LOO, one blocked fold, checks; evidence off). Each phase
runs in its own process so its peak memory (``ru_maxrss``) is its own:

1. ``warmup``: the whole grid once, to fill the JAX persistent compilation cache (a fresh one in
   the benchmark's temporary folder), so the two timed phases below both run with a warm cache
   (a first try that warmed up data set 0 only ran data sets 1-2 3x slower in the serial phase
   than in the later Dask phase, which found their programs in the cache the serial phase
   had filled: the compiled programs appear to differ per data set);
2. ``serial``: the whole grid, ``fresh`` (every unit computed), in one process;
3. ``dask``: the whole grid, ``fresh``, on a ``LocalCluster`` of ``--workers`` single-threaded
   processes; peak memory is read from every worker;
4. ``rerun``: the serial grid again, unchanged: every unit is a store hit.

Per-unit cost against grid position: the serial phase's computed seconds per stage for the
first and the last data set (it must stay flat, not climb as compiled code builds up).
Timings on a shared machine are noisy. Writes ``reports/benchmarks/bench_scale.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "reports" / "benchmarks" / "bench_scale.json"
LAWS = ("coulomb", "coulomb_viscous", "stribeck")
SIDECAR = ('[dataset]\nname = "{name}"\nprovenance = "simulated"\nsource = "bench_scale.py"\n'
           '[columns.speed]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n'
           '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n')


def write_grid(folder: Path, n: int) -> list[Path]:
    """``n`` simulated data sets and their study files under ``folder``; returns the study files."""
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.laws import get_law

    speeds = np.geomspace(0.01, 4.0, 20)
    v = np.concatenate([-speeds[::-1], speeds])
    studies = []
    for i in range(n):
        truth = {"T_C": 2.0 + 0.5 * i, "c_v": 1.0 + 0.25 * i}
        ds = simulate(get_law("coulomb_viscous"), {"velocity": v}, truth, sigma=0.1, seed=100 + i)
        rows = ["speed,torque"] + [f"{a:.10g},{b:.10g}" for a, b in zip(v, ds["torque"].values, strict=True)]
        (folder / f"d{i}.csv").write_text("\n".join(rows) + "\n")
        (folder / f"d{i}.toml").write_text(SIDECAR.format(name=f"d{i}"))
        laws = "".join(f'[[laws]]\nname = "{law}"\n' for law in LAWS)
        study = folder / f"grid{i}.toml"
        study.write_text(f'[study]\nname = "grid{i}"\n[data]\ndataset = "d{i}.csv"\n{laws}'
                         '[compare]\nloo = true\nevidence = false\nfailed_fits = "run"\n'
                         '[[compare.blocked]]\naxis = "velocity"\nthreshold = 2.0\n')
        studies.append(study)
    return studies


def phase(name: str, folder: Path, n: int, workers: int) -> dict:
    """Run one phase in this process; return its timings and peak memory."""
    from bayesfric.pipeline.runner import run_study
    from bayesfric.study.executor import open_client

    studies = sorted(folder.glob("grid*.toml"))[:n]
    out = folder / ("reports-dask" if name == "dask" else "reports")
    rows: list = []
    start = time.perf_counter()
    with open_client(workers if name == "dask" else 0) as client:
        for path in studies:
            run_study(path, out_root=out, quick=True, fresh=name in ("serial", "dask"), client=client, timings=rows)
        worker_rss = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) if client else {}
    wall = time.perf_counter() - start
    return {"phase": name, "wall_s": wall, "units": len(rows),
            "computed": sum(r.status == "computed" for r in rows), "reused": sum(r.status == "reused" for r in rows),
            "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "worker_peak_rss_mib": sorted(v / 1024 for v in worker_rss.values()),
            "rows": [[r.study, r.law, r.stage, r.label, r.status, r.seconds] for r in rows]}


def per_unit_cost(rows: list, n: int) -> dict:
    """Mean computed seconds per stage for the first and the last data set of the grid."""
    table = {}
    for stage in ("fit", "loo", "cv", "checks"):
        first = [r[5] for r in rows if r[0] == "grid0" and r[2] == stage and r[4] == "computed"]
        last = [r[5] for r in rows if r[0] == f"grid{n - 1}" and r[2] == stage and r[4] == "computed"]
        table[stage] = {"first_dataset_s": float(np.mean(first)), "last_dataset_s": float(np.mean(last))}
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", type=int, default=4)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--phase", help=argparse.SUPPRESS)
    parser.add_argument("--folder", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.phase:  # child process
        print("PHASE " + json.dumps(phase(args.phase, Path(args.folder), args.datasets, args.workers)))
        return
    results = {}
    with tempfile.TemporaryDirectory(prefix="bench_scale_") as tmp:
        folder = Path(tmp)
        write_grid(folder, args.datasets)
        env = os.environ | {"BAYESFRIC_CACHE_DIR": str(folder / "jax-cache")}
        env.pop("BAYESFRIC_STORE_DIR", None)
        for name in ("warmup", "serial", "dask", "rerun"):
            start = time.perf_counter()
            proc = subprocess.run([sys.executable, __file__, "--phase", name, "--folder", str(folder),
                                   "--datasets", str(args.datasets), "--workers", str(args.workers)],
                                  capture_output=True, text=True, env=env)
            if proc.returncode != 0:
                sys.exit(f"phase {name} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
            line = next(x for x in reversed(proc.stdout.splitlines()) if x.startswith("PHASE "))
            results[name] = json.loads(line[6:]) | {"process_wall_s": time.perf_counter() - start}
            print(f"{name}: {results[name]['wall_s']:.1f} s in the run, {results[name]['process_wall_s']:.1f} s "
                  f"with process start; {results[name]['computed']} computed, {results[name]['reused']} reused",
                  flush=True)
    serial, dask = results["serial"], results["dask"]
    summary = {
        "grid": f"{args.datasets} data sets x {len(LAWS)} laws, --quick", "workers": args.workers,
        "speedup": serial["wall_s"] / dask["wall_s"],
        "serial_peak_rss_mib": serial["peak_rss_mib"], "worker_peak_rss_mib": dask["worker_peak_rss_mib"],
        "per_unit_cost": per_unit_cost(serial["rows"], args.datasets),
        "rerun_wall_s": results["rerun"]["wall_s"], "rerun_process_wall_s": results["rerun"]["process_wall_s"],
        "cpu_count": os.cpu_count(), "platform": platform.platform(),
    }
    print(json.dumps(summary, indent=1))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"summary": summary, "phases": results}, indent=1))


if __name__ == "__main__":
    main()
