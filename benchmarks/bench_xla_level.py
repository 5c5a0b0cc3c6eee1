"""Trace, compile and run time of each main-job law's NUTS sampler at XLA's default CPU
optimisation level and at level 1, side by side in one process.

Run: ``BAYESFRIC_NO_CACHE=1 .venv/bin/python benchmarks/bench_xla_level.py [STUDY ...]``
(default: the five seed studies; ``BAYESFRIC_NO_CACHE=1`` so nothing is read from disk).
Prints one JSON line per law and level. Measured 2026-11-23 on robot_joint and dahl_duplex
(12 laws): 32.9 s of compilation at level 1 against 39.3 s at the default, sampling unchanged
within noise -- about 6 s of a 772 s cold main job, so the level is left at XLA's default.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time

import jax
import jax.numpy as jnp
import numpy as np

from bayesfric.inference import release_compiled_code
from bayesfric.inference.engine import NutsEngine
from bayesfric.model import build_program
from bayesfric.runtime import configure
from bayesfric.study import STUDIES_DIR
from bayesfric.study.plan import _prepare

LEVELS = ({}, {"xla_backend_optimization_level": 1})
SEEDS = ("robot_joint", "pitch_bearing", "dahl_duplex", "unwinder", "drum_rollout")


def time_law(engine: NutsEngine) -> list[dict]:
    """Lower, compile and run the engine's chain step (the whole schedule in one chunk: the engine
    is built with ``chunk_steps`` at least its schedule) once per optimisation level."""
    program, sampler = engine.program, engine.kernel.sampler
    assert sampler.chunk == sampler.rows, "build the engine with chunk_steps >= tune + draws"
    keys = np.asarray(jnp.stack([jax.random.split(jax.random.PRNGKey(1), engine.chains)]))
    masks = np.ones((1, program.n_obs), bool)
    leaves, step = sampler.start(keys, masks, program.response, np.asarray(engine.kernel.positions(engine.start)),
                                 np.asarray(engine.start.inverse_mass))
    args = (leaves, step, masks, program.response, np.asarray(engine.start.schedule), np.asarray(engine.target_accept))
    rows = []
    for options in LEVELS:
        jitted = jax.jit(sampler._advance, compiler_options=options or None)
        t0 = time.perf_counter()
        lowered = jitted.lower(*args)
        t1 = time.perf_counter()
        compiled = lowered.compile()
        t2 = time.perf_counter()
        out = jax.block_until_ready(compiled(*args))
        t3 = time.perf_counter()
        rows.append(dict(level=options.get("xla_backend_optimization_level", "default"), trace=round(t1 - t0, 2),
                         compile=round(t2 - t1, 2), run=round(t3 - t2, 2),
                         steps_per_draw=round(float(np.asarray(out[1]["n_steps"])[:, :, engine.tune:].mean()), 1)))
    return rows


def main(studies: list[str]) -> None:
    configure()
    with tempfile.TemporaryDirectory() as out:
        for name in studies:
            study, _, ds, config, *_ = _prepare(STUDIES_DIR / f"{name}.toml", out, False)
            for spec in study.laws:
                program = build_program(spec.build(), ds, priors=spec.priors, noise=study.noise,
                                        constants=spec.constants)
                engine = NutsEngine.build(program, config, seed=1, chain_batch=config.chains, chunk_steps=10**9)
                for row in time_law(engine):
                    print(json.dumps(dict(study=name, law=spec.name, **row)), flush=True)
                release_compiled_code()


if __name__ == "__main__":
    main(sys.argv[1:] or list(SEEDS))
