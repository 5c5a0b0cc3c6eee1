"""The engine's chains in chunks: the same compiled step function called again and again with
the carried state, so a fit can report progress between calls.

A chain's warm-up and sampling (:func:`bayesfric.inference.adaptation.nuts_chain`, one
``lax.scan`` over the schedule) ran as one call of the compiled sampler, so nothing could be
shown inside a 5-13 minute fit. Here the scan runs in chunks of ``chunk`` schedule rows: a
*start* program makes each chain's carry (NUTS state and adaptation state at its starting
point) and its per-step keys, an *advance* program moves the carry over one chunk of the
schedule and returns the chunk's output, and the engine's *finish* program maps the kept draws
to the constrained space and computes the pointwise predictive density. All three are traced
once per engine (and kept on disk, :mod:`bayesfric.exported`); the advance program, which holds
the NUTS kernel and the law, is the one the engine counts as its compilation. The schedule is
padded with inactive rows to a whole number of chunks (an inactive row leaves the chain
untouched and uses no key), so the carry and the keys seen by every step are those of the
unchunked scan, and so are the draws (``tests/test_progress.py``). Between chunks the carry
stays where the program left it; only a chunk's divergences are read back, and only when
progress is shown.

Overhead: one call per chunk and chain group, about 0.3 ms each: 16-32 ms per fit of 4 chains ×
2000 rows against the one-call engine (``benchmarks/bench_chunked.py``, benchmarks/README.md).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import numpy as np

from bayesfric.exported import exported_jit
from bayesfric.inference.adaptation import chain_start, chain_steps, step_keys
from bayesfric.inference.config import CHUNK_STEPS

__all__ = ["ChunkedSampler", "CHUNK_STEPS"]

# CHUNK_STEPS (schedule rows per compiled call) is a setting of SamplerConfig: bayesfric.inference.config


class ChunkedSampler:
    """The start / advance / finish programs of one engine and the loop that drives them.

    Parameters
    ----------
    density
        The program's log density (``log_joint``, ``dim``).
    data_of : callable
        ``data_of(response)`` -> the density's data dict (inputs are constants, the response an
        argument).
    vmap : callable
        :func:`bayesfric.inference.batching.vmap_or_squeeze`.
    finish : callable
        ``finish(positions (F, C, D, dim), masks (F, n_obs), response)`` -> ``(constrained, lpd)``.
    parts : dict
        The engine's disk-cache key parts (each program adds what it is).
    example : tuple
        ``(keys, masks, response, starts, init_imm, schedule, target_accept, dense_above)``:
        shapes of a call.
    depth : int
        Maximum tree depth of NUTS.
    tune : int
        Warm-up rows of the schedule (the rest are draws).
    chunk : int
        Schedule rows per call of the advance program.
    auto : bool
        The ``auto`` metric (:func:`bayesfric.inference.adaptation.chain_start`).
    on_trace : callable
        Called once per trace of the advance program (the engine counts its compilations).
    """

    def __init__(self, density: Any, data_of: Callable, vmap: Callable, finish: Callable, parts: dict,
                 example: tuple, depth: int, tune: int, chunk: int, on_trace: Callable[[], None],
                 auto: bool = False):
        keys, masks, response, starts, init_imm, schedule, target, dense_above = example
        self.density, self.data_of, self.vmap, self.depth, self.on_trace = density, data_of, vmap, depth, on_trace
        self.auto = bool(auto)
        self.rows = schedule.shape[0]
        self.tune = tune
        self.chunk = max(1, min(int(chunk), self.rows))
        self.padded = -(-self.rows // self.chunk) * self.chunk
        n_folds, n_chains = keys.shape[0], keys.shape[1]
        start_args = (keys, masks, response, starts, init_imm)
        carry_shapes, keys_shape = jax.eval_shape(self._start_tree, *start_args)
        self.treedef = jax.tree.structure(carry_shapes)
        self.start, _ = exported_jit(self._start, parts | dict(what="chunked start", rows=self.rows),
                                     start_args, ahead=True)
        chunk_keys = jax.ShapeDtypeStruct((n_folds, n_chains, self.chunk) + keys_shape.shape[3:], keys_shape.dtype)
        chunk_rows = jax.ShapeDtypeStruct((self.chunk,) + schedule.shape[1:], schedule.dtype)
        advance_args = (jax.tree.leaves(carry_shapes), chunk_keys, masks, response, chunk_rows, target, dense_above)
        self.advance, self.loaded = exported_jit(self._advance, parts | dict(what="chunked advance"),
                                                 advance_args, ahead=True)
        dim = starts.shape[-1]
        positions = jax.ShapeDtypeStruct((n_folds, n_chains, self.rows - tune, dim), starts.dtype)
        self.finish, _ = exported_jit(finish, parts | dict(what="chunked finish"), (positions, masks, response),
                                      ahead=True)

    @property
    def out_shapes(self) -> Any:
        """Shapes of ``(constrained, lpd)`` of a call (the finish program's)."""
        return self.finish.out_shapes

    @property
    def fallbacks(self) -> int:
        """Calls of the three programs that did not match their ahead-compiled signature."""
        return sum(getattr(f, "fallbacks", 0) for f in (self.start, self.advance, self.finish))

    # -- traced ------------------------------------------------------------------------------
    def _start_tree(self, keys, masks, response, starts, init_imm):
        data = self.data_of(response)

        def one_fold(fold_keys, mask):
            def logdensity(x):  # the fold's levels without data sampled non-centred (Program.model ``seen``)
                return self.density.log_joint(x, mask, dict(data, seen=mask))

            def one_chain(key, x0):
                return chain_start(x0, logdensity, init_imm, self.auto), step_keys(key, self.rows)

            return self.vmap(one_chain)(fold_keys, starts)

        return self.vmap(one_fold)(keys, masks)

    def _start(self, keys, masks, response, starts, init_imm):
        carry, step = self._start_tree(keys, masks, response, starts, init_imm)
        return jax.tree.leaves(carry), step

    def _advance(self, leaves, keys, masks, response, rows, target_accept, dense_above):
        self.on_trace()
        data = self.data_of(response)
        carry = jax.tree.unflatten(self.treedef, leaves)

        def one_fold(fold_carry, fold_keys, mask):
            def logdensity(x):
                return self.density.log_joint(x, mask, dict(data, seen=mask))

            def one_chain(c, k):
                return chain_steps(c, k, rows, logdensity, target_accept, self.depth, self.auto, dense_above)

            return self.vmap(one_chain)(fold_carry, fold_keys)

        carry, out = self.vmap(one_fold)(carry, keys, masks)
        return jax.tree.leaves(carry), out._asdict()

    # -- the loop ----------------------------------------------------------------------------
    def __call__(self, keys, masks, response, starts, init_imm, schedule, target_accept, dense_above,
                 report: Callable[[int, np.ndarray], None] | None = None) -> tuple:
        """``(constrained, stats, lpd)`` of one call of the unchunked sampler: the draws after
        the warm-up, per-draw statistics and the pointwise predictive density. ``report(rows,
        divergent)`` is called after each chunk with the rows done and the divergent
        transitions of the chunk's sampling rows per (fold, chain)."""
        leaves, step = self.start(keys, masks, response, starts, init_imm)
        leaves, step = [np.asarray(x) for x in leaves], np.asarray(step)
        pad = np.zeros(step.shape[:2] + (self.padded - self.rows,) + step.shape[3:], dtype=step.dtype)
        step = np.concatenate([step, pad], axis=2)  # inactive rows use no key
        rows = np.zeros((self.padded,) + schedule.shape[1:], dtype=schedule.dtype)
        rows[:self.rows] = schedule
        outs = []
        for lo in range(0, self.padded, self.chunk):
            part = rows[lo:lo + self.chunk]
            leaves, out = self.advance(leaves, step[:, :, lo:lo + self.chunk], masks, response, part,
                                       target_accept, dense_above)
            outs.append(out)  # the carry and the output stay where the program put them
            if report is not None:
                sampling = (part[:, 2] == 1) & (part[:, 3] == 1)
                report(min(lo + self.chunk, self.rows), np.asarray(out["diverging"])[:, :, sampling].sum(axis=-1))
        kept = {k: np.concatenate([np.asarray(o[k]) for o in outs], axis=2)[:, :, self.tune:self.rows]
                for k in outs[0]}
        constrained, lpd = self.finish(kept.pop("position"), masks, response)
        return jax.tree.map(np.asarray, constrained), kept, np.asarray(lpd)
