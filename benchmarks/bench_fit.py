"""One fit, NUTS against emcee, side by side: wall time and minimum bulk/tail ESS.

Usage: .venv/bin/python benchmarks/bench_fit.py [--n 60] [--repeats 2]

Law ``stribeck`` simulated on a Stribeck-curve design (both directions, 0.002–4 rad/s); both
backends run with their defaults (NUTS: 4 chains × 1000 tune + 1000 draws; emcee: MAP start,
max(32, 4·ndim) walkers × 2500 burn-in + 2500 steps, thinned by 10). The first call of each
backend includes compilation; the second (``--repeats 2``) a warm cache. Writes
``reports/benchmarks/bench_fit.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from bayesfric.datasets.synthetic import simulate
from bayesfric.inference import fit, verdict_of
from bayesfric.laws import get_law

TRUTH = {"T_C": 10.0, "dT_s": 4.0, "v_s": 0.05, "delta": 0.8}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=60, help="observations")
    parser.add_argument("--repeats", type=int, default=2, help="runs per backend (first compiles)")
    args = parser.parse_args()
    law = get_law("stribeck")
    speeds = np.geomspace(0.002, 4.0, args.n // 2)
    ds = simulate(law, {"velocity": np.concatenate([-speeds[::-1], speeds])}, TRUTH, sigma=0.2, seed=7)
    rows = []
    for repeat in range(args.repeats):
        for sampler in ("nuts", "emcee"):
            start = time.perf_counter()
            dt = fit(law, ds, sampler=sampler, seed=repeat)
            seconds = time.perf_counter() - start
            v = verdict_of(dt)
            rows.append({"sampler": sampler, "repeat": repeat, "seconds": seconds, "ess_bulk_min": v.ess_bulk_min,
                         "ess_tail_min": v.ess_tail_min, "rhat_max": v.rhat_max, "gate": v.passed})
            print(f"{sampler:6s} run {repeat}: {seconds:6.1f} s  min ESS bulk {v.ess_bulk_min:6.0f}  "
                  f"tail {v.ess_tail_min:6.0f}  R-hat {v.rhat_max:.3f}  gate {'passed' if v.passed else 'FAILED'}")
    last = {r["sampler"]: r for r in rows if r["repeat"] == args.repeats - 1}
    ratio = last["emcee"]["seconds"] / last["nuts"]["seconds"]
    per_ess = (last["emcee"]["seconds"] / last["emcee"]["ess_bulk_min"]) / (
        last["nuts"]["seconds"] / last["nuts"]["ess_bulk_min"])
    print(f"emcee/NUTS wall-time ratio (last run): {ratio:.2f}; time per bulk-ESS ratio: {per_ess:.2f}")
    out = Path("reports/benchmarks/bench_fit.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"n": args.n, "runs": rows, "emcee_over_nuts": ratio,
                               "emcee_over_nuts_per_ess": per_ess}, indent=2))


if __name__ == "__main__":
    main()
