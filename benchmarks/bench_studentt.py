"""Student-t posterior predictive draws: numpyro's sampler (jax.random.gamma) against
bayesfric.studentt, side by side in one process, as a fit's tables draw them (vmap over draws).

    .venv/bin/python benchmarks/bench_studentt.py [--draws 4000] [--rows 300] [--repeats 5]

Prints compile and median run seconds of each and their ratio.
"""

from __future__ import annotations

import argparse
import statistics
import time

from bayesfric.runtime import configure

configure()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpyro.distributions as dist  # noqa: E402

from bayesfric.studentt import StudentT  # noqa: E402


def timed(law, draws: int, rows: int, repeats: int) -> tuple[float, float]:
    """(compile seconds, median run seconds) of ``draws`` vmapped draws of ``rows`` values."""
    nu, scale = jnp.linspace(3.0, 30.0, draws), jnp.ones(draws)
    fn = jax.jit(jax.vmap(lambda k, n, s: law(n, 0.0, s).sample(k, (rows,))))
    keys = jax.random.split(jax.random.PRNGKey(0), draws)
    start = time.perf_counter()
    compiled = fn.lower(keys, nu, scale).compile()
    compile_s = time.perf_counter() - start
    runs = []
    for r in range(repeats):
        keys = jax.random.split(jax.random.PRNGKey(r + 1), draws)
        start = time.perf_counter()
        compiled(keys, nu, scale).block_until_ready()
        runs.append(time.perf_counter() - start)
    return compile_s, statistics.median(runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--draws", type=int, default=4000)
    parser.add_argument("--rows", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    results = {name: timed(law, args.draws, args.rows, args.repeats)
               for name, law in (("numpyro", dist.StudentT), ("bayesfric", StudentT))}
    for name, (compile_s, run_s) in results.items():
        print(f"{name:10s} compile {compile_s:6.2f} s  run {run_s:6.3f} s")
    print(f"run ratio bayesfric/numpyro: {results['bayesfric'][1] / results['numpyro'][1]:.3f}")


if __name__ == "__main__":
    main()
