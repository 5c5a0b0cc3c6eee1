"""The compiled, masked NUTS sampler of one program: the full fit, every fold refit, one compilation.

A program's likelihood takes a 0/1 ``mask`` *as data* (:class:`bayesfric.model.Program`), so
the sampler below is one ``jax.jit`` function of ``(keys, masks, initial points, inverse mass
matrix, schedule)``: the full fit is its all-true mask, a fold refit any other mask, and
changing the fold, the seed or the warm-up length reuses the compiled code. The data set's
*inputs* are constants of the compiled code, not arguments: XLA then computes everything that
depends on the inputs alone once, at compile time. With the inputs as arguments, the skf_2014
bearing law re-solved its rigid-ring ball loads (60 Newton steps per observation) at every
leapfrog step, 2.4 ms a step instead of 7 µs, and its fit ran past 30 minutes. The *response*
is an argument: :meth:`NutsEngine.with_response` refits other
responses on the same inputs (simulation studies, calibration replicates) with the same
compiled code. A repeated fit of the same data still loads its compiled program from disk.

Every chain is :func:`bayesfric.inference.adaptation.nuts_chain` (blackjax NUTS,
Stan's window adaptation from blackjax's public primitives) on the program's one log density
(:mod:`bayesfric.density`), vectorised with ``jax.vmap`` over chains and optionally over a
fixed-size batch of folds (``fold_batch``; the last batch is padded with copies of its first
fold so the batch shape, and so the compilation, never changes). A fold's chains run as
``chains / chain_batch`` groups (on CPUs one chain per group), each one call of the compiled
sampler on a thread pool: XLA releases the GIL, so on the 2-core machine a single fit, the
full one included, samples on both cores, and no chain waits for another's trajectory. A batch
of one is not vmapped at all (``vmap_or_squeeze``), which is what makes tracing cheap. The
chains' keys and starts do not depend on the grouping of the calls.

Progress: each call runs its chains' warm-up and sampling as consecutive calls of one compiled
chunk of ``chunk_steps`` schedule rows (:mod:`bayesfric.inference.chunked`: the carried state
goes from one call to the next, the draws are those of one call over the whole schedule), and
after each chunk reports to the run's :class:`~bayesfric.inference.progress.SamplingProgress`,
which shows something only inside :func:`bayesfric.inference.progress.reporting`.

Warm starts: :meth:`NutsEngine.warm_started` returns a view of the same compiled sampler whose
chains start at draws of a full fit, with its unconstrained posterior variance as the initial
inverse mass matrix and a 250-step warm-up (the schedule is data: the skipped warm-up steps
are idle). Folds that drop a few points (PSIS-LOO refits, random K-fold) use it; folds that
remove a whole region or series start cold (:meth:`NutsEngine.cold_started`: a shorter
Stan warm-up from the prior median inside the same compiled scan).

Every fold fit goes through the diagnostics gate of :mod:`bayesfric.inference.diagnostics`
(R-hat, bulk/tail ESS, divergences, E-BFMI on the fold's own draws, thresholds unchanged). A
fold that fails is *flagged* in the result, never silently used as if healthy.

>>> engine = NutsEngine(build_program(law, ds))                        # doctest: +SKIP
>>> dt = engine.fit(ds)                    # the full fit: the all-true mask  # doctest: +SKIP
>>> folds = engine.warm_started(dt).run(kfold_masks(ds, k=10).train)   # doctest: +SKIP
"""

from __future__ import annotations

import copy
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from bayesfric.fingerprint import program_parts
from bayesfric.inference.adaptation import DENSE_ABOVE, sampling_schedule
from bayesfric.inference.batching import FoldFits, available_cpus, chain_batch_of, join_chains, vmap_or_squeeze
from bayesfric.inference.chunked import CHUNK_STEPS, ChunkedSampler
from bayesfric.inference.datatree import assemble, draw_tables_args, tables_jit
from bayesfric.inference.diagnostics import GATE, Gate, Verdict, check_folds, import_statistics
from bayesfric.inference.init import Init, pending_chain_starts
from bayesfric.inference.pointwise import log_mean_likelihood, storage
from bayesfric.inference.progress import SamplingProgress, current
from bayesfric.inference.warmstart import warm_start_from
from bayesfric.model import Program

__all__ = ["NutsEngine", "FoldFits", "available_cpus", "METRICS"]

#: Mass matrices the warm-up can estimate (``NutsEngine(metric=...)``, study key ``[sampler] metric``).
METRICS = ("diag", "dense", "auto")


class NutsEngine:
    """The compiled NUTS sampler of one :class:`~bayesfric.model.Program`, full fit and folds.

    One compiled function serves the full fit (the all-true mask) and every fold refit (another
    mask); seeds, masks and warm or cold starts change nothing compiled. Why it is built this
    way, with the measurements behind each default: ``docs/inference.md``.

    Parameters
    ----------
    program : Program
        The law bound to the *full* dataset (its data scale fixes the priors of every fold).
    draws, tune, chains : int
        Per fit or fold. ``tune`` is the length of the compiled warm-up: a full Stan warm-up for
        the full fit and folds that start cold, or the frame of a warm start's shorter one.
        1000 draws by default because 500 left R-hat just above the gate on about one fold in ten.
    target_accept, max_tree_depth
        Target acceptance of the step-size adaptation and the largest tree depth (doublings).
    metric : {"auto", "diag", "dense"}
        The mass matrix the warm-up estimates (Stan's ``diag_e`` / ``dense_e``). ``auto`` keeps
        each slow window's dense estimate where the condition number of its correlation matrix
        exceeds :data:`~bayesfric.inference.adaptation.DENSE_ABOVE`, else its diagonal: per chain,
        re-decided at each window, recorded in the fit's ``metric`` setting (per draw in the
        ``dense_metric`` statistic of :meth:`run`'s folds). A dense metric crosses strongly
        correlated posteriors in far fewer leapfrog steps; where no window goes dense, ``auto``
        draws exactly what ``diag`` draws.
    retry_target_accept : float or None
        A fold (the full fit included) with divergent transitions is sampled once more, same keys
        and starts, at this target acceptance (default 0.99, a smaller step), and the second run
        is kept and gated; ``None`` or 0 switches it off. Under ``auto``, a fold that fails the
        gate after a chain went dense is first sampled again with the diagonal metric at
        ``target_accept`` (a dense metric fails on some curved posteriors where the diagonal one
        passes), and only if that fails too at this target, diagonal again; so no verdict is
        worse than the raised target alone would give. The targets are arguments of the compiled
        sampler: a retry compiles nothing and costs one more sampling of that fold only.
    fold_batch : int
        Folds sampled together in one vectorised call. Fixed per engine so one compilation
        serves any K. Default 1: vmapped NUTS steps wait for the longest trajectory of all
        ``fold_batch × chains`` chains, so folds in sequence are faster on CPUs.
    gate : Gate
        Diagnostics thresholds (default: the project gate).
    seed : int
        Seed of the chains' initial points, or of the draws picked as initial points under
        ``warm_start``.
    warm_start : xarray.DataTree, optional
        Start every chain from this full fit (see :meth:`warm_started`); the compiled warm-up is
        then ``warm_tune`` steps long. A study instead takes ``engine.warm_started(fit)`` of the
        engine that made the full fit, which shares its compiled sampler.
    warm_tune : int
        Warm-up steps per chain under ``warm_start`` (default 250; at least 120).
    init : {"median", "pathfinder"}
        Starting points of chains that start cold (:mod:`bayesfric.inference.init`): prior
        medians (default), or multi-path Pathfinder draws for posteriors with minor modes.
    threads : int, optional
        Calls of the compiled sampler (fold batches × chain groups) run at once, each from its
        own thread (XLA releases the GIL). Default: the CPUs this process may use. The draws do
        not depend on it.
    chain_batch : int, optional
        Chains vectorised in one call (a divisor of ``chains``). Default on CPUs: 1, each chain
        its own call, because a vmapped NUTS step waits for the longest trajectory in the batch
        and vmapped nested while loops are slow to trace; on an accelerator, all chains in one
        call. Fixed per engine (it is the compiled shape); the draws do not depend on it.
    chunk_steps : int
        Schedule rows per call of the compiled step function (default
        :data:`~bayesfric.inference.chunked.CHUNK_STEPS`): how often chains report progress.
        The draws do not depend on it.

    Notes
    -----
    ``compilations`` counts how often the sampler was built -- traced, or read from the exported
    programs on disk (:mod:`bayesfric.exported`; ``loaded`` says which): it stays at 1
    for every later call (any mask, seed, warm or cold start) on the engine and its views.
    """

    def __init__(
        self,
        program: Program,
        *,
        draws: int = 1000,
        tune: int = 500,
        chains: int = 4,
        target_accept: float = 0.9,
        max_tree_depth: int = 10,
        metric: str = "auto",
        retry_target_accept: float | None = 0.99,
        fold_batch: int = 1,
        gate: Gate = GATE,
        seed: int = 0,
        warm_start: xr.DataTree | None = None,
        warm_tune: int = 250,
        init: Init = "median",
        threads: int | None = None,
        chain_batch: int | None = None,
        chunk_steps: int = CHUNK_STEPS,
    ):
        self._program = program
        self.threads = available_cpus() if threads is None else max(1, int(threads))
        self.chain_batch = chain_batch_of(int(chains), chain_batch)
        self.draws, self.chains = int(draws), int(chains)
        self.target_accept, self.max_tree_depth = float(target_accept), int(max_tree_depth)
        if metric not in METRICS:
            raise ValueError(f"metric must be one of {', '.join(METRICS)} (got {metric!r})")
        self.metric = metric
        self.retry_target_accept = float(retry_target_accept) if retry_target_accept else None
        self.fold_batch = int(fold_batch)
        self.gate = gate
        self.seed = int(seed)
        self.compilations = 0
        self._density = program.density(seed)
        # the warm-up length is the compiled scan's; a warm start idles through part of it
        self.tune = int(warm_tune) if warm_start is not None else int(tune)
        self.warm = False
        self.active_tune = self.tune
        self._schedule = sampling_schedule(self.tune, self.draws)
        self.init = init  # how cold chains start (bayesfric.inference.init)
        # cold starts compile in the background while the sampler is traced (bayesfric.exported)
        self._cold_starts = pending_chain_starts(program, self.chains, seed, init)
        self._init_z = None  # None: the cold starts; a warm start sets its own
        self._init_imm = self._unit_imm()
        # warm-up and sampling in chunks of chunk_steps rows, for progress (bayesfric.inference.chunked)
        self._sampler = ChunkedSampler(self._density, self._data, vmap_or_squeeze, self._finish_batch,
                                       self._program_parts(), self._example_args(), self.max_tree_depth,
                                       self.tune, chunk_steps, self._traced, auto=self.metric == "auto")
        self.loaded = self._sampler.loaded
        self._tables = None  # the full fit's DataTree tables, compiled on the first fit
        self.compilations += int(self.loaded)  # a program read from disk counts as its one compilation
        if warm_start is not None:
            self._start_from(warm_start, int(warm_tune))

    @property
    def program(self) -> Program:
        """The program this engine samples (read-only: :meth:`with_response` swaps the response)."""
        return self._program

    def with_response(self, response: np.ndarray) -> NutsEngine:
        """This engine (same compiled sampler) on another response at the same inputs.

        The priors stay those the program was built with (data-scaled on its own response);
        ``response`` must have the program's shape and be finite.
        """
        y = np.asarray(response, dtype=self._program.response.dtype)
        if y.shape != self._program.response.shape:
            raise ValueError(f"response must have shape {self._program.response.shape}; got {y.shape}")
        if not np.isfinite(y).all():
            raise ValueError("response has non-finite values")
        view = copy.copy(self)
        view._program = replace(self._program, response=y)
        view._tables = None  # the original's compiled fit tables close over its own response
        return view

    def warm_started(self, fit: xr.DataTree, warm_tune: int = 250) -> NutsEngine:
        """This engine (same compiled sampler) with chains started from the full fit ``fit``.

        Each chain starts at a draw of that posterior (from different chains where possible)
        with its unconstrained posterior variance as the initial diagonal inverse mass matrix,
        and the warm-up shrinks to ``warm_tune`` steps (the rest of the compiled warm-up idles):
        a 50-step fast window (step size only), one slow window that re-estimates the mass
        matrix from the fold's own draws, and a 50-step fast window. Meant for folds that drop
        a few points (PSIS-LOO refits, random K-fold), whose posteriors are close to the full
        one; the gate still checks every fold. Use only a fit that passed the gate.
        ``warm_tune`` must lie in [120, ``tune``].
        """
        if warm_tune > self.tune:
            raise ValueError(f"warm_tune ({warm_tune}) exceeds the engine's warm-up of {self.tune} steps")
        view = copy.copy(self)
        view._start_from(fit, int(warm_tune))
        return view

    def cold_started(self, tune: int) -> NutsEngine:
        """This engine (same compiled sampler) with a cold Stan warm-up of ``tune`` steps.

        Chains start at the prior median with a unit mass matrix, as the full fit's do; the
        warm-up is Stan's default schedule over ``tune`` steps (the rest of the compiled
        warm-up idles). For folds that remove a whole region or series, whose posteriors may
        lie far from the full one. ``tune`` must lie in [120, the engine's warm-up].
        """
        if not 120 <= tune <= self.tune:
            raise ValueError(f"a cold warm-up needs 120 to {self.tune} steps (got {tune})")
        view = copy.copy(self)
        view._init_z = None  # the prior-median starts, computed once per engine
        view._init_imm = self._unit_imm()
        view._schedule = sampling_schedule(self.tune, self.draws, active=tune, warm=False)
        view.warm, view.active_tune = False, tune
        return view

    def _start_from(self, fit: xr.DataTree, warm_tune: int) -> None:
        if warm_tune < 120:
            raise ValueError(f"warm_tune must be at least 120 (got {warm_tune})")
        self._init_z, self._init_imm = warm_start_from(self.program, fit, self.chains, self.seed, self.metric)
        self._schedule = sampling_schedule(self.tune, self.draws, active=warm_tune)
        self.warm, self.active_tune = True, warm_tune

    @property
    def settings(self) -> dict:
        """Sampler settings, as stored with results."""
        return dict(draws=self.draws, tune=self.active_tune, chains=self.chains,
                    target_accept=self.target_accept, retry_target_accept=self.retry_target_accept,
                    max_tree_depth=self.max_tree_depth, metric=self.metric, fold_batch=self.fold_batch,
                    chain_batch=self.chain_batch, init=self.init,
                    sampler="blackjax NUTS, window adaptation",
                    warm_start="from the full fit's draws and mass matrix" if self.warm else "no")

    def _unit_imm(self) -> np.ndarray:
        """The inverse mass matrix chains start cold with: ones, or the identity (dense, auto)."""
        dim = self._density.dim
        return np.ones(dim) if self.metric == "diag" else np.eye(dim)

    # -- the compiled function ------------------------------------------------------------
    def _program_parts(self) -> dict:
        """What the traced sampler depends on besides the package source (its disk-cache key)."""
        return dict(program=program_parts(self.program, response=False), what="NutsEngine",
                    draws=self.draws, max_tree_depth=self.max_tree_depth, metric=self.metric)

    def _example_args(self) -> tuple:
        keys = jax.ShapeDtypeStruct((self.fold_batch, self.chain_batch) + jax.random.PRNGKey(0).shape, jnp.uint32)
        masks = jax.ShapeDtypeStruct((self.fold_batch, self.program.n_obs), jnp.bool_)
        y = self.program.response
        schedule = np.asarray(self._schedule)
        starts = jax.ShapeDtypeStruct((self.chain_batch, self._density.dim), self._init_imm.dtype)
        return (keys, masks, jax.ShapeDtypeStruct(y.shape, y.dtype), starts, self._init_imm,
                jax.ShapeDtypeStruct(schedule.shape, schedule.dtype),
                jax.ShapeDtypeStruct((), self._init_imm.dtype), jax.ShapeDtypeStruct((), self._init_imm.dtype))

    def _traced(self) -> None:
        self.compilations += 1  # runs only while tracing the sampler's step, i.e. once per compilation

    def _data(self, response) -> dict:
        p = self.program  # its inputs: constants of the compiled code (see the module notes)
        return dict(inputs=p.inputs, group_index=p.group_index, response=response)

    def _finish_batch(self, positions, masks, response):
        """Constrained draws and lpd of every observation from the kept unconstrained draws
        ``(fold, chain, draw, dim)`` of one call, each fold with its training mask (which levels
        of a group column its draws hold centred: ``Program.model``'s ``seen``)."""
        density = self._density  # the program's one log density
        data = self._data(response)

        def one_fold(position, mask):
            fold = dict(data, seen=mask)
            constrained = jax.vmap(jax.vmap(lambda v: density.constrain(v, fold)))(position)
            flat = {k: v.reshape((-1,) + v.shape[2:]) for k, v in constrained.items()}
            # draws × rows at once for small data, else in chunks of draws (bounded memory)
            lpd = log_mean_likelihood(lambda c: density.pointwise(c, fold), flat, self.program.n_obs)
            return constrained, lpd

        return vmap_or_squeeze(one_fold)(positions, masks)

    # -- public ---------------------------------------------------------------------------
    def run(self, train_masks: np.ndarray, seed: int = 0) -> FoldFits:
        """Refit the program once per row of ``train_masks`` (bool, ``(K, n_obs)``).

        Returns every fold's draws, the pointwise predictive density of all observations, and
        the gate verdict per fold. Folds whose draws diverged are sampled once more at
        ``retry_target_accept`` (see the class notes).
        """
        masks = np.asarray(train_masks, dtype=bool)
        if masks.ndim != 2 or masks.shape[1] != self.program.n_obs:
            raise ValueError(f"train masks must be (K, {self.program.n_obs}); got {masks.shape}")
        if not masks.any(axis=1).all():
            raise ValueError("a fold trains on no observation")
        start = time.perf_counter()
        folds = np.arange(masks.shape[0])
        samples, stats, lpd = self._sample(masks, folds, seed, self.target_accept, DENSE_ABOVE)
        fits = FoldFits(samples, lpd, self._verdicts(samples, stats), 0.0, stats,
                        np.full(folds.size, self.target_accept), np.zeros(folds.size, bool))
        raise_target = self.retry_target_accept is not None and self.retry_target_accept > self.target_accept
        went_dense = (stats["dense_metric"].any(axis=(1, 2)) if self.metric == "auto"
                      else np.zeros(folds.size, bool))
        # a dense metric that failed: first the diagonal one at the same target (its divergences
        # may say the metric was wrong, not that the step was too long), then, if that fails
        # too, the raised target (so never a worse verdict than the raised target alone)
        self._again(fits, masks, seed, [i for i, v in enumerate(fits.verdicts) if not v.passed and went_dense[i]],
                    self.target_accept)
        if raise_target:
            self._again(fits, masks, seed, [i for i, v in enumerate(fits.verdicts)
                                            if not v.passed and (v.divergences or went_dense[i])],
                        self.retry_target_accept)
        fits.diagonal[:] = fits.diagonal & went_dense
        fits.seconds = time.perf_counter() - start
        return fits

    def _again(self, fits: FoldFits, masks: np.ndarray, seed: int, retry: list[int], target: float) -> None:
        """Sample the folds ``retry`` once more at ``target`` (diagonal metric under ``auto``), same
        keys and starts, and keep that run in ``fits``."""
        if not retry:
            return
        again = self._sample(masks[retry], np.asarray(retry), seed, target,
                             np.inf if self.metric == "auto" else DENSE_ABOVE)
        for whole, part in ((fits.samples, again[0]), (fits.stats, again[1])):
            for name in whole:
                whole[name][retry] = part[name]
        fits.lpd[retry], fits.target_accept[retry], fits.diagonal[retry] = again[2], target, True
        for i, verdict in zip(retry, self._verdicts(again[0], again[1]), strict=True):
            fits.verdicts[i] = verdict

    def _sample(self, masks: np.ndarray, folds: np.ndarray, seed: int, target_accept: float,
                dense_above: float) -> tuple:
        """Draws, statistics and lpd of the folds ``folds`` (indices of the run, which fix
        their keys) with training masks ``masks``, at ``target_accept`` (and the ``auto``
        metric's threshold ``dense_above``)."""
        n_folds, b = masks.shape[0], self.fold_batch
        n_pad = (-n_folds) % b
        padded = np.concatenate([masks, np.repeat(masks[:1], n_pad, axis=0)])
        ids = np.concatenate([folds, np.repeat(folds[:1], n_pad)])
        # fold k's chains draw from fold_in(seed, k): independent of K, batch, padding and retries
        base = jax.random.PRNGKey(seed)
        keys = np.asarray(jnp.stack([jax.random.split(jax.random.fold_in(base, int(k)), self.chains) for k in ids]))
        # host arrays: a device-committed start would count as another signature of the
        # exported program and compile it again
        starts, cb = np.asarray(self._starts()), self.chain_batch
        fixed = (np.asarray(self._init_imm), np.asarray(self._schedule), np.asarray(target_accept, dtype=float),
                 np.asarray(dense_above, dtype=float))
        idle = self.tune - self.active_tune
        shown = SamplingProgress(current(), n_folds, self.chains, idle, self.active_tune, self.draws)

        def one_call(work: tuple[int, int]) -> Any:  # folds lo:lo+b, chains c:c+cb
            lo, c = work

            def report(rows: int, divergent: np.ndarray) -> None:
                shown.update(range(lo, lo + b), range(c, c + cb), rows, divergent)

            constrained, stats, lpd = self._sampler(keys[lo:lo + b, c:c + cb], padded[lo:lo + b],
                                                    self.program.response, starts[c:c + cb], *fixed,
                                                    report=report if shown.target is not None else None)
            return constrained, stats, lpd

        work = [(lo, c) for lo in range(0, padded.shape[0], b) for c in range(0, self.chains, cb)]
        threads = min(self.threads, len(work))
        if threads > 1:  # XLA runs each call on its own core; results keep their order
            with ThreadPoolExecutor(threads, thread_name_prefix="bayesfric-chains") as pool:
                parts = list(pool.map(one_call, work))
        else:
            parts = [one_call(w) for w in work]
        splits = self.chains // cb
        per_batch = [join_chains(parts[i:i + splits]) for i in range(0, len(parts), splits)]
        return jax.tree.map(lambda *xs: np.concatenate(xs)[:n_folds], *per_batch)

    def _verdicts(self, samples: dict, stats: dict) -> list[Verdict]:
        """The gate of every fold, in one pass of arviz-stats over a ``fold`` dimension."""
        lead = ("fold", "chain", "draw")

        site_dims = self.program.site_dims()

        def dims(name: str, value: np.ndarray) -> tuple[str, ...]:
            return lead + tuple(site_dims.get(name, [f"{name}_dim_{i}" for i in range(value.ndim - 3)]))

        posterior = xr.Dataset({k: (dims(k, v), np.asarray(v)) for k, v in samples.items()})
        sample_stats = xr.Dataset({k: (lead, np.asarray(stats[k])) for k in ("diverging", "energy")})
        return check_folds(posterior, sample_stats, gate=self.gate)

    def fit(self, ds: xr.Dataset, seed: int | None = None) -> xr.DataTree:
        """The full fit: the all-true mask of this engine, assembled into the fit's DataTree.

        ``ds`` is the data set the program was built on (for its coordinates and provenance).
        ``seed`` defaults to the engine's seed.
        """
        seed = self.seed if seed is None else int(seed)
        if self._tables is None:  # compiles in the background while the chains run
            self._tables = tables_jit(self.program, storage(self.program.n_obs, self.chains, self.draws))
            sites = {k: jax.ShapeDtypeStruct(v.shape[3:], v.dtype) for k, v in self._sampler.out_shapes[0].items()}
            self._tables.ahead(*draw_tables_args(sites, self.chains * self.draws, seed))
        import_statistics()  # the gate's library imports while the programs above compile or load
        fits = self.run(np.ones((1, self.program.n_obs), dtype=bool), seed=seed)
        samples = {k: v[0] for k, v in fits.samples.items()}
        stats = {k: v[0] for k, v in fits.stats.items()}
        dense = stats.pop("dense_metric").any(axis=-1)  # per chain: sampled with a dense metric
        settings = dict(draws=self.draws, tune=self.active_tune, chains=self.chains,
                        target_accept=float(fits.target_accept[0]), max_tree_depth=self.max_tree_depth,
                        init=self.init, algorithm="blackjax NUTS, Stan window adaptation")
        if self.metric == "auto":
            settings["metric"] = (f"auto: dense in {int(dense.sum())} of {dense.size} chains (correlation "
                                  f"condition number above {DENSE_ABOVE:g}), diagonal in the others")
        elif self.metric != "diag":  # recorded when not the default, so existing fits keep their attrs
            settings["metric"] = self.metric
        raised = fits.target_accept[0] != self.target_accept
        if fits.diagonal[0]:
            settings["retried"] = (f"the dense metric the warm-up chose failed the gate: sampled again with the "
                                   f"diagonal one at {self.target_accept}")
            if raised:
                settings["retried"] += f", which failed too; then at {fits.target_accept[0]}"
        elif raised:
            settings["retried"] = (f"divergent transitions at target_accept {self.target_accept}: sampled again "
                                   f"at {fits.target_accept[0]}")
        return assemble(self.program, ds, samples, stats, sampler="nuts", settings=settings, seed=seed,
                        tables=self._tables)

    def _starts(self) -> jax.Array:
        """The chains' starting points ``(chains, dim)``: a warm start's, or the cold ones."""
        return self._cold_starts() if self._init_z is None else self._init_z
