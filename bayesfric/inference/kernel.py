"""The compiled part of a NUTS engine, and where its chains start.

:class:`Kernel` holds what one program and one configuration compile: the program's one log
density, the chunked sampler's start / advance / finish programs
(:class:`~bayesfric.inference.chunked.ChunkedSampler`, with the program's *inputs* as constants of
the compiled code and the response, the masks, the starts, the schedule and the targets as
arguments), and the cold chain starts (compiled in the background). It is built once per engine by
:func:`bayesfric.inference.engine.build` and shared, never copied, by every engine made from that
one (warm or cold starts, another response): they differ only in their :class:`Start` or their
program's response, both arguments of the compiled code.

:class:`Start` is where a run's chains start and how long their warm-up is: an immutable value,
made by :func:`cold_start` (prior medians or Pathfinder, a unit mass matrix, Stan's warm-up over
``active`` of the compiled warm-up's steps) or :func:`warm_start` (draws of a full fit and its
unconstrained posterior variance, a 250-step warm-up). :class:`FitTables` holds the full fit's
compiled DataTree tables of one response.

>>> kernel = Kernel(program, SamplerConfig(draws=200, tune=200, chains=2))   # doctest: +SKIP
>>> start = cold_start(kernel)                   # the full fit's: the whole compiled warm-up  # doctest: +SKIP
>>> start.active_tune, start.warm                                                           # doctest: +SKIP
(200, False)
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.fingerprint import program_parts
from bayesfric.inference.adaptation import sampling_schedule
from bayesfric.inference.batching import chain_batch_of, vmap_or_squeeze
from bayesfric.inference.chunked import ChunkedSampler
from bayesfric.inference.config import SamplerConfig
from bayesfric.inference.datatree import draw_tables_args, tables_jit
from bayesfric.inference.init import pending_chain_starts
from bayesfric.inference.pointwise import log_mean_likelihood, storage
from bayesfric.inference.warmstart import warm_start_from
from bayesfric.model import Program

__all__ = ["Kernel", "Start", "FitTables", "cold_start", "warm_start", "MIN_WARMUP"]

#: The shortest warm-up a warm or cold start may ask for (Stan's windows need it).
MIN_WARMUP = 120


class Start(NamedTuple):
    """Where a run's chains start: ``positions`` (``(chains, dim)`` unconstrained; None: the
    kernel's cold starts), the initial ``inverse_mass`` matrix, the ``schedule`` of the compiled
    scan, whether it is a ``warm`` start, and the warm-up steps it uses (``active_tune``)."""

    positions: np.ndarray | None
    inverse_mass: np.ndarray
    schedule: np.ndarray
    warm: bool
    active_tune: int


class Kernel:
    """The compiled sampler of one program and one configuration (see the module notes).

    Parameters
    ----------
    program : Program
        Its inputs are constants of the compiled code; its response is only the shape of one.
    config : SamplerConfig
        ``draws``, ``tune`` (the compiled warm-up), ``chains``, ``chain_batch``, ``fold_batch``,
        ``max_tree_depth``, ``metric``, ``chunk_steps``, ``seed``, ``init``.

    Notes
    -----
    ``compilations`` counts how often the sampler was built -- traced, or read from the exported
    programs on disk (:mod:`bayesfric.exported`; ``loaded`` says which): it stays at 1 for every
    call of every engine sharing this kernel.
    """

    def __init__(self, program: Program, config: SamplerConfig):
        self.program, self.config = program, config
        self.chain_batch = chain_batch_of(config.chains, config.chain_batch)
        self.compilations = 0
        self.density = program.density(config.seed)
        # cold starts compile in the background while the sampler is traced (bayesfric.exported)
        self.cold_starts = pending_chain_starts(program, config.chains, config.seed, config.init)
        schedule = np.asarray(sampling_schedule(config.tune, config.draws))
        self.sampler = ChunkedSampler(self.density, self.data, vmap_or_squeeze, self.finish, self.parts(),
                                      self._example_args(schedule), config.max_tree_depth, config.tune,
                                      config.chunk_steps, self._traced, auto=config.metric == "auto")
        self.loaded = self.sampler.loaded
        self.compilations += int(self.loaded)  # a program read from disk counts as its one compilation

    def unit_mass(self) -> np.ndarray:
        """The inverse mass matrix chains start cold with: ones, or the identity (dense, auto)."""
        dim = self.density.dim
        return np.ones(dim) if self.config.metric == "diag" else np.eye(dim)

    def parts(self) -> dict:
        """What the traced sampler depends on besides the package source (its disk-cache key)."""
        c = self.config
        return dict(program=program_parts(self.program, response=False), what="NutsEngine",
                    draws=c.draws, max_tree_depth=c.max_tree_depth, metric=c.metric)

    def _example_args(self, schedule: np.ndarray) -> tuple:
        c, imm = self.config, self.unit_mass()
        keys = jax.ShapeDtypeStruct((c.fold_batch, self.chain_batch) + jax.random.PRNGKey(0).shape, jnp.uint32)
        masks = jax.ShapeDtypeStruct((c.fold_batch, self.program.n_obs), jnp.bool_)
        y = self.program.response
        starts = jax.ShapeDtypeStruct((self.chain_batch, self.density.dim), imm.dtype)
        scalar = jax.ShapeDtypeStruct((), imm.dtype)
        return (keys, masks, jax.ShapeDtypeStruct(y.shape, y.dtype), starts, imm,
                jax.ShapeDtypeStruct(schedule.shape, schedule.dtype), scalar, scalar)

    def _traced(self) -> None:
        self.compilations += 1  # runs only while tracing the sampler's step, i.e. once per compilation

    def data(self, response) -> dict:
        """The density's data: the program's inputs (constants of the compiled code) and ``response``."""
        p = self.program
        return dict(inputs=p.inputs, group_index=p.group_index, response=response)

    def finish(self, positions, masks, response):
        """Constrained draws and lpd of every observation from the kept unconstrained draws
        ``(fold, chain, draw, dim)`` of one call, each fold with its training mask (which levels
        of a group column its draws hold centred: ``Program.model``'s ``seen``)."""
        density = self.density  # the program's one log density
        data = self.data(response)

        def one_fold(position, mask):
            fold = dict(data, seen=mask)
            constrained = jax.vmap(jax.vmap(lambda v: density.constrain(v, fold)))(position)
            flat = {k: v.reshape((-1,) + v.shape[2:]) for k, v in constrained.items()}
            # draws × rows at once for small data, else in chunks of draws (bounded memory)
            lpd = log_mean_likelihood(lambda c: density.pointwise(c, fold), flat, self.program.n_obs)
            return constrained, lpd

        return vmap_or_squeeze(one_fold)(positions, masks)

    def positions(self, start: Start) -> jax.Array:
        """The chains' starting points ``(chains, dim)`` of ``start``: its own, or the cold ones."""
        return self.cold_starts() if start.positions is None else start.positions


class FitTables:
    """The full fit's compiled DataTree tables of one response, compiled on the first fit and
    shared by the engines of that response (another response gets its own: they close over it)."""

    def __init__(self):
        self.compiled = None

    def of(self, engine, seed: int):
        """The tables of ``engine`` (a :class:`~bayesfric.inference.engine.NutsEngine`) for ``seed``."""
        if self.compiled is None:  # compiles in the background while the chains run
            c = engine.config
            self.compiled = tables_jit(engine.program, storage(engine.program.n_obs, c.chains, c.draws))
            shapes = engine.kernel.sampler.out_shapes[0]
            sites = {k: jax.ShapeDtypeStruct(v.shape[3:], v.dtype) for k, v in shapes.items()}
            self.compiled.ahead(*draw_tables_args(sites, c.chains * c.draws, seed))
        return self.compiled


def cold_start(kernel: Kernel, active: int | None = None) -> Start:
    """Chains at the cold starts with a unit mass matrix and Stan's warm-up over ``active`` of
    the compiled warm-up's steps (None: all of them, the full fit's)."""
    tune, draws = kernel.config.tune, kernel.config.draws
    if active is None:
        return Start(None, kernel.unit_mass(), sampling_schedule(tune, draws), False, tune)
    if not MIN_WARMUP <= active <= tune:
        raise UserError(f"a cold warm-up needs {MIN_WARMUP} to {tune} steps (got {active})", "tune")
    return Start(None, kernel.unit_mass(), sampling_schedule(tune, draws, active=active, warm=False), False, active)


def warm_start(kernel: Kernel, program: Program, fit: xr.DataTree, warm_tune: int) -> Start:
    """Chains at draws of the full fit ``fit`` with its unconstrained posterior variance, and a
    ``warm_tune``-step warm-up (in [:data:`MIN_WARMUP`, the compiled warm-up])."""
    c = kernel.config
    if warm_tune > c.tune:
        raise UserError(f"{warm_tune} exceeds the engine's warm-up of {c.tune} steps", "warm_tune")
    if warm_tune < MIN_WARMUP:
        raise UserError(f"must be at least {MIN_WARMUP} (got {warm_tune})", "warm_tune")
    positions, imm = warm_start_from(program, fit, c.chains, c.seed, c.metric)
    return Start(positions, imm, sampling_schedule(c.tune, c.draws, active=warm_tune), True, warm_tune)
