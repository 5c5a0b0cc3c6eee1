"""The evidence pair against the fit it checks, per law of the shipped studies, side by side.

Usage: .venv/bin/python benchmarks/bench_evidence.py [--studies robot_joint dahl_duplex ...] [--laws a b]
       [--smc]

For every law of each named study (the study's data, selection, priors and noise): one full NUTS
fit with the study's sampler settings and the law's own mass matrix, then bridge sampling on its
draws, then importance sampling from the Laplace-t proposal (independent of the draws),
optionally tempered SMC (the opt-in reference). Prints wall times, the ratio of each estimator
to the fit, the estimates with their errors and whether the pair agrees.
Writes ``reports/benchmarks/bench_evidence.json``.
Target (engine issue): bridge + importance ≤ 1.0 × the fit on every shipped law.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from bayesfric import compare
from bayesfric.datasets import load_dataset, resolve, select
from bayesfric.inference import SAMPLERS, release_compiled_code
from bayesfric.model import build_program
from bayesfric.study import STUDIES_DIR, load_study


def _timed(fn, *args, **kwargs):
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def bench_study(name: str, laws: list[str] | None, smc: bool) -> list[dict]:
    study = load_study(STUDIES_DIR / f"{name}.toml")
    ds = select(load_dataset(resolve(study.dataset)), study.select)
    config = study.sampler_config.replace(seed=0)
    rows = []
    for spec in study.laws:
        if laws and spec.name not in laws:
            continue
        program = build_program(spec.build(), ds, priors=spec.priors, noise=study.noise,
                                constants=spec.constants)
        dt, t_fit = _timed(SAMPLERS["nuts"], program, ds, spec.config(config))
        bridge, t_bridge = _timed(compare.bridge_log_evidence, program, dt, seed=0)
        importance, t_is = _timed(compare.laplace_is_log_evidence, program, seed=0)
        row = {"study": name, "law": spec.name, "fit_s": t_fit, "bridge_s": t_bridge, "is_s": t_is,
               "pair_ratio": (t_bridge + t_is) / t_fit, "bridge": bridge.log_z, "bridge_se": bridge.error,
               "is": importance.log_z, "is_se": importance.error,
               "is_pareto_k": importance.diagnostics["pareto_k"],
               "agree": compare.compare_estimators(bridge, importance).agree,
               "fit_passed": compare.verdict_of(dt).passed}
        if smc:
            reference, t_smc = _timed(compare.smc_log_evidence, program, seed=0, particles=300, runs=3)
            row |= {"smc_s": t_smc, "smc_ratio": t_smc / t_fit, "smc": reference.log_z, "smc_se": reference.error}
        print(f"{name:>14} {spec.name:<28} fit {t_fit:6.1f} s  bridge {t_bridge:5.1f} s  IS {t_is:5.1f} s  "
              f"pair/fit {row['pair_ratio']:.2f}  logZ bridge {bridge.log_z:.3f}±{bridge.error:.3f}  "
              f"IS {importance.log_z:.3f}±{importance.error:.3f} (k̂ {row['is_pareto_k']:.2f})  "
              + (f"SMC {row['smc']:.3f}±{row['smc_se']:.3f} ({row['smc_ratio']:.1f}× fit)" if smc else ""),
              flush=True)
        rows.append(row)
        release_compiled_code()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--studies", nargs="+", default=["robot_joint", "dahl_duplex", "drum_rollout",
                                                         "unwinder", "pitch_bearing"])
    parser.add_argument("--laws", nargs="*", help="only these laws")
    parser.add_argument("--smc", action="store_true", help="also time tempered SMC (300 particles × 3 runs)")
    args = parser.parse_args()
    rows = [row for name in args.studies for row in bench_study(name, args.laws, args.smc)]
    worst = max(rows, key=lambda r: r["pair_ratio"])
    print(f"\nworst bridge + IS over fit: {worst['pair_ratio']:.2f} ({worst['study']} / {worst['law']}); "
          f"pairs agreeing: {sum(r['agree'] for r in rows)}/{len(rows)}")
    out = Path("reports/benchmarks/bench_evidence.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
