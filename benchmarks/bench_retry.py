"""What the divergence retry costs: one full-fit sampling at the retry's target acceptance
against the same sampling at the study's target and against the whole fit, per law.

Run: ``.venv/bin/python benchmarks/bench_retry.py [--studies robot_joint ...]``

Per law of each study (its data, selection, priors, noise and sampler settings): one
:class:`~bayesfric.inference.engine.NutsEngine` with the retry off; ``fit`` (the whole fit:
compilation unless cached, sampling, DataTree); then, on the same compiled sampler, the all-true
mask sampled at the study's target acceptance and at the retry's (0.99), each timed. The retry
of a diverging fit or fold costs the second sampling; folds without divergences pay nothing.
Prints one JSON line per law; writes ``reports/benchmarks/bench_retry.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from bayesfric.datasets import load_dataset, resolve, select
from bayesfric.inference import release_compiled_code
from bayesfric.inference.engine import NutsEngine
from bayesfric.model import build_program
from bayesfric.study import STUDIES_DIR, load_study

OUT = Path(__file__).resolve().parents[1] / "reports" / "benchmarks" / "bench_retry.json"
RETRY_TARGET = 0.99


def _sampling(engine: NutsEngine, target: float) -> tuple[float, float, int]:
    """Seconds, mean leapfrog steps per draw and divergences of one all-true-mask run at ``target``
    (the same compiled kernel: the target is an argument of the compiled sampler)."""
    engine = dataclasses.replace(engine, config=engine.config.replace(target_accept=target))
    start = time.perf_counter()
    fits = engine.run(np.ones((1, engine.program.n_obs), dtype=bool))
    return time.perf_counter() - start, float(fits.stats["n_steps"].mean()), int(fits.stats["diverging"].sum())


def bench_study(name: str) -> list[dict]:
    """One row per law of the study."""
    study = load_study(STUDIES_DIR / f"{name}.toml")
    ds = select(load_dataset(resolve(study.dataset)), study.select)
    config = study.sampler_config.replace(retry_target_accept=None)  # each run below is one sampling
    rows = []
    for spec in study.laws:
        release_compiled_code()
        program = build_program(spec.build(), ds, priors=spec.priors, noise=study.noise, constants=spec.constants)
        engine = NutsEngine.build(program, spec.config(config))
        start = time.perf_counter()
        engine.fit(ds)
        fit_s = time.perf_counter() - start
        base = engine.target_accept
        plain_s, plain_steps, plain_div = _sampling(engine, base)
        retry_s, retry_steps, retry_div = _sampling(engine, RETRY_TARGET)
        row = dict(study=name, law=spec.name, fit_s=round(fit_s, 2), sampling_s=round(plain_s, 2),
                   retry_s=round(retry_s, 2), retry_over_sampling=round(retry_s / plain_s, 2),
                   retry_over_fit=round(retry_s / fit_s, 2), steps_per_draw=(round(plain_steps, 1),
                                                                            round(retry_steps, 1)),
                   divergences=(plain_div, retry_div))
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--studies", nargs="+", default=["robot_joint"])
    args = parser.parse_args()
    rows = [row for name in args.studies for row in bench_study(name)]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"rows": rows, "when": time.strftime("%Y-%m-%d %H:%M:%S")}, indent=1) + "\n")
    print(f"written {OUT}")


if __name__ == "__main__":
    main()
