"""Compile and run time of each main-job law's NUTS sampler and of its fit's tables (the
once-run program of :func:`bayesfric.inference.datatree.draw_tables_jit`) at XLA's CPU
optimisation levels, side by side in one process.

Run: ``BAYESFRIC_NO_CACHE=1 .venv/bin/python benchmarks/bench_xla_level.py [STUDY ...] [--laws N]``
(default: the seed studies; ``BAYESFRIC_NO_CACHE=1`` so nothing is read from disk). Prints one
JSON line per law, program and level. What it decided (:mod:`bayesfric.exported`): the sampler
stays at the default level (level 1 saved ~15 % of its compilation, level 0 slowed sampling
more than it saved); the tables compile at level 0 (about half the compilation, 3-4x a run of
milliseconds). Figures in benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer import Predictive

from bayesfric.inference import release_compiled_code
from bayesfric.inference.adaptation import DENSE_ABOVE
from bayesfric.inference.datatree import N_PRIOR, OBS_SITE, _draw_tables
from bayesfric.inference.engine import NutsEngine
from bayesfric.model import build_program
from bayesfric.runtime import configure
from bayesfric.study import STUDIES_DIR
from bayesfric.study.plan import _prepare

LEVELS = ({}, {"xla_backend_optimization_level": 1}, {"xla_backend_optimization_level": 0})
SEEDS = ("robot_joint", "pitch_bearing", "dahl_duplex", "unwinder", "drum_rollout", "drum_campaigns")


def time_law(engine: NutsEngine) -> list[dict]:
    """Lower, compile and run the engine's chain step (the whole schedule in one chunk: the engine
    is built with ``chunk_steps`` at least its schedule) once per optimisation level."""
    program, sampler = engine.program, engine.kernel.sampler
    assert sampler.chunk == sampler.rows, "build the engine with chunk_steps >= tune + draws"
    keys = np.asarray(jnp.stack([jax.random.split(jax.random.PRNGKey(1), engine.chains)]))
    masks = np.ones((1, program.n_obs), bool)
    leaves, step = sampler.start(keys, masks, program.response, np.asarray(engine.kernel.positions(engine.start)),
                                 np.asarray(engine.start.inverse_mass))
    args = (leaves, step, masks, program.response, np.asarray(engine.start.schedule), np.asarray(engine.target_accept),
            np.asarray(DENSE_ABOVE, dtype=float))
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
        rows.append(dict(program="sampler", level=options.get("xla_backend_optimization_level", "default"),
                         trace=round(t1 - t0, 2),
                         compile=round(t2 - t1, 2), run=round(t3 - t2, 2),
                         steps_per_draw=round(float(np.asarray(out[1]["n_steps"])[:, :, engine.tune:].mean()), 1)))
    return rows


def time_tables(program, n_draws: int = 4000) -> list[dict]:
    """Compile and run time of a fit's tables over ``n_draws`` prior draws, per level."""
    prior = Predictive(program.model, num_samples=n_draws)(jax.random.PRNGKey(0),
                                                             **dict(program.model_kwargs, response=None))
    flat = {k: np.asarray(v) for k, v in prior.items() if k != OBS_SITE}
    key = jax.random.PRNGKey(1)
    rows = []
    for options in LEVELS:
        jitted = jax.jit(partial(_draw_tables, program, N_PRIOR), compiler_options=options or None)
        t0 = time.perf_counter()
        compiled = jitted.lower(flat, key, key).compile()
        t1 = time.perf_counter()
        for _ in range(3):
            jax.block_until_ready(compiled(flat, key, key))
        t2 = time.perf_counter()
        rows.append(dict(program="tables", level=options.get("xla_backend_optimization_level", "default"),
                         compile=round(t1 - t0, 2), run=round((t2 - t1) / 3, 4)))
    return rows


def main(studies: list[str], laws: int | None = None) -> None:
    configure()
    with tempfile.TemporaryDirectory() as out:
        for name in studies:
            study, _, ds, config, *_ = _prepare(STUDIES_DIR / f"{name}.toml", out, False)
            for spec in study.laws[:laws]:
                program = build_program(spec.build(), ds, priors=spec.priors, noise=study.noise,
                                        constants=spec.constants)
                engine = NutsEngine.build(program, config, seed=1, chain_batch=config.chains, chunk_steps=10**9)
                for row in time_law(engine) + time_tables(program):
                    print(json.dumps(dict(study=name, law=spec.name, **row)), flush=True)
                release_compiled_code()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("studies", nargs="*", default=list(SEEDS))
    parser.add_argument("--laws", type=int, default=None, help="the first N laws of each study")
    args = parser.parse_args()
    main(args.studies, args.laws)
