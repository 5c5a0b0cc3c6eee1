"""Cost of one log-density gradient, the unit of a NUTS fit's work: powers as ``**`` or through exp/log.

Usage::

    .venv/bin/python benchmarks/bench_gradient.py [--repeats 3] [--evals 20000]

A NUTS fit spends nearly all of its sampling time evaluating the gradient of the program's log
density (robot_joint/joint_tribological: ~80 000 evaluations per chain). This measures it, in
microseconds per value-and-gradient evaluation, with the evaluations chained inside one
compiled ``fori_loop`` (as the sampler chains them), in two parts:

1. **The power term alone**, on the robot_joint speeds (111 points, float64): ``(c + x)**p``,
   ``exp(p · log(c + x))`` (:func:`bayesfric.numerics.positive_power`), and ``(|q̇| / s)**p``
   against ``exp(p · (log|q̇| − log s))`` (:func:`bayesfric.numerics.power_ratio`, whose
   ``log|q̇|`` XLA folds into a constant); and with the exponent a constant 1.5: ``**``,
   exp/log, and ``positive_power`` (``sqrt(a) ** 3``).
2. **Every law of the seed studies**, each on its study's data, noise model and priors, at the
   first chain's prior-median start, in two child processes: one with ``bayesfric.numerics`` as
   shipped, one with its two functions replaced by the ``a ** p`` formulation they replaced
   (``jnp.where(a > 0, jnp.where(a > 0, a, 1) ** p, 0)``), patched before the laws are imported.
   The children alternate, ``--repeats`` times; the median per law is reported.

Writes ``reports/benchmarks/bench_gradient.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT_JSON = REPO / "reports" / "benchmarks" / "bench_gradient.json"
FORMULATIONS = ("exp_log", "pow")


def _per_eval_us(value_and_grad, x0, evals: int) -> float:
    """Microseconds per evaluation of ``value_and_grad`` chained ``evals`` times in one compiled loop."""
    import jax

    @jax.jit
    def chain(x):
        def body(_, carry):
            x, total = carry
            value, grad = value_and_grad(x)
            return x + 1e-12 * grad, total + value  # depends on the result: nothing is skipped

        return jax.lax.fori_loop(0, evals, body, (x, 0.0))

    jax.block_until_ready(chain(x0))
    start = time.perf_counter()
    jax.block_until_ready(chain(x0))
    return (time.perf_counter() - start) / evals * 1e6


def _patch_pow() -> None:
    """Replace bayesfric.numerics' functions by the ``**`` formulation (before the laws import them)."""
    import jax.numpy as jnp

    import bayesfric.numerics as numerics

    def positive_power(a, p):
        positive = a > 0
        return jnp.where(positive, jnp.where(positive, a, 1.0) ** p, 0.0)

    numerics.positive_power = positive_power
    numerics.power_ratio = lambda x, scale, p: positive_power(x / scale, p)


def _laws_child(formulation: str, evals: int) -> dict[str, float]:
    """µs per gradient of every seed-study law's log density (run in a child process)."""
    import jax
    import jax.numpy as jnp

    if formulation == "pow":
        _patch_pow()
    from bayesfric.density import median_starts, start_seeds
    from bayesfric.model import build_program
    from bayesfric.study import STUDIES_DIR
    from bayesfric.study.config import load_study
    from bayesfric.study.runner import load_study_data

    out = {}
    for path in sorted(STUDIES_DIR.glob("*.toml")):
        study = load_study(path)
        ds = load_study_data(study)
        for spec in study.laws:
            program = build_program(spec.build(), ds, priors=spec.priors, noise=study.noise,
                                    constants=spec.constants)
            density = program.density(0)
            mask = jnp.ones(program.n_obs, dtype=bool)
            data = dict(inputs=program.inputs, group_index=program.group_index, response=program.response)
            x0 = median_starts(program, start_seeds(0, 1))[0]
            grad = jax.value_and_grad(lambda x, d=density, m=mask, dd=data: d.log_joint(x, m, dd))
            out[f"{study.name}/{spec.name}"] = _per_eval_us(grad, x0, evals)
    return out


def _power_terms(evals: int) -> dict[str, float]:
    """µs per value-and-gradient of one power term over the robot_joint speeds."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from bayesfric.datasets import load_dataset, resolve
    from bayesfric.numerics import positive_power, power_ratio

    speed = jnp.asarray(np.abs(load_dataset(resolve("robot_joint"))["velocity"].values))
    x0 = jnp.array([0.1, 0.8])  # (shift or log scale, exponent)
    terms = {
        "(c + x)**p": lambda x: jnp.sum((speed + jnp.exp(x[0])) ** x[1]),
        "positive_power(c + x, p)": lambda x: jnp.sum(positive_power(speed + jnp.exp(x[0]), x[1])),
        "(|v| / s)**p": lambda x: jnp.sum((speed / jnp.exp(x[0])) ** x[1]),
        "power_ratio(|v|, s, p)": lambda x: jnp.sum(power_ratio(speed, jnp.exp(x[0]), x[1])),
        # an exponent fixed at trace time, a multiple of 1/2: sqrt and multiplications
        "(c + x)**1.5": lambda x: jnp.sum((speed + jnp.exp(x[0])) ** 1.5),
        "exp(1.5 log(c + x))": lambda x: jnp.sum(jnp.exp(1.5 * jnp.log(speed + jnp.exp(x[0])))),
        "positive_power(c + x, 1.5)": lambda x: jnp.sum(positive_power(speed + jnp.exp(x[0]), 1.5)),
    }
    return {name: _per_eval_us(jax.value_and_grad(fn), x0, evals) for name, fn in terms.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="child runs per formulation, alternating")
    parser.add_argument("--evals", type=int, default=20000, help="chained evaluations per timing")
    parser.add_argument("--child", choices=FORMULATIONS, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(_laws_child(args.child, args.evals)))
        return
    import jax

    jax.config.update("jax_enable_x64", True)
    terms = _power_terms(args.evals)
    runs: dict[str, list[dict[str, float]]] = {f: [] for f in FORMULATIONS}
    for _ in range(args.repeats):
        for formulation in FORMULATIONS:
            child = subprocess.run([sys.executable, __file__, "--child", formulation, "--evals", str(args.evals)],
                                   check=True, capture_output=True, text=True, cwd=REPO)
            runs[formulation].append(json.loads(child.stdout.strip().splitlines()[-1]))
    laws = {law: {f: statistics.median(r[law] for r in runs[f]) for f in FORMULATIONS} for law in runs["pow"][0]}
    print("power term, 111 robot_joint speeds: µs per value and gradient")
    for name, us in terms.items():
        print(f"  {name:28s} {us:7.2f}")
    print(f"\nlaw log density: µs per value and gradient (median of {args.repeats})")
    print(f"  {'study/law':48s} {'a ** p':>8s} {'exp/log':>8s} {'ratio':>6s}")
    for law, us in laws.items():
        print(f"  {law:48s} {us['pow']:8.2f} {us['exp_log']:8.2f} {us['exp_log'] / us['pow']:6.2f}")
    OUT_JSON.parent.mkdir(parents=True, exist_ok=True)
    OUT_JSON.write_text(json.dumps({"evals": args.evals, "repeats": args.repeats, "power_terms_us": terms,
                                    "laws_us": laws, "runs": runs}, indent=1))
    print(f"\nwritten {OUT_JSON.relative_to(REPO)}")


if __name__ == "__main__":
    main()
