"""Leapfrog steps per draw as the data grow: bayesfric's warm-up against Stan's rule and nutpie.

Usage::

    .venv/bin/python benchmarks/bench_scale_rows.py [--rows 1000 10000 100000] [--chains 4]
        [--draws 1000] [--tune 1000] [--sides bayesfric diag stan nutpie] [--save] [--cold]

Data: SIMULATED steady-state Stribeck friction (``bayesfric.datasets.synthetic.simulate``; T_C = 2,
dT_s = 1, v_s = 0.1 rad/s, δ = 0.8, σ = 0.1 N·m; speeds log-uniform on 0.01–4 rad/s in both
directions), the same rows for every side at a size.

Sides, each a fresh whole process timed by this parent, interleaved per size:

* ``bayesfric``: ``bayesfric.inference.fit`` with its defaults (the compiled blackjax NUTS engine,
  its warm-up with the scale-relative regulariser and the ``auto`` metric of
  :mod:`bayesfric.inference.adaptation`: dense on this law's correlated posterior);
* ``diag``, ``auto``: the same with ``metric="diag"`` (the default before 2026-11-26) or
  ``metric="auto"`` set explicitly;
* ``fisher``: the same with the Fisher diagonal (``adaptation.DIAGONAL = "fisher"``, measured but
  not the default: see that module);
* ``dense``: the same with the dense metric in every chain (``metric="dense"``: on this law's
  correlated posterior it takes ~4× fewer steps; on weakly correlated seed laws it passed the
  gate less often, hence ``auto``; ``benchmarks/bench_adaptation.py``);
* ``stan``: the same, with the warm-up's metric estimated and regularised as Stan and blackjax's
  ``mass_matrix_adaptation`` do (positions' variance, shrunk towards ``1e-3 I``) — patched in
  this benchmark's child only, to show the before/after side by side;
* ``nutpie``: PyMC + nutpie on the same model, priors and data (the child of
  ``benchmarks/bench_vs_pymc.py``; needs the ``bench`` extra: ``pip install -e ".[bench]"``).

Reported per size and side: wall seconds of the process, leapfrog steps per draw (mean over all
draws and chains), the smallest bulk ESS over the four coefficients (arviz-stats, from the draws),
divergences, peak RSS (the child's ``ru_maxrss``) and the posterior means; the
bayesfric children time the sampling call alone as well (``fit`` also assembles pointwise
log-likelihood and predictive draws, which is what memory grew with: issue 30 item 2). With
``--save`` a bayesfric child also writes its fit (``bayesfric.inference.save_fit``, as ``bayesfric fit
--out`` does) and reports the file's size, its peak RSS then covering the write too; the fit's
``pointwise_storage`` attr (what it keeps per row) is reported with it. Each bayesfric side runs
twice per size with one cache folder (the first fills JAX's persistent compilation cache; the
second, warm, is the one reported; ``--cold`` runs once). Writes
``reports/benchmarks/bench_scale_rows.json``.
"""

from __future__ import annotations

import argparse
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
OUT = REPO / "reports" / "benchmarks" / "bench_scale_rows.json"
TRUTH = {"T_C": 2.0, "dT_s": 1.0, "v_s": 0.1, "delta": 0.8}
SIGMA = 0.1


def dataset(rows: int):
    """The simulated data set of ``rows`` rows (seeded by its size)."""
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.laws import get_law

    rng = np.random.default_rng(rows)
    v = rng.choice([-1.0, 1.0], rows) * np.exp(rng.uniform(np.log(0.01), np.log(4.0), rows))
    return simulate(get_law("stribeck"), {"velocity": v}, TRUTH, sigma=SIGMA, seed=rows + 1)


def stan_metric(diagonal: bool):
    """Stan's (absolute) regulariser in the shape of ``adaptation._scale_relative_metric``."""
    import jax.numpy as jnp
    from blackjax.adaptation.mass_matrix import welford_algorithm

    wc_init, wc_update, wc_final = welford_algorithm(diagonal)

    def final(state, current):
        covariance, count, _ = wc_final(state)
        target = 1e-3 * (jnp.ones_like(covariance) if diagonal else jnp.eye(covariance.shape[0]))
        return (count / (count + 5.0)) * covariance + (5.0 / (count + 5.0)) * target, wc_init(covariance.shape[0])

    return wc_init, lambda state, position, grad: wc_update(state, position), final


def bayesfric_child(args: argparse.Namespace) -> None:
    """Child: fit the data set of ``args.rows`` rows; one JSON line of figures on stdout."""
    from bayesfric.inference import fit
    from bayesfric.laws import get_law

    if args.child == "stan":
        import bayesfric.inference.adaptation as adaptation

        adaptation._scale_relative_metric = stan_metric
    if args.child == "fisher":
        import bayesfric.inference.adaptation as adaptation

        adaptation.DIAGONAL = "fisher"
    ds = dataset(args.rows)
    start = time.perf_counter()
    metric = {"metric": args.child} if args.child in ("dense", "diag", "auto") else {}
    dt = fit(get_law("stribeck"), ds, seed=args.seed, draws=args.draws, tune=args.tune, chains=args.chains,
             **metric)
    seconds = time.perf_counter() - start
    stats, post = dt["sample_stats"], dt["posterior"]
    saved = {}
    if args.save:
        from bayesfric.inference import save_fit

        with tempfile.TemporaryDirectory(prefix="bench_scale_rows_fit_") as tmp:
            path = save_fit(dt, Path(tmp) / "fit.nc")
            saved = {"fit_file_mb": path.stat().st_size / 1e6,
                     "pointwise_storage": json.loads(dt.attrs.get("pointwise_storage", "null"))}
    print(json.dumps({"fit_seconds": seconds, "steps_per_draw": float(stats["n_steps"].mean()),
                      "divergent": int(stats["diverging"].sum()),
                      "means": {k: float(post[k].mean()) for k in TRUTH},
                      "ess_bulk_min": ess_min({k: np.asarray(post[k]) for k in TRUTH}),
                      "sds": {k: float(post[k].std()) for k in TRUTH},
                      "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, **saved}))


def ess_min(draws: dict[str, np.ndarray]) -> float:
    """The smallest bulk ESS over the coefficients (each draws shaped (chain, draw))."""
    from arviz_stats.base import array_stats

    return min(float(array_stats.ess(np.asarray(v).reshape(v.shape[0], -1), chain_axis=0, draw_axis=1,
                                     method="bulk")) for v in draws.values())


def nutpie_spec(rows: int, folder: Path) -> Path:
    """The JSON spec ``bench_vs_pymc``'s PyMC child reads, for the data set of ``rows`` rows."""
    from bayesfric.laws import get_law
    from bayesfric.model import build_program

    program = build_program(get_law("stribeck"), dataset(rows))
    priors = {k: {"dist": p.dist, "args": dict(p.args)} for k, p in program.resolved.items()}
    spec = {"law": "stribeck", "noise": "normal", "velocity": program.inputs["velocity"].tolist(),
            "torque": program.response.tolist(), "priors": priors, "constants": program.constants}
    path = folder / f"spec_{rows}.json"
    path.write_text(json.dumps(spec))
    return path


def run(side: str, rows: int, folder: Path, args: argparse.Namespace) -> dict:
    """One timed whole-process run of ``side`` at ``rows`` rows."""
    env = dict(os.environ, BAYESFRIC_CACHE_DIR=str(folder / f"cache_{side}"))
    sampling = ["--draws", str(args.draws), "--tune", str(args.tune), "--chains", str(args.chains)]
    if args.save and side != "nutpie":
        sampling.append("--save")
    if side == "nutpie":
        spec = nutpie_spec(rows, folder)
        cmd = [sys.executable, str(REPO / "benchmarks" / "bench_vs_pymc.py"), "--child", "pymc", "--spec", str(spec),
               "--out", str(folder / f"nutpie_{rows}.npz"), *sampling]
    else:
        cmd = [sys.executable, __file__, "--child", side, "--one", str(rows), *sampling]
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=REPO, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode:
        raise RuntimeError(f"{side} at {rows} rows failed:\n{proc.stderr[-3000:]}")
    row = {"side": side, "rows": rows, "wall_seconds": wall, "load1": os.getloadavg()[0],
           **json.loads(proc.stdout.strip().splitlines()[-1])}
    if side == "nutpie":
        row["steps_per_draw"] = row.pop("n_steps_mean")
        with np.load(folder / f"nutpie_{rows}.npz") as f:
            row["means"] = {k: float(f[k].mean()) for k in TRUTH}
            row["ess_bulk_min"] = ess_min({k: f[k] for k in TRUTH})
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, nargs="+", default=[1000, 10_000, 100_000])
    parser.add_argument("--sides", nargs="+", default=["bayesfric", "stan", "nutpie"],
                        choices=["bayesfric", "diag", "dense", "auto", "stan", "fisher", "nutpie"])
    parser.add_argument("--chains", type=int, default=4)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--tune", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cold", action="store_true", help="skip the cache-filling run (large sizes)")
    parser.add_argument("--save", action="store_true", help="bayesfric sides also write the fit; report its size")
    parser.add_argument("--child", choices=["bayesfric", "diag", "dense", "auto", "stan", "fisher"],
                        help=argparse.SUPPRESS)
    parser.add_argument("--one", type=int, dest="rows_one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        args.rows = args.rows_one
        return bayesfric_child(args)
    results = []
    with tempfile.TemporaryDirectory(prefix="bench_scale_rows_") as tmp:
        for rows in args.rows:
            for side in args.sides:
                if side != "nutpie" and not args.cold:
                    run(side, rows, Path(tmp), args)  # fills the compilation cache
                row = run(side, rows, Path(tmp), args)
                results.append(row)
                print(f"{rows:>8} {side:<9} wall {row['wall_seconds']:7.1f} s  steps/draw "
                      f"{row['steps_per_draw']:5.1f}  ESS min {row.get('ess_bulk_min', float('nan')):6.0f}  "
                      f"rss {row.get('peak_rss_gb', float('nan')):5.2f} GB  "
                      + (f"file {row['fit_file_mb']:7.1f} MB  " if "fit_file_mb" in row else "") +
                      f"means {', '.join(f'{k}={v:.4g}' for k, v in row['means'].items())}", flush=True)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"settings": vars(args), "results": results}, indent=1))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
