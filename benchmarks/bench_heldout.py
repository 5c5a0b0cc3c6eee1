"""Cost of keeping the held-out predictive of a blocked fold (bayesfric.compare.heldout), which
sizing needs to measure model-form error, relative to one cold fit of the same law.

Usage: ``.venv/bin/python benchmarks/bench_heldout.py`` (robot_joint, stribeck and helical_gear;
the fold is refitted with the same compiled engine, with and without the predictive).
"""

import time

from bayesfric import compare
from bayesfric.datasets.registry import load_builtin
from bayesfric.laws import get_law
from bayesfric.model import build_program


def seconds(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def main() -> None:
    ds = load_builtin("robot_joint")
    folds = compare.blocked_masks(ds, "velocity", threshold=0.5, direction="upper")
    for name in ("stribeck", "helical_gear"):
        engine = compare.RefitEngine.build(build_program(get_law(name), ds), draws=1000, tune=1000, chains=4, seed=0)
        fit = seconds(lambda engine=engine: engine.fit(ds))
        compare.cross_validate(engine, folds, seed=0)  # compiled once
        cv = seconds(lambda engine=engine: compare.cross_validate(engine, folds, seed=1))
        kept = seconds(lambda engine=engine: compare.cross_validate(engine, folds, seed=1, predictive=True))
        print(f"{name}: fit {fit:.1f} s, blocked fold {cv:.2f} s, with held-out predictive {kept:.2f} s "
              f"(+{kept - cv:.2f} s = {(kept - cv) / fit:.3f}x the fit)")


if __name__ == "__main__":
    main()
