"""Answers for the next run: does a 90 % band for a *new* run cover that run's true mean curve?

Usage::

    .venv/bin/python benchmarks/bench_new_run.py [--replicates 120] [--runs 6] [--spread 0.15]

SIMULATED data. Each replicate draws ``--runs`` runs of ``coulomb_viscous`` at the same 20 speeds
(0.1-2 rad/s), whose Coulomb level and viscous coefficient vary between runs by a factor
``exp(spread · z)`` (``T_C = 2 N·m``, ``c_v = 1 N·m·s/rad`` typical, noise sd 0.05 N·m:
:func:`bayesfric.datasets.synthetic.simulate_runs`), holds one run out (replicate ``r`` holds out
run ``r mod runs``), and fits on the others, with NUTS (4 chains × 500 draws after 500 warm-up):

* ``pooled``: ``coulomb_viscous`` as today, every run the same curve;
* ``by run``: ``coulomb_viscous.vary_by("run", "T_C", "c_v")`` -- the held-out run's level is
  masked out of the likelihood, so its values are drawn from the group distribution: the answer
  for a new run (:mod:`bayesfric.hierarchy`).

Per law it reports how often the central 90 % band of the mean curve at 0.1, 1, 2 and 3 rad/s
(3 rad/s: half a tested range beyond the data) covers the held-out run's true mean curve, how
often the band covers the whole curve at once, the mean interval score (Gneiting & Raftery 2007,
alpha = 0.1: width plus 20× the miss; lower is sharper and better calibrated) and how often the
held-out run's log predictive density ranks the hierarchical law first (leave-one-run-out), both
pointwise (each row alone, ``Σ_i log mean_s p(y_i | θ_s)``, what a study's grouped folds score) and
jointly (the run's rows together, ``log mean_s Π_i p(y_i | θ_s)``, the density of a new run).
One compiled sampler per law serves every replicate (``NutsEngine.with_response``); the priors
are data-scaled on the first replicate's response.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bayesfric.datasets.synthetic import simulate_runs
from bayesfric.inference.engine import NutsEngine
from bayesfric.laws import get_law
from bayesfric.model import build_program

SPEEDS = np.linspace(0.1, 2.0, 20)
AT = np.array([0.1, 1.0, 2.0, 3.0])
TRUTH = {"T_C": 2.0, "c_v": 1.0}
SIGMA = 0.05
ALPHA = 0.1


def interval_score(lo, hi, x, alpha=ALPHA):
    """Gneiting & Raftery (2007) interval score of the central (1 - alpha) interval [lo, hi] at x."""
    return (hi - lo) + (2 / alpha) * np.maximum(lo - x, 0) + (2 / alpha) * np.maximum(x - hi, 0)


def joint_lpd(t_c, c_v, sigma, v, y) -> float:
    """``log mean_s prod_i p(y_i | theta_s)``: the held-out run's rows scored together, as one new run."""
    mu = t_c.reshape(-1)[:, None] + c_v.reshape(-1)[:, None] * v[None, :]
    sd = sigma.reshape(-1)[:, None]
    ll = (-0.5 * ((y[None, :] - mu) / sd) ** 2 - np.log(sd) - 0.5 * np.log(2 * np.pi)).sum(axis=1)
    return float(np.logaddexp.reduce(ll) - np.log(ll.size))


def band(t_c: np.ndarray, c_v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    curve = t_c.reshape(-1)[:, None] + c_v.reshape(-1)[:, None] * AT[None, :]
    return np.quantile(curve, ALPHA / 2, axis=0), np.quantile(curve, 1 - ALPHA / 2, axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=120)
    ap.add_argument("--runs", type=int, default=6)
    ap.add_argument("--spread", type=float, default=0.15)
    args = ap.parse_args()
    law = get_law("coulomb_viscous")
    spread = {"T_C": args.spread, "c_v": args.spread}

    def data(r):
        return simulate_runs(law, {"velocity": SPEEDS}, TRUTH, spread, runs=args.runs, sigma=SIGMA, seed=r)

    first, _ = data(0)
    settings = dict(draws=500, tune=500, chains=4, seed=0)
    engines = {"pooled": NutsEngine.build(build_program(law, first), **settings),
               "by run": NutsEngine.build(build_program(law.vary_by("run", "T_C", "c_v"), first), **settings)}
    run_of = np.asarray(first["run"].values)
    labels = sorted(set(run_of))
    rows = {k: {"cover": [], "all": [], "score": [], "elpd": [], "joint": [], "failed": 0, "s": 0.0} for k in engines}
    for r in range(args.replicates):
        ds, truth = data(r)
        g = r % args.runs
        held = run_of == labels[g]
        true_curve = truth["T_C"][g] + truth["c_v"][g] * AT
        for name, engine in engines.items():
            start = time.perf_counter()
            fits = engine.with_response(np.asarray(ds["torque"].values)).run(~held[None, :], seed=r)
            rows[name]["s"] += time.perf_counter() - start
            post = {k: v[0] for k, v in fits.samples.items()}
            if name == "by run":
                lo, hi = band(post["T_C_run"][..., g], post["c_v_run"][..., g])
            else:
                lo, hi = band(post["T_C"], post["c_v"])
            inside = (lo <= true_curve) & (true_curve <= hi)
            rows[name]["cover"].append(inside)
            rows[name]["all"].append(inside.all())
            rows[name]["score"].append(interval_score(lo, hi, true_curve))
            rows[name]["elpd"].append(float(fits.lpd[0, held].sum()))
            t_c, c_v = ((post["T_C_run"][..., g], post["c_v_run"][..., g]) if name == "by run"
                        else (post["T_C"], post["c_v"]))
            y_held = np.asarray(ds["torque"].values)[held]
            rows[name]["joint"].append(joint_lpd(t_c, c_v, post["sigma"], SPEEDS, y_held))
            rows[name]["failed"] += int(not fits.verdicts[0].passed)
    report(rows, args)


def report(rows: dict, args) -> None:
    n = args.replicates
    print(f"SIMULATED: {args.runs} runs x {SPEEDS.size} speeds, spread {args.spread} (log scale) in T_C and c_v, "
          f"noise sd {SIGMA} N*m, {n} replicates, one run held out each")
    print("law      " + "  ".join(f"cover@{v:g}" for v in AT) + "  whole curve  interval score@" +
          "/".join(f"{v:g}" for v in AT) + "  gate failed  s/fit")
    for name, row in rows.items():
        cover = np.mean(row["cover"], axis=0)
        score = np.mean(row["score"], axis=0)
        print(f"{name:8s} " + "  ".join(f"{c:8.3f}" for c in cover) + f"  {np.mean(row['all']):11.3f}  "
              + "/".join(f"{s:.3f}" for s in score) + f"  {row['failed']:11d}  {row['s'] / n:5.2f}")
    better = np.mean(np.asarray(rows["by run"]["elpd"]) > np.asarray(rows["pooled"]["elpd"]))
    diff = np.asarray(rows["by run"]["elpd"]) - np.asarray(rows["pooled"]["elpd"])
    print(f"leave-one-run-out: the hierarchical law scores higher in {better:.3f} of replicates "
          f"(median elpd difference {np.median(diff):.1f} nats over the held-out run's {SPEEDS.size} rows)")
    joint = np.asarray(rows["by run"]["joint"]) - np.asarray(rows["pooled"]["joint"])
    print(f"leave-one-run-out, the run's rows scored jointly (log mean_s prod_i p): the hierarchical law scores "
          f"higher in {np.mean(joint > 0):.3f} of replicates (median difference {np.median(joint):.1f} nats)")
    se = np.sqrt(0.9 * 0.1 / n)
    print(f"binomial sd of a 90 % coverage over {n} replicates: {se:.3f}")


if __name__ == "__main__":
    main()
