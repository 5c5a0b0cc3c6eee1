"""Every stateful (hysteresis) law on loops simulated from another law, at tribometer scale (issue 29).

Data: SIMULATED Dahl loops (F_c0 = 500 µN, x_c0 = 2 µm, i = 1.5, noise 5 µN), written as a
tribometer CSV in µN, mm, mm/s and ms with a sidecar and read by the loader (the helpers of
``tests/test_tribometer.py``). Two designs:

* ``tribo`` — the shipped ``tribo_loops`` scale: 3 stroke amplitudes (10, 20, 30 µm) × 2 cycles ×
  60 samples = 360 rows;
* ``800`` — the issue's measured log: 4 loops (10, 20, 30, 40 µm), one cycle each, 200 samples a
  loop = 800 rows;
* ``5000`` — a long trajectory (issue 50's 5 000-row budget): 5 loops (10–50 µm), one cycle each,
  1000 samples a loop = 5000 rows.

Each law (``dahl``, ``lugre``, ``maxwell_slip`` (N = 4), ``gms`` (N = 4), ``elastoplastic``) is
fitted with its default priors and the default sampler settings (4 chains × (1000 + 1000), chains
from prior medians) in a fresh process under a time limit; the row says whether the diagnostics
gate passed, its R-hat / ESS / divergences, leapfrog steps per draw and the fit's seconds relative
to Dahl's on the same data (the issue's budget: ≤ 3×). Seconds move with the shared machine's
load, printed with each row.

A law name ``<law>_<reduction>`` (``lugre_Fs_eq_Fc``) fits the companion a study would add on the
data (issue 50 item 2, :mod:`bayesfric.identifiability`).

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_stateful_loops.py [--design 800] [--laws dahl lugre]
[--limit 1800] [--init pathfinder] [--seeds 1 2 3 4]``. ``--seeds`` runs every law on each data seed in
turn (Dahl first on each, so each ratio is to Dahl on the same data; issue 50's target is four seeds × the
two designs). Writes ``reports/benchmarks/bench_stateful_loops.json`` (``--out`` for another file).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "reports" / "benchmarks" / "bench_stateful_loops.json"
LAWS = ["dahl", "lugre", "maxwell_slip", "gms", "elastoplastic"]
DESIGNS = {"tribo": {"per_cycle": 60, "cycles": 2, "runs": (10e-6, 20e-6, 30e-6)},
           "800": {"per_cycle": 200, "cycles": 1, "runs": (10e-6, 20e-6, 30e-6, 40e-6)},
           "5000": {"per_cycle": 1000, "cycles": 1, "runs": (10e-6, 20e-6, 30e-6, 40e-6, 50e-6)}}


def child(law_name: str, design: str, seed: int, init: str = "median") -> dict:
    """Simulate the Dahl loops of ``design``, fit ``law_name`` with defaults (chains started by
    ``init``: prior medians, the default, or ``"pathfinder"``), return the row."""
    import numpy as np

    from bayesfric.compare import verdict_of
    from bayesfric.inference import fit
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import vary
    from tests import test_tribometer as tt

    truth_law = vary(get_law("dahl"), without=["preload"], motion="translational")
    layout = DESIGNS[design]
    with tempfile.TemporaryDirectory() as tmp:
        original = tt._loops
        tt._loops = lambda: original(**layout)  # the design's strokes through the tests' writer
        try:
            ds = tt._write(Path(tmp), truth_law, tt.DAHL, seed=seed)
        finally:
            tt._loops = original
        law = _law(law_name, ds)
        start = time.perf_counter()
        dt = fit(law, ds, seed=1, **({} if init == "median" else {"init": init}))
        seconds = time.perf_counter() - start
    verdict = verdict_of(dt)
    steps = float(np.asarray(dt["sample_stats"]["n_steps"]).mean()) if "n_steps" in dt["sample_stats"] else None
    return {"law": law_name, "design": design, "init": init, "rows": int(ds.sizes["obs"]), "seconds": seconds,
            "passed": bool(verdict.passed), "rhat_max": verdict.rhat_max, "ess_bulk_min": verdict.ess_bulk_min,
            "ess_tail_min": verdict.ess_tail_min, "divergences": verdict.divergences,
            "steps_per_draw": steps, "problems": list(verdict.problems),
            "loglik_rhat_max": verdict.loglik_rhat_max, "loglik_ess_bulk_min": verdict.loglik_ess_bulk_min,
            "predictions_converged": verdict.predictions_converged, "multimodal": bool(verdict.multimodal),
            "unidentified": list(verdict.unidentified), "mode_note": verdict.mode_note}


def _law(name: str, ds):
    """A registered law, or ``<law>_<reduction>``: the companion a study would add on ``ds``
    (its reduced variant, :mod:`bayesfric.identifiability`), e.g. ``lugre_Fs_eq_Fc``."""
    from bayesfric import identifiability
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import for_data, vary
    from bayesfric.model import Noise, build_program

    base = next((b for b in LAWS if name.startswith(b + "_")), None)
    if base is None:
        return get_law(name)
    law = for_data(get_law(base), ds)
    checks = identifiability.assess(law, base, ds, build_program(law, ds, noise=Noise()).resolved)
    suffix, fixed = identifiability.reduction(checks)
    if f"{base}_{suffix}" != name:
        raise SystemExit(f"{name}: on these data the companion of {base} is {base}_{suffix or '(none)'}")
    return vary(get_law(base), fixed=fixed)


def run_one(law_name: str, design: str, seed: int, limit: float, init: str = "median") -> dict:
    """One law in a fresh process under ``limit`` seconds."""
    cmd = [sys.executable, __file__, "--child", law_name, "--design", design, "--seed", str(seed), "--init", init]
    start = time.perf_counter()
    load = os.getloadavg()[0]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=limit, cwd=ROOT,
                              env=os.environ | {"PYTHONPATH": str(ROOT)})
    except subprocess.TimeoutExpired:
        return {"law": law_name, "design": design, "timed_out": limit, "load_start": load}
    lines = [x for x in proc.stdout.splitlines() if x.startswith("{")]
    if proc.returncode != 0 or not lines:
        return {"law": law_name, "design": design, "error": proc.stderr[-1500:], "load_start": load}
    row = json.loads(lines[-1])
    row.update(wall=time.perf_counter() - start, load_start=load, load_end=os.getloadavg()[0])
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--design", choices=sorted(DESIGNS), default="800")
    parser.add_argument("--laws", nargs="+", default=LAWS)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--seeds", type=int, nargs="+", help="data seeds, each law on each (overrides --seed)")
    parser.add_argument("--out", type=Path, default=OUT, help="JSON file written after each row")
    parser.add_argument("--limit", type=float, default=1800.0, help="seconds per law (a fit past it is cut)")
    parser.add_argument("--init", choices=["median", "pathfinder"], default="median",
                        help="chain starts of every law (the default: prior medians)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child(args.child, args.design, args.seed, args.init)), flush=True)
        return
    seeds = args.seeds or [args.seed]
    rows = []
    for seed in seeds:
        for name in args.laws:
            row = run_one(name, args.design, seed, args.limit, args.init)
            row["seed"] = seed
            rows.append(row)
            dahl = next((r["seconds"] for r in rows
                         if r["law"] == "dahl" and r["seed"] == seed and "seconds" in r), None)
            if "seconds" in row and dahl:
                row["vs_dahl"] = row["seconds"] / dahl
            print(json.dumps(row), flush=True)
            args.out.parent.mkdir(parents=True, exist_ok=True)
            summary = {"design": args.design, "seeds": seeds, "init": args.init, "rows": rows}
            args.out.write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
