"""Answers for the next run from the two, three or five runs users have: is the group-term fit
used, and does its 90 % band for a *new* run cover that run's true mean curve?

Usage::

    .venv/bin/python benchmarks/bench_new_run.py [--replicates 100] [--train-runs 2 3 5]
        [--truths coulomb_viscous armstrong_helouvry] [--spread 0.1-0.3] [--every 20]

SIMULATED data. Each replicate draws ``train + 1`` runs of the truth at the same 20 speeds
(0.1-2 rad/s), its Coulomb level and viscous coefficient varying between runs by a factor
``exp(s · z)``, ``s`` drawn per replicate uniformly from ``--spread`` (10-30 % by default; noise
sd 0.05 N·m, about 2.5 % of the torque: :func:`bayesfric.datasets.synthetic.simulate_runs`).
The last run is held back; the others are fitted (NUTS, the default 4 chains x 1000 draws,
the gate's verdict of the full fit's mask; ``used`` counts fits that passed it, or that failed
on mixing alone with a converged pointwise log-likelihood, as a study uses them; a multimodal fit
a study would combine is counted as not used):

* ``by run``: the truth's law with ``vary_by("run", "T_C", "c_v")`` (the default spread prior,
  :func:`bayesfric.hierarchy.hyperprior`), answered for a NEW run (:func:`bayesfric.hierarchy.mean_draws`);
* ``pooled``: the same law without group terms (every run the same curve);
* ``pooled+spread``: the pooled law widened by the between-run spread its residual-structure
  check measured (:func:`bayesfric.sizing.newrun.widen_draws`), the answer a study gives for a
  new run when no group-aware law can be used.

Per variant: how often the fit is *used* (passed the gate, or multimodal / unidentified with
converged predictions), how often the central 90 % band of the mean curve at 0.1, 1, 2 rad/s
(inside) and 3, 3.9 rad/s (up to one tested range beyond) covers the held-back run's true mean
curve, and the mean interval score (Gneiting & Raftery 2007, alpha = 0.1: width plus 20x the
miss). A fit that is not used still has its band counted (``used`` says how often a study would
drop it). One compiled sampler per law serves every replicate (``NutsEngine.with_response``);
priors are data-scaled on the first replicate's response.
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

from bayesfric.compare.structure_stats import Column, structure_tests
from bayesfric.datasets.synthetic import simulate_runs
from bayesfric.hierarchy import level_values
from bayesfric.inference.diagnostics import GATE, mixing_only, with_predictions
from bayesfric.inference.engine import NutsEngine
from bayesfric.laws import get_law
from bayesfric.model import build_program
from bayesfric.priors import Prior
from bayesfric.sizing.newrun import widen_draws

SPEEDS = np.linspace(0.1, 2.0, 20)
AT = np.array([0.1, 1.0, 2.0, 3.0, 3.9])
TRUTHS = {"coulomb_viscous": {"T_C": 2.0, "c_v": 1.0},
          "armstrong_helouvry": {"T_C": 2.0, "dT_s": 1.0, "v_s": 0.2, "delta": 1.0, "c_v": 1.0}}
SIGMA = 0.05
ALPHA = 0.1
VARIANTS = ("by run", "pooled", "pooled+spread")


def interval_score(lo, hi, x, alpha=ALPHA):
    """Gneiting & Raftery (2007) interval score of the central (1 - alpha) interval [lo, hi] at x."""
    return (hi - lo) + (2 / alpha) * np.maximum(lo - x, 0) + (2 / alpha) * np.maximum(x - hi, 0)


def replicate_data(law, truth, train: int, lo: float, hi: float, r: int):
    """(training runs, held-back run's true curve at AT) of replicate ``r``."""
    s = float(np.random.default_rng([r, 99]).uniform(lo, hi))
    ds, values = simulate_runs(law, {"velocity": SPEEDS}, truth, {"T_C": s, "c_v": s}, runs=train + 1,
                               sigma=SIGMA, seed=r)
    held = np.asarray(ds["run"].values) == f"r{train}"
    import jax.numpy as jnp

    curve = np.asarray(law.mean({"velocity": jnp.asarray(AT)}, {k: jnp.asarray(v[-1]) for k, v in values.items()}, {}))
    return ds.isel(obs=np.flatnonzero(~held)), curve


def used_as_a_fit_is(fits, program, pointwise) -> bool:
    """Whether a study would use this fit: it passed the gate, or it failed on mixing alone and its
    pointwise log-likelihood converged (parameters not identified, predictions converged: the
    rule :func:`bayesfric.inference.diagnostics.resolve_fold` shares with a full fit)."""
    import xarray as xr

    verdict = fits.verdicts[0]
    if verdict.passed:
        return True
    if not mixing_only(verdict, fits.samples[next(iter(fits.samples))].shape[1]):
        return False
    draws = {k: np.asarray(v[0]) for k, v in fits.samples.items()}
    chains, per = next(iter(draws.values())).shape[:2]
    flat = {k: v.reshape((chains * per,) + v.shape[2:]) for k, v in draws.items()}
    ll = np.asarray(pointwise(flat)).reshape(chains, per, -1)
    loglik = xr.Dataset({"y": (("chain", "draw", "obs"), ll)})
    return bool(with_predictions(verdict, loglik, GATE).predictions_converged)


def posterior_tree(fits, program):
    """The one fold of ``fits`` as a tree with a posterior (group levels labelled), as a fit has.

    The engine's ``run`` (the full fit's all-true mask) rather than ``fit``: a fit's tables are a
    program per response, which over hundreds of replicates piles up compiled code."""
    import xarray as xr

    dims = program.site_dims()
    post = xr.Dataset({k: (("chain", "draw") + tuple(dims.get(k, [f"{k}_dim_{i}" for i in range(v.ndim - 3)])),
                           np.asarray(v[0])) for k, v in fits.samples.items()},
                      coords={c: list(g.labels) for c, g in program.groupings.items()})
    return xr.DataTree.from_dict({"posterior": post})


def curves(law, program, fit, at: np.ndarray, seed: int) -> np.ndarray:
    """Mean-curve draws ``(S, len(at))`` for a NEW run (:func:`bayesfric.hierarchy.level_values`),
    the law evaluated eagerly (one compiled function per call of ``mean_draws`` would pile up
    compiled code over hundreds of replicates)."""
    import jax.numpy as jnp

    post = fit["posterior"]
    flat = {k: np.asarray(v.values).reshape((-1,) + v.shape[2:]) for k, v in post.data_vars.items()}
    labels = {str(k): tuple(str(x) for x in c.values) for k, c in post.coords.items() if k not in ("chain", "draw")}
    values = level_values(program.law, program.resolved, flat, None, labels, np.random.default_rng(seed))
    return np.asarray(law.mean({"velocity": jnp.asarray(at)[None, :]},
                               {k: jnp.asarray(v)[:, None] for k, v in values.items()}, {}), dtype=float)


def pooled_spread(law, fit, program, ds):
    """The pooled fit's residual-structure check on the run column (the study's checks unit)."""
    mu = curves(law, program, fit, np.asarray(ds["velocity"].values), 0).mean(axis=0)
    resid = np.asarray(ds["torque"].values) - mu
    sd = np.full(resid.size, float(fit["posterior"]["sigma"].mean()))
    (check,) = structure_tests(resid, sd, {"velocity": np.asarray(ds["velocity"].values)},
                               [Column("run", "group", np.asarray(ds["run"].values))])
    return check


def one_case(truth_name: str, train: int, args) -> dict:
    law, truth = get_law(truth_name), TRUTHS[truth_name]
    lo, hi = (float(x) for x in args.spread.split("-"))
    first, _ = replicate_data(law, truth, train, lo, hi, 0)
    spread = {} if args.spread_prior is None else {
        f"{p}_sd": Prior("LogNormal", loc=float(np.log(args.spread_prior)), scale=0.7) for p in ("T_C", "c_v")}
    programs = {"by run": build_program(law.vary_by("run", "T_C", "c_v"), first, priors=spread),
                "pooled": build_program(law, first)}
    engines = {k: NutsEngine.build(p, seed=0) for k, p in programs.items()}
    pointwise = {k: jax.jit(jax.vmap(p.density().pointwise)) for k, p in programs.items()}
    rows = {k: {"cover": [], "score": [], "used": 0, "s": 0.0} for k in VARIANTS}
    for r in range(args.replicates):
        ds, curve = replicate_data(law, truth, train, lo, hi, r)
        bands = {}
        for name, engine in engines.items():
            start = time.perf_counter()
            fits = engine.with_response(np.asarray(ds["torque"].values)).run(np.ones((1, ds.sizes["obs"]), bool),
                                                                           seed=r)
            rows[name]["s"] += time.perf_counter() - start
            used = used_as_a_fit_is(fits, programs[name], pointwise[name])
            fit = posterior_tree(fits, programs[name])
            mu = curves(law, programs[name], fit, AT, r)
            bands[name] = mu
            rows[name]["used"] += int(used)
            if name == "pooled":
                check = pooled_spread(law, fit, programs[name], ds)
                rel = check.between_sd / float(np.mean(np.abs(ds["torque"].values)))
                bands["pooled+spread"] = widen_draws(mu, rel, check.levels, seed=r)
                rows["pooled+spread"]["used"] += int(used)
        for name, mu in bands.items():
            lo_b, hi_b = np.quantile(mu, ALPHA / 2, axis=0), np.quantile(mu, 1 - ALPHA / 2, axis=0)
            rows[name]["cover"].append((lo_b <= curve) & (curve <= hi_b))
            rows[name]["score"].append(interval_score(lo_b, hi_b, curve))
        if args.every and (r + 1) % args.every == 0 and r + 1 < args.replicates:
            report(truth_name, train, rows, args, n=r + 1)  # the figures so far (a long run can be cut)
    return rows


def report(truth: str, train: int, rows: dict, args, n: int | None = None) -> None:
    n = n or args.replicates
    prior = "default" if args.spread_prior is None else f"LogNormal(log {args.spread_prior:g}, 0.7)"
    print(f"\n{truth}, {train} training runs (+1 held back), spread {args.spread} (log scale, per replicate), "
          f"noise sd {SIGMA} N*m, {n} replicates, spread prior {prior}")
    print(f"{'variant':14s} {'used':>5s}  " + "  ".join(f"cover@{v:g}" for v in AT) + "   interval score@"
          + "/".join(f"{v:g}" for v in AT) + "   s/fit")
    for name in VARIANTS:
        row = rows[name]
        cover, score = np.mean(row["cover"], axis=0), np.mean(row["score"], axis=0)
        s = row["s"] / n if row["s"] else float("nan")
        print(f"{name:14s} {row['used'] / n:5.2f}  " + "  ".join(f"{c:8.3f}" for c in cover) + "   "
              + "/".join(f"{x:.2f}" for x in score) + f"   {s:5.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=100)
    ap.add_argument("--train-runs", type=int, nargs="+", default=[2, 3, 5])
    ap.add_argument("--truths", nargs="+", default=list(TRUTHS), choices=list(TRUTHS))
    ap.add_argument("--spread", default="0.1-0.3", help="range of the run-to-run log-scale spread, LO-HI")
    ap.add_argument("--spread-prior", type=float, default=None,
                    help="median of a LogNormal(., 0.7) spread prior instead of the default (a sensitivity check)")
    ap.add_argument("--every", type=int, default=0, help="also print the figures so far every N replicates")
    args = ap.parse_args()
    print("SIMULATED data (bayesfric.datasets.synthetic.simulate_runs)")
    for truth in args.truths:
        for train in args.train_runs:
            report(truth, train, one_case(truth, train, args), args)
    print(f"\nbinomial sd of a 90 % coverage over {args.replicates} replicates: "
          f"{np.sqrt(0.09 / args.replicates):.3f}")


if __name__ == "__main__":
    main()
