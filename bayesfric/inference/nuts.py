"""NUTS backend for the full fit (numpyro).

The compiled engine that refits the folds (:class:`bayesfric.inference.engine.NutsEngine`) can
make the full fit too (``engine.fit(ds)``: its all-true mask, one compilation for fit and
folds), and ``benchmarks/bench_refit.py`` measures that path. Full fits stay on numpyro's NUTS
for now: on the skf_2014 bearing law the blackjax chain took hundreds of leapfrog steps per draw
and the law's posterior-recovery test ran past 30 minutes, where numpyro's fit passes in a few
(found at integration, 2026-11-23; not yet explained).
"""

from __future__ import annotations

import jax
import numpy as np
import xarray as xr
from numpyro.infer import MCMC, NUTS, init_to_median

from bayesfric.inference.datatree import assemble
from bayesfric.model import Program

__all__ = ["sample_nuts"]


def sample_nuts(
    program: Program,
    ds: xr.Dataset,
    *,
    draws: int = 1000,
    tune: int = 1000,
    chains: int = 4,
    seed: int = 0,
    target_accept: float = 0.9,
    max_tree_depth: int = 10,
    progress: bool = False,
) -> xr.DataTree:
    """Sample the program's posterior with NUTS and return the fit's DataTree.

    Chains run vectorised in one process (``chain_method="vectorized"``); initialisation is at
    the prior median so that every chain starts in the bulk.
    """
    kernel = NUTS(program.model, target_accept_prob=target_accept, max_tree_depth=max_tree_depth,
                  init_strategy=init_to_median(num_samples=15))
    mcmc = MCMC(kernel, num_warmup=tune, num_samples=draws, num_chains=chains,
                chain_method="vectorized", progress_bar=progress)
    mcmc.run(jax.random.PRNGKey(seed), **program.model_kwargs, extra_fields=("diverging", "energy",
             "num_steps", "accept_prob"))
    samples = {k: np.asarray(v) for k, v in mcmc.get_samples(group_by_chain=True).items()}
    extra = mcmc.get_extra_fields(group_by_chain=True)
    stats = {
        "diverging": np.asarray(extra["diverging"]),
        "energy": np.asarray(extra["energy"]),
        "n_steps": np.asarray(extra["num_steps"]),
        "acceptance_rate": np.asarray(extra["accept_prob"]),
    }
    settings = dict(draws=draws, tune=tune, chains=chains, target_accept=target_accept,
                    max_tree_depth=max_tree_depth)
    return assemble(program, ds, samples, stats, sampler="nuts", settings=settings, seed=seed)
