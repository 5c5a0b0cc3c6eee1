"""NUTS backend of the full fit: the all-true mask of the law's compiled engine.

:func:`sample_nuts` builds the program's :class:`~bayesfric.inference.engine.NutsEngine`
(blackjax NUTS with Stan's window adaptation on the program's one log density) and takes its
full fit, so a fit and every fold refit of a law are draws of one sampler and one compiled
program. With ``progress`` the chains report as they go (warm-up and draws per chain, divergent
transitions so far, time left: :mod:`bayesfric.inference.progress`), on stderr.
"""

from __future__ import annotations

import contextlib
import sys
import time

import xarray as xr

from bayesfric.inference.engine import NutsEngine
from bayesfric.inference.init import Init
from bayesfric.inference.progress import reporting
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
    metric: str = "auto",
    init: Init = "median",
    retry_target_accept: float = 0.99,
    progress: bool = False,
) -> xr.DataTree:
    """Sample the program's posterior with NUTS and return the fit's DataTree.

    Chains run in one compiled sampler (on CPUs one chain per call, the calls on a thread pool;
    on accelerators all chains vectorised: :class:`~bayesfric.inference.engine.NutsEngine`) and
    start at different prior-median points (numpyro's ``init_to_median``), so every chain starts
    in the bulk of the prior; ``init = "pathfinder"`` starts them at multi-path Pathfinder draws
    instead (:mod:`bayesfric.inference.init`). Draws with divergent transitions are sampled once
    more at ``retry_target_accept`` (0 switches that off; the cost is stated on the engine).
    ``metric = "dense"`` estimates a dense mass matrix in the warm-up instead of a diagonal one
    (for strongly correlated coefficients; see the engine).
    """
    engine = NutsEngine(program, draws=draws, tune=tune, chains=chains, seed=seed,
                        target_accept=target_accept, max_tree_depth=max_tree_depth, metric=metric, init=init,
                        retry_target_accept=retry_target_accept)
    start = time.perf_counter()
    if progress:
        print(f"sampling {program.law.name}: {chains} chains × ({tune} warm-up + {draws} draws), "
              "compiling first unless cached …", file=sys.stderr, flush=True)
    with reporting(f"{program.law.name} fit") if progress else contextlib.nullcontext():
        dt = engine.fit(ds)
    if progress:
        print(f"sampled in {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
    return dt
