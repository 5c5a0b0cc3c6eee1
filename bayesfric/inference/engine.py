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

The engine is built as blackjax builds its kernels: :func:`build` (``NutsEngine.build``) takes a
program and a :class:`~bayesfric.inference.config.SamplerConfig` and compiles the
:class:`~bayesfric.inference.kernel.Kernel` once; a :class:`NutsEngine` is a frozen value of that
kernel, its program, its configuration and an immutable :class:`~bayesfric.inference.kernel.Start`.
A warm or cold start, or another response, is a new engine sharing the same kernel
(``dataclasses.replace``): nothing is copied and then changed, and no engine is kept anywhere but
by its caller (a study keeps a law's engine in :class:`bayesfric.study.units.Engines`).

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

Warm starts: :meth:`NutsEngine.warm_started` returns an engine of the same compiled sampler whose
chains start at draws of a full fit, with its unconstrained posterior variance as the initial
inverse mass matrix and a 250-step warm-up (the schedule is data: the skipped warm-up steps
are idle). Folds that drop a few points (PSIS-LOO refits, random K-fold) use it; folds that
remove a whole region or series start cold (:meth:`NutsEngine.cold_started`: a shorter
Stan warm-up from the prior median inside the same compiled scan).

Every fold fit goes through the diagnostics gate of :mod:`bayesfric.inference.diagnostics`
(R-hat, bulk/tail ESS, divergences, E-BFMI on the fold's own draws, thresholds unchanged). A
fold that fails is *flagged* in the result, never silently used as if healthy.

>>> engine = build(build_program(law, ds))                             # doctest: +SKIP
>>> dt = engine.fit(ds)                    # the full fit: the all-true mask  # doctest: +SKIP
>>> folds = engine.warm_started(dt).run(kfold_masks(ds, k=10).train)   # doctest: +SKIP
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.inference.adaptation import DENSE_ABOVE
from bayesfric.inference.batching import FoldFits, available_cpus, join_chains
from bayesfric.inference.config import METRICS, SamplerConfig
from bayesfric.inference.datatree import assemble
from bayesfric.inference.diagnostics import GATE, Gate, Verdict, check_folds, import_statistics
from bayesfric.inference.kernel import FitTables, Kernel, Start, cold_start, warm_start
from bayesfric.inference.progress import SamplingProgress, current
from bayesfric.model import Program

__all__ = ["NutsEngine", "build", "ENGINE_DEFAULTS", "FoldFits", "available_cpus", "METRICS"]

#: The configuration of an engine built without one: the NUTS defaults with a 500-step compiled
#: warm-up (the refits' length: a warm start uses 250 of it, a cold fold at most 500).
ENGINE_DEFAULTS = SamplerConfig(tune=500)


@dataclass(frozen=True, eq=False)
class NutsEngine:
    """The compiled NUTS sampler of one :class:`~bayesfric.model.Program`, full fit and folds.

    One compiled function serves the full fit (the all-true mask) and every fold refit (another
    mask); seeds, masks and warm or cold starts change nothing compiled. Made by :func:`build`;
    frozen: :meth:`warm_started`, :meth:`cold_started` and :meth:`with_response` return new
    engines sharing its :class:`~bayesfric.inference.kernel.Kernel`. Why it is built this way,
    with the measurements behind each default: ``docs/inference.md``.

    The ``auto`` metric keeps each slow window's dense estimate where the condition number of its
    correlation matrix exceeds :data:`~bayesfric.inference.adaptation.DENSE_ABOVE`, else its
    diagonal (per chain, recorded in the fit's ``metric`` setting and per draw in the
    ``dense_metric`` statistic of :meth:`run`'s folds); where no window goes dense it draws exactly
    what ``diag`` draws. A fold (the full fit included) with divergent transitions is sampled once
    more, same keys and starts, at ``retry_target_accept`` (default 0.99) and the second run is
    kept and gated; under ``auto``, a fold that fails the gate after a chain went dense is first
    sampled again with the diagonal metric at ``target_accept``, and only if that fails too at the
    raised target, diagonal again. The targets are arguments of the compiled sampler: a retry
    compiles nothing and costs one more sampling of that fold only. ``fold_batch`` folds are
    sampled in one vectorised call (default 1: vmapped NUTS steps wait for the longest trajectory,
    so folds in sequence are faster on CPUs); ``chain_batch`` chains per call (default on CPUs 1,
    on accelerators all); ``threads`` calls at once. The draws depend on none of these three.

    Attributes
    ----------
    program : Program
        The law bound to the *full* dataset (its data scale fixes the priors of every fold).
    config : SamplerConfig
        Its settings; ``config.tune`` is the compiled warm-up (a warm start's frame).
    kernel : Kernel
        The compiled programs, shared by every engine made from this one.
    start : Start
        Where its chains start and how long their warm-up is.
    gate : Gate
        Diagnostics thresholds (default: the project gate).

    Examples
    --------
    >>> engine = build(program, SamplerConfig(draws=300, tune=300, chains=2))   # doctest: +SKIP
    >>> fit = engine.fit(ds)                                                   # doctest: +SKIP
    >>> folds = engine.warm_started(fit).run(masks)      # the same compiled code  # doctest: +SKIP
    >>> engine.compilations                                                    # doctest: +SKIP
    1
    """

    program: Program
    config: SamplerConfig
    kernel: Kernel
    start: Start
    gate: Gate = GATE
    tables: FitTables = field(default_factory=FitTables, repr=False)

    @classmethod
    def build(cls, program: Program, config: SamplerConfig | None = None, *, gate: Gate = GATE,
              warm_start: xr.DataTree | None = None, warm_tune: int = 250, **settings: Any) -> NutsEngine:
        """Compile the sampler of ``program`` under ``config`` (:data:`ENGINE_DEFAULTS` over which
        ``settings`` apply, as :meth:`SamplerConfig.replace`); see :func:`build`."""
        config = (config or ENGINE_DEFAULTS).replace(**settings)
        if config.name != "nuts":
            raise UserError(f"the NUTS engine samples with NUTS, got sampler {config.name!r}", "name")
        if warm_start is not None:  # the compiled warm-up is the warm start's
            config = config.replace(tune=int(warm_tune))
        kernel = Kernel(program, config)
        engine = cls(program, config, kernel, cold_start(kernel), gate)
        return engine if warm_start is None else engine.warm_started(warm_start, int(warm_tune))

    # -- what it is -------------------------------------------------------------------------
    draws = property(lambda self: self.config.draws, doc="Draws per chain.")
    tune = property(lambda self: self.config.tune, doc="Steps of the compiled warm-up.")
    chains = property(lambda self: self.config.chains, doc="Chains per fold.")
    seed = property(lambda self: self.config.seed, doc="Seed of the starts (and of :meth:`fit`).")
    metric = property(lambda self: self.config.metric, doc="The warm-up's mass matrix.")
    init = property(lambda self: self.config.init, doc="How chains that start cold are placed.")
    target_accept = property(lambda self: self.config.target_accept, doc="Target acceptance.")
    retry_target_accept = property(lambda self: self.config.retry, doc="Retry target (None: off).")
    warm = property(lambda self: self.start.warm, doc="Whether chains start from a full fit.")
    active_tune = property(lambda self: self.start.active_tune, doc="Warm-up steps its runs use.")
    compilations = property(lambda self: self.kernel.compilations, doc="Builds of the compiled sampler.")
    loaded = property(lambda self: self.kernel.loaded, doc="Whether it was read from disk.")
    chain_batch = property(lambda self: self.kernel.chain_batch, doc="Chains per compiled call.")

    @property
    def threads(self) -> int:
        """Calls of the compiled sampler run at once (default: the CPUs this process may use)."""
        return self.config.threads or available_cpus()

    @property
    def settings(self) -> dict:
        """Sampler settings, as stored with results."""
        c = self.config
        return dict(draws=c.draws, tune=self.active_tune, chains=c.chains, target_accept=c.target_accept,
                    retry_target_accept=c.retry, max_tree_depth=c.max_tree_depth, metric=c.metric,
                    fold_batch=c.fold_batch, chain_batch=self.chain_batch, init=c.init,
                    sampler="blackjax NUTS, window adaptation",
                    warm_start="from the full fit's draws and mass matrix" if self.warm else "no")

    # -- variations: new engines of the same kernel ------------------------------------------
    def with_response(self, response: np.ndarray) -> NutsEngine:
        """This engine (same compiled sampler) on another response at the same inputs.

        The priors stay those the program was built with (data-scaled on its own response);
        ``response`` must have the program's shape and be finite.
        """
        y = np.asarray(response, dtype=self.program.response.dtype)
        if y.shape != self.program.response.shape:
            raise UserError(f"must have shape {self.program.response.shape}; got {y.shape}", "response")
        if not np.isfinite(y).all():
            raise UserError("has non-finite values", "response")
        return replace(self, program=replace(self.program, response=y), tables=FitTables())

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
        return replace(self, start=warm_start(self.kernel, self.program, fit, int(warm_tune)))

    def cold_started(self, tune: int) -> NutsEngine:
        """This engine (same compiled sampler) with a cold Stan warm-up of ``tune`` steps.

        Chains start at the prior median with a unit mass matrix, as the full fit's do; the
        warm-up is Stan's default schedule over ``tune`` steps (the rest of the compiled
        warm-up idles). For folds that remove a whole region or series, whose posteriors may
        lie far from the full one. ``tune`` must lie in [120, the engine's warm-up].
        """
        return replace(self, start=cold_start(self.kernel, int(tune)))

    # -- public ---------------------------------------------------------------------------
    def run(self, train_masks: np.ndarray, seed: int = 0) -> FoldFits:
        """Refit the program once per row of ``train_masks`` (bool, ``(K, n_obs)``).

        Returns every fold's draws, the pointwise predictive density of all observations, and
        the gate verdict per fold. Folds whose draws diverged are sampled once more at
        ``retry_target_accept`` (see the class notes).
        """
        masks = np.asarray(train_masks, dtype=bool)
        if masks.ndim != 2 or masks.shape[1] != self.program.n_obs:
            raise UserError(f"must be (K, {self.program.n_obs}); got {masks.shape}", "train_masks")
        if not masks.any(axis=1).all():
            raise UserError("a fold trains on no observation", "train_masks")
        start = time.perf_counter()
        folds = np.arange(masks.shape[0])
        target, retry = self.config.target_accept, self.config.retry
        samples, stats, lpd = self._sample(masks, folds, seed, target, DENSE_ABOVE)
        fits = FoldFits(samples, lpd, self._verdicts(samples, stats), 0.0, stats,
                        np.full(folds.size, target), np.zeros(folds.size, bool))
        went_dense = (stats["dense_metric"].any(axis=(1, 2)) if self.metric == "auto"
                      else np.zeros(folds.size, bool))
        # a dense metric that failed: first the diagonal one at the same target (its divergences
        # may say the metric was wrong, not that the step was too long), then, if that fails
        # too, the raised target (so never a worse verdict than the raised target alone)
        fits = self._again(fits, masks, seed, [i for i, v in enumerate(fits.verdicts)
                                               if not v.passed and went_dense[i]], target)
        if retry is not None and retry > target:
            fits = self._again(fits, masks, seed, [i for i, v in enumerate(fits.verdicts)
                                                   if not v.passed and (v.divergences or went_dense[i])], retry)
        return replace(fits, diagonal=fits.diagonal & went_dense, seconds=time.perf_counter() - start)

    def _again(self, fits: FoldFits, masks: np.ndarray, seed: int, retry: list[int], target: float) -> FoldFits:
        """``fits`` with the folds ``retry`` sampled once more at ``target`` (diagonal metric under
        ``auto``), same keys and starts: a new result, ``fits`` unchanged."""
        if not retry:
            return fits
        again = self._sample(masks[retry], np.asarray(retry), seed, target,
                             np.inf if self.metric == "auto" else DENSE_ABOVE)

        def merged(whole: np.ndarray, part: np.ndarray) -> np.ndarray:
            out = np.array(whole, copy=True)
            out[retry] = part
            return out

        verdicts = list(fits.verdicts)
        for i, verdict in zip(retry, self._verdicts(again[0], again[1]), strict=True):
            verdicts[i] = verdict
        return replace(fits, samples={k: merged(v, again[0][k]) for k, v in fits.samples.items()},
                       stats={k: merged(v, again[1][k]) for k, v in fits.stats.items()},
                       lpd=merged(fits.lpd, again[2]), verdicts=verdicts,
                       target_accept=merged(fits.target_accept, target), diagonal=merged(fits.diagonal, True))

    def _sample(self, masks: np.ndarray, folds: np.ndarray, seed: int, target_accept: float,
                dense_above: float) -> tuple:
        """Draws, statistics and lpd of the folds ``folds`` (indices of the run, which fix
        their keys) with training masks ``masks``, at ``target_accept`` (and the ``auto``
        metric's threshold ``dense_above``)."""
        c, cb, sampler = self.config, self.chain_batch, self.kernel.sampler
        n_folds, b = masks.shape[0], c.fold_batch
        n_pad = (-n_folds) % b
        padded = np.concatenate([masks, np.repeat(masks[:1], n_pad, axis=0)])
        ids = np.concatenate([folds, np.repeat(folds[:1], n_pad)])
        # fold k's chains draw from fold_in(seed, k): independent of K, batch, padding and retries
        base = jax.random.PRNGKey(seed)
        keys = np.asarray(jnp.stack([jax.random.split(jax.random.fold_in(base, int(k)), c.chains) for k in ids]))
        # host arrays: a device-committed start would count as another signature of the
        # exported program and compile it again
        starts = np.asarray(self.kernel.positions(self.start))
        fixed = (np.asarray(self.start.inverse_mass), np.asarray(self.start.schedule),
                 np.asarray(target_accept, dtype=float), np.asarray(dense_above, dtype=float))
        shown = SamplingProgress(current(), n_folds, c.chains, c.tune - self.active_tune, self.active_tune, c.draws)

        def one_call(work: tuple[int, int]) -> Any:  # folds lo:lo+b, chains i:i+cb
            lo, i = work

            def report(rows: int, divergent: np.ndarray) -> None:
                shown.update(range(lo, lo + b), range(i, i + cb), rows, divergent)

            return sampler(keys[lo:lo + b, i:i + cb], padded[lo:lo + b], self.program.response, starts[i:i + cb],
                           *fixed, report=report if shown.target is not None else None)

        work = [(lo, i) for lo in range(0, padded.shape[0], b) for i in range(0, c.chains, cb)]
        threads = min(self.threads, len(work))
        if threads > 1:  # XLA runs each call on its own core; results keep their order
            with ThreadPoolExecutor(threads, thread_name_prefix="bayesfric-chains") as pool:
                parts = list(pool.map(one_call, work))
        else:
            parts = [one_call(w) for w in work]
        splits = c.chains // cb
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
        tables = self.tables.of(self, seed)
        import_statistics()  # the gate's library imports while the programs above compile or load
        fits = self.run(np.ones((1, self.program.n_obs), dtype=bool), seed=seed)
        samples = {k: v[0] for k, v in fits.samples.items()}
        stats = {k: v[0] for k, v in fits.stats.items()}
        dense = stats.pop("dense_metric").any(axis=-1)  # per chain: sampled with a dense metric
        settings = dict(draws=self.draws, tune=self.active_tune, chains=self.chains,
                        target_accept=float(fits.target_accept[0]), max_tree_depth=self.config.max_tree_depth,
                        init=self.init, algorithm="blackjax NUTS, Stan window adaptation")
        settings |= _fit_notes(self.metric, self.target_accept, dense, fits)
        return assemble(self.program, ds, samples, stats, sampler="nuts", settings=settings, seed=seed, tables=tables)


def _fit_notes(metric: str, target: float, dense: np.ndarray, fits: FoldFits) -> dict:
    """What a full fit records of its metric and of a retry."""
    notes = {}
    if metric == "auto":
        notes["metric"] = (f"auto: dense in {int(dense.sum())} of {dense.size} chains (correlation "
                           f"condition number above {DENSE_ABOVE:g}), diagonal in the others")
    elif metric != "diag":  # recorded when not the default, so existing fits keep their attrs
        notes["metric"] = metric
    raised = fits.target_accept[0] != target
    if fits.diagonal[0]:
        notes["retried"] = (f"the dense metric the warm-up chose failed the gate: sampled again with the "
                            f"diagonal one at {target}")
        if raised:
            notes["retried"] += f", which failed too; then at {fits.target_accept[0]}"
    elif raised:
        notes["retried"] = (f"divergent transitions at target_accept {target}: sampled again "
                            f"at {fits.target_accept[0]}")
    return notes


def build(program: Program, config: SamplerConfig | None = None, *, gate: Gate = GATE,
          warm_start: xr.DataTree | None = None, warm_tune: int = 250, **settings: Any) -> NutsEngine:
    """Compile the NUTS sampler of ``program`` under ``config`` and return its engine.

    Parameters
    ----------
    program : Program
        The law bound to the full data set.
    config : SamplerConfig, optional
        Its settings (default :data:`ENGINE_DEFAULTS`); ``settings`` replace some of them.
    gate : Gate
        Diagnostics thresholds.
    warm_start : xarray.DataTree, optional
        Start every chain from this full fit (:meth:`NutsEngine.warm_started`); the compiled
        warm-up is then ``warm_tune`` steps long. A study instead takes
        ``engine.warm_started(fit)`` of the engine that made the full fit (one compilation).
    warm_tune : int
        Warm-up steps per chain under ``warm_start`` (default 250; at least 120).

    Returns
    -------
    NutsEngine
        Frozen: its variations are new engines of the same compiled kernel.

    Examples
    --------
    >>> engine = build(program, SamplerConfig(draws=300, tune=300, chains=2, seed=1))  # doctest: +SKIP
    >>> engine.cold_started(200).run(masks).verdicts                                  # doctest: +SKIP
    """
    return NutsEngine.build(program, config, gate=gate, warm_start=warm_start, warm_tune=warm_tune, **settings)
