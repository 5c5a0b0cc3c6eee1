"""What running the chains in chunks costs (progress inside a fit): the same compiled engine
with chunks of ``CHUNK_STEPS`` schedule rows against one chunk (the whole scan in one call).

Run: ``.venv/bin/python benchmarks/bench_chunked.py [--law stribeck] [--repeats 5]``

Per setting: one :class:`~bayesfric.inference.engine.NutsEngine` on simulated data (4 chains ×
(1000 + 1000), the defaults of ``bayesfric fit``), compiled and warmed by a first run, then
``--repeats`` runs of the all-true mask, interleaved between the two settings, timed. The draws
of the two settings are checked equal. Prints one JSON line per law; writes
``reports/benchmarks/bench_chunked.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from bayesfric.datasets.synthetic import simulate
from bayesfric.inference.chunked import CHUNK_STEPS
from bayesfric.inference.engine import NutsEngine
from bayesfric.laws import get_law
from bayesfric.model import build_program

OUT = Path(__file__).resolve().parents[1] / "reports" / "benchmarks" / "bench_chunked.json"
TRUTH = {"coulomb_viscous": {"T_C": 1.0, "c_v": 0.5},
         "stribeck": {"T_C": 1.0, "dT_s": 0.5, "v_s": 0.3, "delta": 0.7}}


def _data(law_name: str, rows: int):
    law = get_law(law_name)
    params = TRUTH[law_name]
    return law, simulate(law, {"velocity": np.linspace(-2, 2, rows)}, params, sigma=0.05, seed=4)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--law", nargs="+", default=["coulomb_viscous", "stribeck"])
    parser.add_argument("--rows", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    results = []
    for name in args.law:
        law, ds = _data(name, args.rows)
        program = build_program(law, ds)
        mask = np.ones((1, program.n_obs), dtype=bool)
        engines = {"chunked": NutsEngine.build(program, tune=1000, seed=1, chunk_steps=CHUNK_STEPS),
                   "one call": NutsEngine.build(program, tune=1000, seed=1, chunk_steps=10**9)}
        first = {k: e.run(mask) for k, e in engines.items()}  # compiles (or loads) and warms
        same = bool(np.array_equal(first["chunked"].samples[next(iter(first["chunked"].samples))],
                                   first["one call"].samples[next(iter(first["one call"].samples))]))
        seconds: dict[str, list[float]] = {k: [] for k in engines}
        cpu: dict[str, list[float]] = {k: [] for k in engines}  # CPU seconds of this process: less
        for _ in range(args.repeats):                           # sensitive to other processes
            for k, e in engines.items():
                start, start_cpu = time.perf_counter(), time.process_time()
                e.run(mask)
                seconds[k].append(time.perf_counter() - start)
                cpu[k].append(time.process_time() - start_cpu)
        med = {k: float(np.min(v)) for k, v in seconds.items()}  # the least disturbed run (shared cores)
        med_cpu = {k: float(np.median(v)) for k, v in cpu.items()}
        row = dict(law=name, rows=args.rows, chunk=CHUNK_STEPS, chains=4, draws=1000, tune=1000,
                   seconds=seconds, fastest=med, median_cpu=med_cpu,
                   cpu_overhead=med_cpu["chunked"] / med_cpu["one call"] - 1,
                   fallbacks=engines["chunked"].kernel.sampler.fallbacks, overhead=med["chunked"] / med["one call"] - 1,
                   identical=same)
        print(json.dumps(row), flush=True)
        results.append(row)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
