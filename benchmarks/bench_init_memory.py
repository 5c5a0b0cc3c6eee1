"""Peak memory of the chains' initialisation: prior medians, bounded Pathfinder, blackjax's Pathfinder.

Usage::

    .venv/bin/python benchmarks/bench_init_memory.py [--rows 800 10000] [--laws lugre dahl coulomb_viscous]
        [--inits median pathfinder unbounded] [--cap-gb 6] [--fit --draws 500 --tune 500]

Data: SIMULATED reciprocating tribometer loops (``data/tribo_loops/generate.py``'s Dahl truth and
noise, translational, µm and mN), four strokes of 10/20/30/40 µm at 1 Hz, ``rows / 4`` samples each:
800 rows (the size of issue 29's tribometer log) and 10⁴ rows. Laws run as ``bayesfric fit`` runs
them on these data (``bayesfric.laws.variants.for_data``): LuGre and Dahl (stateful, a scan over
the rows) and Coulomb-viscous (steady state).

Inits, each in a fresh whole process (``subprocess``), one after another:

* ``median``: prior-median starts (``bayesfric.inference.init.chain_starts(init="median")``);
* ``pathfinder``: multi-path Pathfinder bounded by ``limits.INIT_NUMBERS`` (the library's);
* ``unbounded``: the Pathfinder that ``init.py`` ran before issue 29 item 2, reproduced here:
  ``blackjax.vi.pathfinder.approximate`` + ``sample``, vmapped over the 8 paths (every ELBO draw of
  every iterate of every path evaluated at once).

Each child builds the program, computes 4 chains' starts and reports its peak RSS (``ru_maxrss``:
the whole process, interpreter, data and compilation included), the seconds of the starts (the
compilation included: each child has its own empty JAX cache folder) and the log densities of the
starts. The parent polls the child's resident memory and kills it above ``--cap-gb`` (the machine
is shared): such a row reads "> cap". With ``--fit`` the child then runs the whole NUTS fit from
those starts (``bayesfric.inference.fit``) and reports the gate and the mean leapfrog steps per
warm-up draw, its peak RSS covering the fit. Writes ``reports/benchmarks/bench_init_memory.json``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "reports" / "benchmarks" / "bench_init_memory.json"
CHAINS = 4


def write_loops(rows: int, folder: Path) -> Path:
    """Four tribometer strokes of ``rows // 4`` samples (CSV + sidecar in ``folder``)."""
    spec = importlib.util.spec_from_file_location("tribo_generate", REPO / "data" / "tribo_loops" / "generate.py")
    generate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(generate)
    generate.AMPLITUDES = (10e-6, 20e-6, 30e-6, 40e-6)
    generate.PER_CYCLE, generate.CYCLES = rows // len(generate.AMPLITUDES), 1
    generate.main(folder)
    return folder / f"{generate.NAME}.csv"


def unbounded_starts(program, chains: int, seed: int):
    """The starts of ``init.py`` before issue 29 item 2 (every evaluation at once)."""
    import blackjax
    import jax

    from bayesfric.density import median_starts, start_seeds
    from bayesfric.inference import init

    density = program.density(seed)
    starts = median_starts(program, start_seeds(seed, max(init.PATHS, chains)))

    def one_path(key, x0):
        k_fit, k_draw = jax.random.split(key)
        state, _ = blackjax.vi.pathfinder.approximate(k_fit, density.log_joint, x0, maxiter=init.MAXITER)
        draws, log_q = blackjax.vi.pathfinder.sample(k_draw, state, init.DRAWS_PER_PATH)
        return draws, jax.vmap(density.log_joint)(draws) - log_q

    keys = jax.random.split(jax.random.PRNGKey(seed), len(starts))
    draws, log_w = jax.jit(jax.vmap(one_path))(keys, starts)
    draws, log_w = np.asarray(draws).reshape(-1, density.dim), np.asarray(log_w).ravel()
    finite = np.isfinite(log_w) & np.isfinite(draws).all(axis=1)
    weights = np.where(finite, np.exp(log_w - log_w[finite].max()), 0.0)
    pick = np.random.default_rng(seed).choice(weights.size, size=chains, replace=False, p=weights / weights.sum())
    return draws[pick]


def child(args: argparse.Namespace) -> None:
    """One law, size and init in this process; prints one JSON line."""
    import jax

    from bayesfric.api.fitting import load_data
    from bayesfric.inference import fit, init
    from bayesfric.inference.diagnostics import check
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import for_data
    from bayesfric.model import build_program

    ds = load_data(write_loops(args.rows, Path(args.folder)))
    law = for_data(get_law(args.law), ds)
    program = build_program(law, ds)
    start = time.perf_counter()
    if args.init == "unbounded":
        z = unbounded_starts(program, CHAINS, args.seed)
    else:
        z = init.chain_starts(program, CHAINS, args.seed, args.init)
    seconds = time.perf_counter() - start
    log_p = np.asarray(jax.vmap(program.density(args.seed).log_joint)(jax.numpy.asarray(z)))
    row = {"rows": program.n_obs, "seconds": seconds, "start_log_p": [round(float(v), 1) for v in log_p]}
    if args.fit and args.init != "unbounded":
        start = time.perf_counter()
        dt = fit(law, ds, draws=args.draws, tune=args.tune, chains=CHAINS, seed=args.seed, init=args.init)
        verdict = check(dt)
        row |= {"fit_seconds": time.perf_counter() - start, "passed": bool(verdict.passed),
                "problems": list(verdict.problems),
                "steps_per_draw": float(dt["sample_stats"]["n_steps"].mean())}
    row["peak_rss_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9
    print(json.dumps(row))


def run(law: str, rows: int, init: str, folder: Path, args: argparse.Namespace) -> dict:
    """One whole-process run, killed above ``args.cap_gb`` of resident memory."""
    env = dict(os.environ, BAYESFRIC_CACHE_DIR=str(folder / f"cache_{law}_{rows}_{init}"))
    cmd = [sys.executable, __file__, "--child", "--law", law, "--rows", str(rows), "--inits", init,
           "--folder", str(folder), "--seed", str(args.seed), "--draws", str(args.draws), "--tune", str(args.tune)]
    cmd += ["--fit"] if args.fit else []
    row: dict = {"law": law, "rows": rows, "init": init}
    start = time.perf_counter()
    with subprocess.Popen(cmd, env=env, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) as proc:
        capped = False
        while proc.poll() is None:
            if resident_gb(proc.pid) > args.cap_gb:
                proc.kill()
                capped = True
            time.sleep(0.2)
        out, err = proc.communicate()
    row["wall_seconds"] = time.perf_counter() - start
    if capped:
        return row | {"peak_rss_gb": None, "capped_at_gb": args.cap_gb}
    if proc.returncode:
        raise RuntimeError(f"{law} {rows} {init} failed:\n{err[-3000:]}")
    return row | json.loads(out.strip().splitlines()[-1])


def resident_gb(pid: int) -> float:
    """Resident memory of process ``pid`` now (0 where it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024 / 1e9
    except OSError:
        pass
    return 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, nargs="+", default=[800, 10_000])
    parser.add_argument("--laws", nargs="+", default=["lugre", "dahl", "coulomb_viscous"])
    parser.add_argument("--inits", nargs="+", default=["median", "pathfinder", "unbounded"],
                        choices=["median", "pathfinder", "unbounded"])
    parser.add_argument("--cap-gb", type=float, default=6.0, help="kill a child above this resident memory")
    parser.add_argument("--fit", action="store_true", help="also run the NUTS fit from the starts")
    parser.add_argument("--draws", type=int, default=500)
    parser.add_argument("--tune", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--law", help=argparse.SUPPRESS)
    parser.add_argument("--folder", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        args.rows, args.init = args.rows[0], args.inits[0]
        return child(args)
    results = []
    with tempfile.TemporaryDirectory(prefix="bench_init_memory_") as tmp:
        for rows in args.rows:
            for law in args.laws:
                for init in args.inits:
                    folder = Path(tmp) / f"{law}_{rows}_{init}"
                    folder.mkdir()
                    row = run(law, rows, init, folder, args)
                    results.append(row)
                    peak = (f"> {row['capped_at_gb']:.1f} (killed)" if row["peak_rss_gb"] is None
                            else f"{row['peak_rss_gb']:.2f}")
                    extra = (f"  fit {row['fit_seconds']:.0f} s passed={row['passed']} "
                             f"steps/draw {row['steps_per_draw']:.1f}" if "passed" in row else "")
                    print(f"{rows:>6} {law:<16} {init:<10} peak RSS {peak} GB  starts "
                          f"{row.get('seconds', float('nan')):6.1f} s  log p {row.get('start_log_p')}{extra}",
                          flush=True)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"settings": vars(args), "load1": os.getloadavg()[0], "results": results}, indent=1))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
