"""How the engine's chains and folds are batched: which chains go in one call of the compiled
sampler, a batch of one without ``vmap``, the chain groups joined back, the threads to use, and
the raw result of a run (:class:`FoldFits`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import jax
import numpy as np
from scipy.special import logsumexp

from bayesfric.errors import UserError
from bayesfric.inference.diagnostics import Verdict

__all__ = ["FoldFits", "available_cpus", "chain_batch_of", "join_chains", "vmap_or_squeeze"]


def available_cpus() -> int:
    """CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass(frozen=True)
class FoldFits:
    """Raw output of one :meth:`NutsEngine.run` call (immutable: a retry or a resolved fold is a
    new value, :func:`dataclasses.replace`).

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
    stats : dict of str to ndarray
        Per-draw sampler statistics shaped ``(fold, chain, draw)``: ``diverging``, ``energy``,
        ``n_steps`` (leapfrog steps), ``acceptance_rate`` and ``dense_metric`` (whether the draw's
        metric was dense).
    target_accept : ndarray
        ``(fold,)``: the target acceptance each fold's draws were adapted to (the engine's, or
        its ``retry_target_accept`` where the first run diverged).
    diagonal : ndarray
        ``(fold,)``: whether the fold was sampled again with the diagonal metric (``auto``
        metric: its first run, dense in some chain, failed the gate).
    """

    samples: dict[str, np.ndarray]
    lpd: np.ndarray
    verdicts: list[Verdict]
    seconds: float
    stats: dict[str, np.ndarray] = field(default_factory=dict)
    target_accept: np.ndarray = field(default_factory=lambda: np.zeros(0))
    diagonal: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    @property
    def failed(self) -> list[int]:
        """Indices of folds whose posterior failed the gate."""
        return [i for i, v in enumerate(self.verdicts) if not v.passed]


def vmap_or_squeeze(fn: Any) -> Any:
    """``jax.vmap(fn)``, or for a batch of one, ``fn`` on the single element (its outputs given
    the batch axis back). Tracing vmapped NUTS is dear: the batching rules of its nested while
    loops re-trace their bodies to a fixed point, 4.5 of the 6.3 s it took to trace the lugre
    sampler with two chains in a batch; a single chain needs none of it."""
    def squeezed(*args: Any) -> Any:
        if all(a.shape[0] == 1 for a in jax.tree.leaves(args)):
            out = fn(*jax.tree.map(lambda a: a[0], args))
            return jax.tree.map(lambda a: a[None], out)
        return jax.vmap(fn)(*args)

    return squeezed


def chain_batch_of(chains: int, chain_batch: int | None) -> int:
    """Chains per call of the compiled sampler: ``chain_batch``, checked, or by default one chain
    per call on CPUs and all chains on accelerators."""
    if chain_batch is None:  # see the class notes: one chain per call on CPUs, all chains on accelerators
        return 1 if jax.default_backend() == "cpu" else chains
    if chain_batch < 1 or chains % chain_batch:
        raise UserError(f"must divide chains ({chains}); got {chain_batch}", "chain_batch")
    return int(chain_batch)


def join_chains(parts: list[Any]) -> Any:
    """One fold batch from its chain groups: draws joined along the chain axis; the pointwise
    predictive density, a log-mean over each group's (equally many) draws, combined into the
    log-mean over all."""
    samples = jax.tree.map(lambda *xs: np.concatenate(xs, axis=1), *[p[0] for p in parts])
    stats = jax.tree.map(lambda *xs: np.concatenate(xs, axis=1), *[p[1] for p in parts])
    lpd = logsumexp(np.stack([p[2] for p in parts]), axis=0) - np.log(len(parts))
    return samples, stats, lpd
