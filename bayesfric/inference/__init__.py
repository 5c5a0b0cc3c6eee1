"""Inference: NUTS and emcee backends with one signature, both returning an arviz DataTree.

>>> dt = fit(get_law("stribeck"), ds, sampler="nuts")          # doctest: +SKIP
>>> save_fit(dt, "fit.nc"); xr.open_datatree("fit.nc")          # doctest: +SKIP
"""

from __future__ import annotations

import gc
import os
import secrets
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import jax
import xarray as xr

from bayesfric.exported import forget_compiled
from bayesfric.fsutil import check_output_file
from bayesfric.inference.config import SamplerConfig
from bayesfric.inference.diagnostics import GATE, Gate, Verdict, check, verdict_of
from bayesfric.inference.ensemble import sample_emcee
from bayesfric.inference.nuts import sample_nuts
from bayesfric.laws.base import Law
from bayesfric.model import Noise, build_program
from bayesfric.priors import Prior

__all__ = [
    "fit", "save_fit", "release_compiled_code", "memory_mappings", "MAPPINGS_BUDGET", "SAMPLERS",
    "GATE", "Gate", "Verdict", "check", "verdict_of", "SamplerConfig",
]


def _emcee(program, ds: xr.Dataset, config: SamplerConfig | None = None, **settings: Any) -> xr.DataTree:
    """:func:`~bayesfric.inference.ensemble.sample_emcee` under a configuration."""
    config = (config or SamplerConfig(name="emcee")).replace(**settings)
    return sample_emcee(program, ds, seed=config.seed, progress=config.progress, **config.settings())


#: The backends by name, each ``sample(program, ds, config=None, **settings)`` -> the fit's DataTree.
SAMPLERS = {"nuts": sample_nuts, "emcee": _emcee}


def release_compiled_code(*, when_mapped_above: int = 0) -> None:
    """Free the compiled JAX executables held by this process.

    Every fit compiles fresh closures of its model, and on the CPU backend each compiled
    executable stays mapped in memory. When each fit compiled a few hundred small programs, a
    fit left ~740 mappings behind and a long loop of fits (a study, a model-recovery grid, the
    test suite) passed the kernel's ``vm.max_map_count`` (65530 by default) after roughly 80
    fits, and XLA then aborted mid-compilation; with the few exported programs of
    :mod:`bayesfric.exported` a small fit leaves ~75. Long loops still call this between items.

    Parameters
    ----------
    when_mapped_above : int
        The programs kept by :mod:`bayesfric.exported` (a law's samplers and tables) are always
        dropped. JAX's own caches (the small programs of eager operations, shared by every law)
        are cleared, with a garbage collection, only when the process holds more than this many
        memory mappings (0: always). Clearing them costs the next law ~60 of those programs
        read back from the compilation cache or recompiled, about 4 s for a six-law study;
        a study therefore passes a budget (:data:`MAPPINGS_BUDGET`).
    """
    forget_compiled()
    if when_mapped_above and 0 <= memory_mappings() <= when_mapped_above:
        return
    jax.clear_caches()
    gc.collect()


#: Memory mappings a study process may hold before :func:`release_compiled_code` clears JAX's
#: caches between laws: a quarter of the kernel's default ``vm.max_map_count`` (65530).
MAPPINGS_BUDGET = 16_000


def memory_mappings() -> int:
    """Number of memory mappings of this process (``/proc/self/maps``); -1 where unknown."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return -1


def fit(
    law: Law,
    ds: xr.Dataset,
    *,
    sampler: Literal["nuts", "emcee"] = "nuts",
    priors: Mapping[str, Prior | Mapping[str, Any]] | None = None,
    noise: Noise | None = None,
    constants: Mapping[str, float] | None = None,
    seed: int = 0,
    progress: bool = False,
    config: SamplerConfig | None = None,
    **settings: Any,
) -> xr.DataTree:
    """Fit ``law`` to ``ds`` and return the DataTree (see :func:`bayesfric.inference.datatree.assemble`).

    Parameters
    ----------
    law : Law
        A registered law.
    ds : xarray.Dataset
        Loaded data.
    sampler : {"nuts", "emcee"}
        Backend; both share this signature and return the same groups.
    priors, noise, constants
        Passed to :func:`bayesfric.model.build_program`.
    seed : int
        Seed of every random draw of the fit.
    progress : bool
        Show a progress bar while sampling.
    config : SamplerConfig, optional
        Every setting at once (``sampler``, ``seed``, ``progress`` and ``settings`` are then
        ignored): what ``bayesfric.fit`` and the ``fit`` command pass.
    **settings
        Backend settings (NUTS: draws, tune, chains, target_accept ...; emcee: draws, tune,
        walkers, thin), checked by :meth:`SamplerConfig.from_table`.

    Examples
    --------
    >>> dt = fit(get_law("stribeck"), ds, draws=300, tune=300, chains=2)        # doctest: +SKIP
    """
    if config is None:
        config = SamplerConfig.from_table({"name": sampler, "seed": seed, "progress": progress} | settings)
    program = build_program(law, ds, priors=priors, noise=noise, constants=constants)
    return SAMPLERS[config.name](program, ds, config)


def save_fit(dt: xr.DataTree, path: str | Path) -> Path:
    """Write a fit as NetCDF atomically (temporary file in the same folder, then rename).

    The path is checked first (:func:`bayesfric.fsutil.check_output_file`: not a folder, in a
    writable place); missing parent folders are created. The file gets the permissions of an
    ordinary new file (``0o666`` less the umask).

    Raises
    ------
    bayesfric.fsutil.PathError
        ``path`` is a folder, not a regular file, or cannot be written.
    """
    path = check_output_file(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # mode: 0o666 less umask
        except FileExistsError:
            continue
        break
    try:
        dt.to_netcdf(tmp, engine="h5netcdf")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
