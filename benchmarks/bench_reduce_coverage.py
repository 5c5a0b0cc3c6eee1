"""Coverage of ``bayesfric data reduce``'s standard errors on synthetic raw logs (README, *Raw logs*).

For each AR(1) correlation rho, 30 logs of 16 plateaus (~225 rows each after settling; the
generator of ``tests/test_data_reduce.py``: ramps, a first-order torque lag, white speed noise)
are reduced with the default settings; printed: the share of segments whose true plateau torque
lies within 1.96 se of the mean, and the sd of z = (mean - truth) / se (1 when the se is right).

Run from the repository root: ``.venv/bin/python benchmarks/bench_reduce_coverage.py``.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bayesfric.datasets.reduce import reduce_log  # noqa: E402
from tests.test_data_reduce import raw_log  # noqa: E402


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for rho in (0.0, 0.5, 0.8, 0.9):
            z = []
            for seed in range(30):
                csv, true = raw_log(Path(tmp) / f"{rho}_{seed}", seed=1000 + seed, rho=rho)
                z += [(s.mean - mu) / s.se for s, mu in zip(reduce_log(csv).segments, true, strict=True)]
            z = np.asarray(z)
            print(f"rho {rho:.1f}: {z.size} segments, within 1.96 se {np.mean(np.abs(z) < 1.96):.1%}, "
                  f"sd(z) {z.std():.2f}, mean(z) {z.mean():+.2f}")


if __name__ == "__main__":
    main()
