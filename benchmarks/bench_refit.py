"""Wall time of one full NUTS fit against a K-fold refit of the same law on the same data.

Run: ``.venv/bin/python benchmarks/bench_refit.py [--k 10] [--n 100] [--variants shared warm cold batch10]``

Data: the ``stribeck`` law simulated at ``n`` speeds in both directions of motion (seed 0).
Full fit: the law's engine with the default NUTS settings, as :func:`bayesfric.inference.fit` runs it
(compilation and DataTree assembly included).
Refit: :class:`bayesfric.compare.refit.RefitEngine` + :func:`cross_validate` on random K-fold
masks, compilation, engine set-up and per-fold diagnostics included, once per variant:

- ``shared`` (what studies run): the engine that made the full fit, warm-started from it
  (``engine.warm_started(fit)``): the folds reuse the fit's compiled sampler;

and, each in its own engine (so each pays its own compilation):

- ``warm``: folds start from the full fit's draws and mass matrix, 250 warm-up steps (what
  studies and PSIS-LOO refits use when the full fit passed the gate);
- ``cold``: folds start at the prior median with a 500-step Stan warm-up;
- ``batch10``: cold, 10 folds vmapped together.

The second refit of the same engine (new seed, no compilation) is timed too. Writes
``reports/benchmarks/bench_refit.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from bayesfric.compare.folds import kfold_masks
from bayesfric.compare.refit import RefitEngine, cross_validate
from bayesfric.datasets.synthetic import simulate
from bayesfric.laws.base import get_law
from bayesfric.model import build_program
from bayesfric.runtime import configure

OUT = Path(__file__).resolve().parents[1] / "reports" / "benchmarks" / "bench_refit.json"


VARIANTS = {  # name -> (fold_batch, warm start from the full fit?)
    "shared": (1, True),  # the full fit's own engine, warm-started: no compilation of its own
    "warm": (1, True),
    "cold": (1, False),
    "batch10": (10, False),
}


def time_numpyro(program, folds) -> dict:
    """The alternative engine: one numpyro MCMC object reused with the mask as a model argument."""
    import jax
    from numpyro.infer import MCMC, NUTS, init_to_median

    kernel = NUTS(program.model, target_accept_prob=0.9, init_strategy=init_to_median(num_samples=15))
    mcmc = MCMC(kernel, num_warmup=500, num_samples=1000, num_chains=4, chain_method="vectorized",
                progress_bar=False, jit_model_args=True)
    start = time.perf_counter()
    per_fold = []
    for k in range(folds.n_folds):
        mcmc.run(jax.random.PRNGKey(k), **program.model_kwargs, mask=folds.train[k])
        mcmc.get_samples()
        per_fold.append(time.perf_counter() - start - sum(per_fold))
    return dict(seconds=time.perf_counter() - start, per_fold_seconds=per_fold,
                settings="tune 500, draws 1000, 4 chains vectorized, no diagnostics or scoring")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--k", type=int, default=10)
    parser.add_argument("--n", type=int, default=100)
    parser.add_argument("--variants", nargs="+", default=["shared", "warm", "cold"], choices=list(VARIANTS))
    parser.add_argument("--with-numpyro", action="store_true",
                        help="also time numpyro MCMC(jit_model_args=True), one run per fold")
    args = parser.parse_args()
    configure()  # x64 and the compilation cache, as the CLI does

    law = get_law("stribeck")
    speeds = np.geomspace(0.02, 4.0, args.n // 2)
    velocity = np.concatenate([-speeds[::-1], speeds])
    truth = {"T_C": 2.0, "dT_s": 1.0, "v_s": 0.1, "delta": 0.8}
    ds = simulate(law, {"velocity": velocity}, truth, sigma=0.05, seed=0)

    program = build_program(law, ds)
    start = time.perf_counter()
    fit_engine = RefitEngine.build(program, tune=1000, seed=0)  # what bayesfric.inference.fit runs
    full = fit_engine.fit(ds)
    t_full = time.perf_counter() - start
    settings = json.loads(full.attrs["sampler_settings"])
    print(f"full fit ({settings}): {t_full:.1f} s")

    folds = kfold_masks(ds, k=args.k, seed=0)
    runs = []
    for variant in args.variants:
        batch, warm = VARIANTS[variant]
        start = time.perf_counter()
        if variant == "shared":
            engine = fit_engine.warm_started(full)
        else:
            engine = RefitEngine.build(program, fold_batch=batch, warm_start=full if warm else None)
        t_init = time.perf_counter() - start
        first = cross_validate(engine, folds, seed=0)
        t_first = time.perf_counter() - start
        start = time.perf_counter()
        again = cross_validate(engine, folds, seed=1)
        t_again = time.perf_counter() - start
        runs.append(dict(variant=variant, fold_batch=batch, seconds_first=t_first, seconds_warm=t_again,
                         seconds_engine_init=t_init,
                         ratio_first=t_first / t_full, ratio_warm=t_again / t_full,
                         compilations=(fit_engine if variant == "shared" else engine).compilations,
                         failed_folds=first.failed_folds,
                         failed_folds_warm=again.failed_folds, elpd=first.elpd, se=first.se,
                         settings=engine.settings))
        print(f"{args.k}-fold refit, {variant}: first {t_first:.1f} s "
              f"(ratio {t_first / t_full:.2f}x; engine init {t_init:.1f} s), again with a new seed {t_again:.1f} s "
              f"(ratio {t_again / t_full:.2f}x); compilations "
              f"{(fit_engine if variant == 'shared' else engine).compilations}; "
              f"failed folds {first.failed_folds} / {again.failed_folds}; "
              f"elpd {first.elpd:.1f} ± {first.se:.1f}")
    numpyro_run = time_numpyro(program, folds) if args.with_numpyro else None
    if numpyro_run:
        print(f"numpyro MCMC(jit_model_args=True), {args.k} folds in sequence: "
              f"{numpyro_run['seconds']:.1f} s (ratio {numpyro_run['seconds'] / t_full:.2f}x)")
    best = min(runs, key=lambda r: r["seconds_first"])
    print(f"best ratio ({best['variant']}): {best['ratio_first']:.2f}x "
          "(target <= 2x)")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(dict(
        law=law.name, n_obs=int(ds.sizes["obs"]), k=args.k, full_fit_seconds=t_full,
        full_fit_settings=settings, refits=runs, numpyro_jit_model_args=numpyro_run, cpu_count=os.cpu_count(),
        load_average=os.getloadavg(), machine=platform.platform(),
    ), indent=2))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
