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
from typing import Any

import xarray as xr

from bayesfric.inference.config import SamplerConfig
from bayesfric.inference.engine import build
from bayesfric.inference.progress import reporting
from bayesfric.model import Program

__all__ = ["sample_nuts"]


def sample_nuts(program: Program, ds: xr.Dataset, config: SamplerConfig | None = None, **settings: Any) -> xr.DataTree:
    """Sample the program's posterior with NUTS and return the fit's DataTree.

    Chains run in one compiled sampler (on CPUs one chain per call, the calls on a thread pool;
    on accelerators all chains vectorised: :class:`~bayesfric.inference.engine.NutsEngine`) and
    start at different prior-median points (numpyro's ``init_to_median``), so every chain starts
    in the bulk of the prior; ``init = "pathfinder"`` starts them at multi-path Pathfinder draws
    instead (:mod:`bayesfric.inference.init`). Draws with divergent transitions are sampled once
    more at ``retry_target_accept`` (0 switches that off; the cost is stated on the engine).
    ``metric = "dense"`` estimates a dense mass matrix in the warm-up instead of a diagonal one
    (for strongly correlated coefficients; see the engine).

    Parameters
    ----------
    program : Program
        The law bound to its data.
    ds : xarray.Dataset
        The data the program was built on (coordinates and provenance of the fit).
    config : SamplerConfig, optional
        The settings (default: :class:`~bayesfric.inference.config.SamplerConfig`'s, 1000 draws
        after 1000 warm-up steps in 4 chains); ``settings`` replace some of them.

    Examples
    --------
    >>> dt = sample_nuts(program, ds, SamplerConfig(draws=300, tune=300, chains=2))   # doctest: +SKIP
    """
    config = (config or SamplerConfig()).replace(**settings)
    engine = build(program, config)
    start = time.perf_counter()
    if config.progress:
        print(f"sampling {program.law.name}: {config.chains} chains × ({config.tune} warm-up + {config.draws} "
              "draws), compiling first unless cached …", file=sys.stderr, flush=True)
    with reporting(f"{program.law.name} fit") if config.progress else contextlib.nullcontext():
        dt = engine.fit(ds)
    if config.progress:
        print(f"sampled in {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
    return dt
