"""NUTS backend: the full fit is the all-true mask of the law's compiled engine."""

from __future__ import annotations

import sys
import time

import xarray as xr

from bayesfric.inference.engine import NutsEngine
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

    Runs :meth:`bayesfric.inference.engine.NutsEngine.fit`: blackjax NUTS with Stan's window
    adaptation, chains vectorised, each started at a prior median (numpyro's
    ``init_to_median``) so that every chain starts in the bulk. The sampling is one compiled
    call, so ``progress`` reports its start and end (with the wall time) on stderr rather than
    a per-draw bar. Fold refits of the same law use the same engine
    (:class:`bayesfric.compare.RefitEngine`).
    """
    engine = NutsEngine(program, draws=draws, tune=tune, chains=chains, seed=seed,
                        target_accept=target_accept, max_tree_depth=max_tree_depth)
    start = time.perf_counter()
    if progress:
        print(f"sampling {program.law.name}: {chains} chains × ({tune} warm-up + {draws} draws) ...",
              file=sys.stderr, flush=True)
    dt = engine.fit(ds, seed=seed)
    if progress:
        print(f"sampled {program.law.name} in {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
    return dt
