"""Compile-once refits: one jitted NUTS sampler per (law, data shape) serves every fold and seed.

Cross-validation needs many refits of the same program on subsets of the data. The program's
likelihood takes a 0/1 ``mask`` *as data* (:class:`bayesfric.model.Program`), so the sampler
below is one ``jax.jit`` function of ``(keys, masks, data)``: changing the fold, the seed or
even the dataset (same shapes) reuses the compiled code. Sampling is blackjax NUTS with
Stan-style window adaptation of step size and diagonal mass matrix, vectorised with
``jax.vmap`` over chains and optionally over a fixed-size batch of folds (``fold_batch``; the
last batch is padded with copies of its first fold so the batch shape, and so the compilation,
never changes). numpyro's ``MCMC(jit_model_args=True)`` was measured as the alternative and
was an order of magnitude slower per fold (see ``benchmarks/README.md``). Given a full fit
(``warm_start=``), every fold starts from its draws and mass matrix with a 250-step warm-up
instead of Stan's 500 from the prior median: a 10-fold refit then costs 1.7× one full fit,
compilation included, against 2.2× cold (``benchmarks/bench_refit.py``).

Every fold fit goes through the diagnostics gate of :mod:`bayesfric.inference.diagnostics`
(R-hat, bulk/tail ESS, divergences, E-BFMI on the fold's own draws, thresholds unchanged). A
fold that fails is *flagged* in the result; scores computed from it are reported with the flag,
never silently used as if healthy.

>>> engine = RefitEngine(build_program(law, ds))                       # doctest: +SKIP
>>> result = cross_validate(engine, kfold_masks(ds, k=10))             # doctest: +SKIP
>>> result.elpd, result.se, result.failed_folds                       # doctest: +SKIP
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import dataclass, field

import arviz as az
import blackjax
import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from blackjax.adaptation.staged_adaptation import build_schedule
from blackjax.adaptation.window_adaptation import base as window_adaptation_base

from bayesfric.compare.folds import Folds
from bayesfric.density import build_density
from bayesfric.inference.diagnostics import GATE, Gate, Verdict, check
from bayesfric.laws.variants import law_of_fit
from bayesfric.model import Noise, Program, build_program

__all__ = [
    "RefitEngine", "FoldFits", "CVResult", "cross_validate", "pointwise_lpd", "program_from_fit",
]


def pointwise_lpd(log_lik: np.ndarray) -> np.ndarray:
    """Log pointwise predictive density ``log mean_s p(y_i | θ_s)`` of draws ``(..., S, n)``.

    The leading axes are flattened into the draw axis ``S`` (chains × draws).
    """
    ll = jnp.asarray(log_lik)
    ll = ll.reshape((-1, ll.shape[-1]))
    return np.asarray(jax.scipy.special.logsumexp(ll, axis=0) - jnp.log(ll.shape[0]))


def program_from_fit(fit: xr.DataTree, ds: xr.Dataset) -> Program:
    """Rebuild the program of a fit from its provenance attrs (law, priors, noise, constants).

    Fits saved before the known noise sigma was recorded in the ``noise`` attr cannot be rebuilt
    when they used one; pass the fit's program explicitly for those.
    """
    noise = json.loads(fit.attrs["noise"])
    priors = json.loads(fit.attrs["priors"])
    sigma = noise.get("sigma")
    if noise["kind"] == "normal" and "sigma" not in priors and sigma is None:
        raise ValueError(f"fit of {fit.attrs['law']!r} used a known noise sigma, which its attrs "
                         "do not record; pass the fit's program (or engine) explicitly")
    return build_program(law_of_fit(fit.attrs), ds, priors=priors,
                         noise=Noise(kind=noise["kind"], group=noise.get("group"), sigma=sigma),
                         constants=json.loads(fit.attrs["constants"]))


@dataclass
class FoldFits:
    """Raw output of one :meth:`RefitEngine.run` call.

    Attributes
    ----------
    samples : dict of str to ndarray
        Constrained draws (sampled and deterministic sites) shaped ``(fold, chain, draw, ...)``.
    lpd : ndarray
        ``(fold, n_obs)``: log pointwise predictive density of *every* observation under each
        fold's posterior (held-out points are the ones cross-validation scores).
    verdicts : list of Verdict
        Diagnostics gate per fold.
    seconds : float
        Wall time of the call (compilation included when it happened).
    """

    samples: dict[str, np.ndarray]
    lpd: np.ndarray
    verdicts: list[Verdict]
    seconds: float

    @property
    def failed(self) -> list[int]:
        """Indices of folds whose posterior failed the gate."""
        return [i for i, v in enumerate(self.verdicts) if not v.passed]


class RefitEngine:
    """A compiled NUTS refit sampler for one :class:`~bayesfric.model.Program`.

    Parameters
    ----------
    program : Program
        The law bound to the *full* dataset (its data scale fixes the priors of every fold).
    draws, tune, chains : int
        Per fold. Default: a full fit's draws and chains with half its tuning (a fold posterior
        is close to the full one). The gate's R-hat and ESS thresholds apply in full; a fold
        that misses them is flagged. With 500 draws, R-hat of 1.011-1.013 flagged about one
        fold in ten on simple laws, hence the full 1000.
    target_accept, max_tree_depth
        As in :func:`bayesfric.inference.nuts.sample_nuts`.
    fold_batch : int
        Number of folds sampled together in one vectorised call (``vmap`` over
        ``fold_batch × chains`` NUTS chains). Fixed per engine so one compilation serves any K.
        Default 1 (chains vectorised, folds in sequence): on the 2-core CPU a 10-fold refit of
        the stribeck law took 17 s warm with ``fold_batch=1`` against 35 s with 10, because
        vmapped NUTS steps wait for the longest trajectory of all ``fold_batch × chains``
        chains (``benchmarks/bench_refit.py``).
    gate : Gate
        Diagnostics thresholds (default: the project gate, unchanged).
    seed : int
        Seed of the chains' initial points (prior median, as the full fit uses), or of the
        draws picked as initial points under ``warm_start``.
    warm_start : xarray.DataTree, optional
        A full fit of the same program. Each fold's chains then start at draws of that
        posterior (one per chain, from different chains where possible) with its unconstrained
        posterior variance as the initial diagonal inverse mass matrix, and warm-up shrinks to
        ``warm_tune`` steps: a 50-step fast window (step size only), one slow window that
        re-estimates the mass matrix from the fold's own draws, and a 50-step fast window.
        Meant for folds that drop a few points (PSIS-LOO refits, random K-fold): their
        posteriors are close to the full one, so the long Stan warm-up from the prior median is
        wasted work; the fold's posterior still decides the final mass matrix and step size,
        and the gate still checks every fold. Folds that remove a whole region or series
        (blocked, grouped) can move the posterior far from the full fit's; studies start those
        cold. Use only a fit that passed the gate.
    warm_tune : int
        Warm-up steps per chain under ``warm_start`` (default 250; at least 120).

    Notes
    -----
    ``compilations`` counts how often the sampler was traced (i.e. compiled): it stays at 1 for
    every later call with the same data shapes.
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
        fold_batch: int = 1,
        gate: Gate = GATE,
        seed: int = 0,
        warm_start: xr.DataTree | None = None,
        warm_tune: int = 250,
    ):
        self.program = program
        self.draws, self.chains = int(draws), int(chains)
        self.target_accept, self.max_tree_depth = float(target_accept), int(max_tree_depth)
        self.fold_batch = int(fold_batch)
        self.gate = gate
        self.compilations = 0
        self._density = program.density(seed)
        self.warm = warm_start is not None
        if self.warm:
            if warm_tune < 120:
                raise ValueError(f"warm_tune must be at least 120 (got {warm_tune})")
            self.tune = int(warm_tune)
            self._schedule = np.asarray(build_schedule(self.tune, initial_buffer_size=50, final_buffer_size=50,
                                                       first_window_size=self.tune - 100), dtype=int)
            self._init_z, self._init_imm = _warm_start_from(program, warm_start, self.chains, seed)
        else:
            self.tune = int(tune)
            self._schedule = np.asarray(build_schedule(self.tune), dtype=int)
            # prior-median starts (numpyro's init_to_median), from different prior draws per chain
            self._init_z = jnp.stack([build_density(program, seed * 7919 + c).x0 for c in range(self.chains)])
            self._init_imm = jnp.ones(self._density.dim)
        self._sampler = jax.jit(self._sample_batch)

    @property
    def settings(self) -> dict:
        """Sampler settings, as stored with results."""
        return dict(draws=self.draws, tune=self.tune, chains=self.chains,
                    target_accept=self.target_accept, max_tree_depth=self.max_tree_depth,
                    fold_batch=self.fold_batch, sampler="blackjax NUTS, window adaptation",
                    warm_start="from the full fit's draws and mass matrix" if self.warm else "no")

    # -- the compiled function ------------------------------------------------------------
    def _sample_batch(self, keys, masks, init_z, init_imm, inputs, group_index, response):
        self.compilations += 1  # runs only while tracing, i.e. once per compilation
        density = self._density  # the program's one log density, data passed as arguments
        data = dict(inputs=inputs, group_index=group_index, response=response)
        depth = self.max_tree_depth

        def one_fold(fold_keys, mask):
            def logdensity(x):
                return density.log_joint(x, mask, data)

            def one_chain(key, x0):
                return _nuts_chain(key, x0, logdensity, self._schedule, init_imm, self.draws,
                                   self.target_accept, depth)

            x, diverging, energy = jax.vmap(one_chain)(fold_keys, init_z)
            constrained = jax.vmap(jax.vmap(lambda v: density.constrain(v, data)))(x)
            flat = {k: v.reshape((-1,) + v.shape[2:]) for k, v in constrained.items()}
            ll = jax.vmap(lambda c: density.pointwise(c, data))(flat)
            lpd = jax.scipy.special.logsumexp(ll, axis=0) - jnp.log(ll.shape[0])
            return constrained, diverging, energy, lpd

        return jax.vmap(one_fold)(keys, masks)

    # -- public ---------------------------------------------------------------------------
    def run(self, train_masks: np.ndarray, seed: int = 0) -> FoldFits:
        """Refit the program once per row of ``train_masks`` (bool, ``(K, n_obs)``).

        Returns every fold's draws, the pointwise predictive density of all observations, and
        the gate verdict per fold.
        """
        masks = np.asarray(train_masks, dtype=bool)
        if masks.ndim != 2 or masks.shape[1] != self.program.n_obs:
            raise ValueError(f"train masks must be (K, {self.program.n_obs}); got {masks.shape}")
        if not masks.any(axis=1).all():
            raise ValueError("a fold trains on no observation")
        start = time.perf_counter()
        n_folds, b = masks.shape[0], self.fold_batch
        n_pad = (-n_folds) % b
        padded = np.concatenate([masks, np.repeat(masks[:1], n_pad, axis=0)])
        # fold k's chains draw from fold_in(seed, k): independent of K, batch and padding
        base = jax.random.PRNGKey(seed)
        keys = jnp.stack([jax.random.split(jax.random.fold_in(base, k), self.chains)
                          for k in range(padded.shape[0])])
        p = self.program
        parts = []
        for lo in range(0, padded.shape[0], b):
            out = self._sampler(keys[lo:lo + b], jnp.asarray(padded[lo:lo + b]), self._init_z,
                                self._init_imm, p.inputs, p.group_index, p.response)
            parts.append(jax.tree.map(np.asarray, out))
        joined = jax.tree.map(lambda *xs: np.concatenate(xs)[:n_folds], *parts)
        samples, diverging, energy, lpd = joined
        verdicts = [self._verdict({k: v[i] for k, v in samples.items()}, diverging[i], energy[i])
                    for i in range(n_folds)]
        return FoldFits(samples, lpd, verdicts, time.perf_counter() - start)

    def _verdict(self, samples: dict, diverging: np.ndarray, energy: np.ndarray) -> Verdict:
        dims = {k: ["group"] for k in ("group_z", "group_offset") if k in samples}
        dt = az.from_dict({"posterior": samples,
                           "sample_stats": {"diverging": diverging, "energy": energy}}, dims=dims)
        return check(dt, gate=self.gate)


def _warm_start_from(program: Program, fit: xr.DataTree, chains: int, seed: int):
    """Initial points and diagonal inverse mass matrix for the fold chains, from a full fit.

    Picks ``chains`` posterior draws (chain ``c % n_chains``, a random draw of it), maps them
    to the unconstrained space the sampler works in, and takes the per-coordinate variance of
    all unconstrained draws as the inverse mass matrix (floored at 1e-8 so a coordinate the
    data pin down hard keeps a positive scale).
    """
    density = program.density(seed)
    post = fit["posterior"]
    missing = [n for n in density.sites if n not in post.data_vars]
    if missing:
        raise ValueError(f"warm start: the fit lacks the sampled site(s) {missing}; is it a fit of "
                         f"{program.law.name!r} with the same noise model?")
    n_chain, n_draw = post.sizes["chain"], post.sizes["draw"]
    flat = {n: np.asarray(post[n].values).reshape((n_chain * n_draw,) + post[n].shape[2:]) for n in density.sites}
    unconstrained = density.to_unconstrained(flat)
    rng = np.random.default_rng(seed)
    picks = np.array([(c % n_chain) * n_draw + rng.integers(n_draw) for c in range(chains)])
    imm = jnp.maximum(jnp.var(unconstrained, axis=0), 1e-8)
    return unconstrained[picks], imm


def _nuts_chain(key, z0, logdensity, schedule: np.ndarray, init_imm, draws: int, target_accept: float,
                depth: int):
    """One NUTS chain with Stan's windowed adaptation, warm-up and sampling in ONE ``scan``.

    ``blackjax.window_adaptation`` followed by a sampling loop compiles the NUTS kernel twice
    (once inside each loop); stepping the same kernel through both phases halves compilation.
    The adaptation rules are blackjax's (``window_adaptation.base``: dual averaging of the step
    size, diagonal mass matrix from Welford variance in the slow windows of ``schedule``, a
    ``(tune, 2)`` array of (stage, window end) from ``build_schedule``), started from the
    inverse mass matrix ``init_imm``. Returns positions, divergence flags and energies of the
    ``draws`` post-warm-up steps.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        adapt_init, adapt_update, adapt_final = window_adaptation_base(
            True, target_acceptance_rate=target_accept, initial_inverse_mass_matrix=init_imm)
    kernel = blackjax.nuts.build_kernel()
    tune = schedule.shape[0]
    schedule = schedule.reshape(-1, 2)
    stage = jnp.concatenate([jnp.asarray(schedule[:, 0]), jnp.zeros(draws, dtype=int)])
    window_end = jnp.concatenate([jnp.asarray(schedule[:, 1], dtype=bool),
                                  jnp.zeros(draws, dtype=bool)])
    warming = jnp.arange(tune + draws) < tune

    def step(carry, xs):
        state, adapt = carry
        k, stage_i, end_i, warm_i = xs
        final_step, final_imm = adapt_final(adapt)
        step_size = jnp.where(warm_i, adapt.step_size, final_step)
        imm = jnp.where(warm_i, adapt.inverse_mass_matrix, final_imm)
        state, info = kernel(k, state, logdensity, step_size, imm, max_num_doublings=depth)
        updated = adapt_update(adapt, (stage_i, end_i), state.position, info.acceptance_rate)
        adapt = jax.tree.map(lambda new, old: jnp.where(warm_i, new, old), updated, adapt)
        return (state, adapt), (state.position, info.is_divergent, info.energy)

    state0 = blackjax.nuts.init(z0, logdensity)
    keys = jax.random.split(key, tune + draws)
    _, (z, diverging, energy) = jax.lax.scan(
        step, (state0, adapt_init(z0, 1.0)), (keys, stage, window_end, warming))
    return jax.tree.map(lambda a: a[tune:], z), diverging[tune:], energy[tune:]


@dataclass
class CVResult:
    """Cross-validated predictive performance of one law under one fold scheme.

    Attributes
    ----------
    law, scheme : str
        Law name and the fold scheme's description (:attr:`Folds.scheme`).
    elpd, se : float
        ``Σ_i log mean_s p(y_i | θ_s^(fold(i)))`` over held-out points, and
        ``sqrt(n · var(elpd_i))``.
    elpd_i : ndarray
        ``(n_obs,)``; NaN where a point is never held out.
    heldout : ndarray
        ``(n_obs,)`` bool, the points scored.
    verdicts : list of Verdict
        Gate verdict per fold; :attr:`failed_folds` lists those that failed.
    """

    law: str
    scheme: str
    elpd: float
    se: float
    elpd_i: np.ndarray
    heldout: np.ndarray
    verdicts: list[Verdict]
    seconds: float
    settings: dict = field(default_factory=dict)

    @property
    def failed_folds(self) -> list[int]:
        return [i for i, v in enumerate(self.verdicts) if not v.passed]

    @property
    def reliable(self) -> bool:
        """True when every fold's posterior passed the gate."""
        return not self.failed_folds

    @property
    def n_heldout(self) -> int:
        return int(self.heldout.sum())

    def __str__(self) -> str:
        flag = "" if self.reliable else f"  [FLAGGED: folds {self.failed_folds} failed the gate]"
        return (f"{self.law} / {self.scheme}: elpd {self.elpd:.2f} ± {self.se:.2f} "
                f"on {self.n_heldout} held-out points{flag}")


def cross_validate(engine: RefitEngine, folds: Folds, *, seed: int = 0) -> CVResult:
    """Refit on every fold's training mask and score its held-out points.

    Parameters
    ----------
    engine : RefitEngine
        Compiled sampler of the law on the full dataset.
    folds : Folds
        From :mod:`bayesfric.compare.folds`; each point may be held out at most once.
    seed : int
        Seed of the fold fits.

    Returns
    -------
    CVResult
        ``elpd = Σ_heldout log mean_s p(y_i | θ_s)`` (log-sum-exp over the fold's draws) with
        ``se = sqrt(n · var(elpd_i))``, and the per-fold gate verdicts.
    """
    counts = folds.heldout.sum(axis=0)
    if counts.max() > 1:
        raise ValueError(f"scheme {folds.scheme!r} holds some points out more than once")
    fits = engine.run(folds.train, seed=seed)
    elpd_i = np.full(engine.program.n_obs, np.nan)
    for k in range(folds.n_folds):
        elpd_i[folds.heldout[k]] = fits.lpd[k, folds.heldout[k]]
    heldout = counts == 1
    scored = elpd_i[heldout]
    return CVResult(
        law=engine.program.law.name,
        scheme=folds.scheme,
        elpd=float(scored.sum()),
        se=float(np.sqrt(scored.size * scored.var())),
        elpd_i=elpd_i,
        heldout=heldout,
        verdicts=fits.verdicts,
        seconds=fits.seconds,
        settings=engine.settings,
    )

