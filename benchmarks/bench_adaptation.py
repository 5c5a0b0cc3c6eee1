"""What the warm-up ends with, and what a draw costs: steps per draw, tree depths, ESS per gradient.

Usage::

    .venv/bin/python benchmarks/bench_adaptation.py [--rows 10000] [--chains 4] [--draws 1000]
        [--tune 1000] [--configs 0.9:diag 0.8:diag 0.9:dense 0.8:dense 0.9:fisher] [--seed 0]

Data: the SIMULATED steady-state Stribeck rows of ``benchmarks/bench_scale_rows.py`` (same
function, same seed per size), law ``stribeck`` with default priors and noise.

Each config ``TARGET:METRIC`` (METRIC ``diag``, ``dense`` or ``fisher``, the last the diagonal
``sqrt(Var x / Var ∇ log p)`` of ``adaptation.DIAGONAL = "fisher"``) runs the engine's chain,
:func:`bayesfric.inference.adaptation.chain_start` + ``chain_steps`` over the engine's schedule,
with the engine's keys and prior-median starts (so the draws are the engine's full fit's), one
chain per call on two threads. Reported per config: leapfrog steps per draw (mean, and the
histogram of 2^k − 1 steps), divergences, bulk ESS per parameter and per 1000 leapfrog steps of
the sampling phase, warm-up steps, sampling seconds; and the warm-up's end state against the
posterior: per chain the averaged step size and the inverse-metric diagonal divided by the
variance of the chain's own unconstrained draws, the diagonal nutpie would estimate from the same
draws (``sqrt(Var x / Var ∇ log p)``, gradients at the draws) divided by that variance, the
posterior's correlations, and the condition number of the posterior covariance preconditioned by
each metric (``D^-1/2 Σ D^-1/2``): what sets the steps per U-turn. Writes
``reports/benchmarks/bench_adaptation.json``.

Measured 2026-11-26 (2-core machine, load 4-6 from other work: seconds are noise, steps and ESS
are not), 4 chains × (1000 + 1000), seed 0. At 10⁵ rows the 0.9:diag chain reproduces the
engine's fit in ``bench_scale_rows.py`` (23.0 steps per draw). The diagonal metric is right
(its inverse over the chain's own posterior variance 0.8-1.2 per coordinate), but the posterior
is correlated (r(dT_s, δ) = -0.94, r(dT_s, v_s) = -0.84): every diagonal metric leaves a
condition number of ~100 (by the posterior variances 97-111, by nutpie's gradient-based
diagonal 92-103), a dense one 1.2-1.6.

| rows | config | steps/draw | worst bulk ESS per 1000 leapfrog steps | divergences |
|---|---|---|---|---|
| 10⁴ | 0.9:diag (default) | 25.8 | 12.4 (dT_s) | 0 |
| 10⁴ | 0.8:diag | 22.4 | 12.5 (dT_s) | 0 |
| 10⁴ | 0.9:fisher | 17.9 | 11.5 (dT_s) | 0 |
| 10⁴ | 0.9:dense | 6.2 | 216.6 (δ) | 0 |
| 10⁴ | 0.8:dense | 5.3 | 234.2 (v_s) | 0 |
| 10⁵ | 0.9:diag (default) | 23.0 | 15.0 (dT_s) | 0 |
| 10⁵ | 0.9:dense | 6.1 | 216.5 (dT_s) | 0 |
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
OUT = REPO / "reports" / "benchmarks" / "bench_adaptation.json"


def preconditioned(cov: np.ndarray, imm: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``cov`` preconditioned by the inverse metric ``imm`` (a diagonal vector or a
    dense matrix): those of ``imm^-1/2 cov imm^-1/2``, ascending."""
    from scipy.linalg import eigh

    return eigh(cov, np.diag(imm) if imm.ndim == 1 else imm, eigvals_only=True)


def condition(cov: np.ndarray, imm: np.ndarray) -> float:
    """Condition number of ``cov`` preconditioned by the inverse metric ``imm``."""
    ev = preconditioned(cov, imm)
    return float(ev[-1] / ev[0])


def run_config(target: float, metric: str, rows: int, args: argparse.Namespace, cache: dict) -> dict:
    import arviz as az
    import jax
    import jax.numpy as jnp

    import bayesfric.inference.adaptation as adaptation
    from bayesfric.inference.adaptation import chain_start, chain_steps, sampling_schedule, step_keys
    from bayesfric.inference.init import pending_chain_starts

    program, density = cache["program"], cache["density"]
    adaptation.DIAGONAL = "fisher" if metric == "fisher" else "welford"
    dim = density.dim
    data = dict(inputs=program.inputs, group_index=program.group_index, response=program.response)
    mask = jnp.ones(program.n_obs, dtype=bool)

    def logdensity(x):
        return density.log_joint(x, mask, data)

    schedule = jnp.asarray(sampling_schedule(args.tune, args.draws))
    imm0 = jnp.eye(dim) if metric == "dense" else jnp.ones(dim)

    @jax.jit
    def chain(key, z0, target_accept):
        carry = chain_start(z0, logdensity, imm0)
        carry, out = chain_steps(carry, step_keys(key, schedule.shape[0]), schedule, logdensity,
                                 target_accept, 10)
        eps = jnp.exp(carry[1].dual_averaging.log_step_size_avg)  # the sampling phase's step size
        return eps, carry[1].inverse_mass_matrix, out

    starts = np.asarray(pending_chain_starts(program, args.chains, args.seed, "median")())
    keys = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(args.seed), 0), args.chains)
    t0 = time.perf_counter()
    chain.lower(keys[0], starts[0], jnp.asarray(target)).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    with ThreadPoolExecutor(2) as pool:
        res = list(pool.map(lambda c: jax.tree.map(np.asarray, chain(keys[c], starts[c], jnp.asarray(target))),
                            range(args.chains)))
    seconds = time.perf_counter() - t0
    eps = np.array([r[0] for r in res])
    imm = np.stack([r[1] for r in res])
    tune = args.tune
    pos = np.stack([r[2].position[tune:] for r in res])  # (chain, draw, dim)
    nsteps = np.stack([r[2].n_steps[tune:] for r in res])
    warm_steps = int(np.stack([r[2].n_steps[:tune] for r in res]).sum())
    div = int(np.stack([r[2].diverging[tune:] for r in res]).sum())
    acc = float(np.stack([r[2].acceptance_rate[tune:] for r in res]).mean())
    names = density.sites
    # flat vector sites: stribeck's are scalars; label by site
    labels = names if len(names) == dim else [f"x{i}" for i in range(dim)]
    ess = {lab: float(az.ess(pos[:, :, i], method="bulk")) for i, lab in enumerate(labels)}
    total = int(nsteps.sum())
    values, counts = np.unique(nsteps, return_counts=True)
    # the posterior against the metric
    grad = jax.jit(jax.vmap(jax.grad(logdensity)))
    var_chain = pos.var(axis=1)  # (chain, dim)
    flat = pos.reshape(-1, dim)
    cov = np.cov(flat.T)
    sd = np.sqrt(np.diag(cov))
    corr = cov / np.outer(sd, sd)
    sub = flat[:: max(1, flat.shape[0] // 2000)]
    g = np.asarray(grad(jnp.asarray(sub)))
    fisher = np.sqrt(sub.var(axis=0) / g.var(axis=0))
    imm_diag = np.stack([np.diag(m) for m in imm]) if imm.ndim == 3 else imm
    return {
        "target_accept": target, "metric": metric, "rows": rows, "compile_seconds": compile_s,
        "sampling_seconds": seconds, "load1": os.getloadavg()[0],
        "steps_per_draw": float(nsteps.mean()),
        "depth_hist": {int(v): int(c) for v, c in zip(values, counts, strict=True)},
        "warmup_steps_per_chain": warm_steps / args.chains, "divergent": div, "accept_mean": acc,
        "ess_bulk": ess, "ess_per_1000_grad": {k: 1000 * v / total for k, v in ess.items()},
        "step_size": eps.tolist(),
        "imm_over_var": (imm_diag / var_chain).tolist(),
        "fisher_over_var": (fisher / np.diag(cov)).tolist(),
        "corr": corr.tolist(), "labels": labels,
        "cond_by_final_metric": [condition(cov, m) for m in imm],
        "cond_by_var": condition(cov, np.diag(cov)), "cond_by_fisher": condition(cov, fisher),
        "eps_over_sqrt_min_eig": [float(e / np.sqrt(preconditioned(cov, m)[0]))
                                  for e, m in zip(eps, imm, strict=True)],
        "depth_counts": {int(k): int(c) for k, c in zip(*np.unique(np.ceil(np.log2(nsteps + 1)).astype(int),
                                                                       return_counts=True), strict=True)},
        "means": flat.mean(axis=0).tolist(), "posterior_var": np.diag(cov).tolist(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=10_000)
    parser.add_argument("--chains", type=int, default=4)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--tune", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--configs", nargs="+", default=["0.9:diag", "0.8:diag", "0.9:dense", "0.8:dense"])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    from bench_scale_rows import dataset

    from bayesfric.laws import get_law
    from bayesfric.model import build_program

    program = build_program(get_law("stribeck"), dataset(args.rows))
    cache = {"program": program, "density": program.density(args.seed)}
    results = []
    for cfg in args.configs:
        target, metric = cfg.split(":")
        r = run_config(float(target), metric, args.rows, args, cache)
        results.append(r)
        hist = " ".join(f"d{k}:{v}" for k, v in r["depth_counts"].items())
        print(f"{cfg:<10} steps/draw {r['steps_per_draw']:5.1f} [{hist}] div {r['divergent']} "
              f"acc {r['accept_mean']:.3f} eps {np.round(r['step_size'], 4).tolist()} "
              f"warm-up steps/chain {r['warmup_steps_per_chain']:.0f} sample {r['sampling_seconds']:.1f} s "
              f"load {r['load1']:.1f}", flush=True)
        print("   ESS bulk  " + "  ".join(f"{k}={v:.0f}" for k, v in r["ess_bulk"].items()))
        print("   ESS/1000g " + "  ".join(f"{k}={v:.1f}" for k, v in r["ess_per_1000_grad"].items()))
        print("   imm/var per chain " + str(np.round(r["imm_over_var"], 2).tolist()))
        print(f"   fisher/var {np.round(r['fisher_over_var'], 2).tolist()}  cond: final metric "
              f"{np.round(r['cond_by_final_metric'], 1).tolist()} by var {r['cond_by_var']:.1f} "
              f"by fisher {r['cond_by_fisher']:.1f}  eps/sqrt(min eig) "
              f"{np.round(r['eps_over_sqrt_min_eig'], 2).tolist()}", flush=True)
    print("labels", results[0]["labels"], "\ncorr\n", np.round(results[0]["corr"], 3))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"settings": {k: str(v) for k, v in vars(args).items()}, "results": results},
                                   indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
