"""Print the derived numbers quoted in README §4 (per-loop Dahl fits on the shipped file).

Usage: ``python data/dahl_duplex/summary.py``. The fits are the ones the tests check
(``tests/datasets/test_dahl_duplex.py``, loaded by path so there is one copy of them).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from bayesfric.datasets import load_builtin

TESTS = Path(__file__).resolve().parents[2] / "tests" / "datasets" / "test_dahl_duplex.py"


def main() -> None:
    """Per loop: running level, free-exponent fit, waviness, RSS of the i = 1, 1.5, 2 fits."""
    spec = importlib.util.spec_from_file_location("dahl_fits", TESTS)
    fits = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fits)
    ds = load_builtin("dahl_duplex")
    print("loop        F_c[in*oz]  i_free  x_c[deg]  wave/F_c  RSS(i=1, 1.5, 2) with F_c fixed")
    for condition in ("new", "worn"):
        for preload in fits.PRELOADS_LBF:
            angle, torque = fits._loop(ds, condition, preload)
            level, centre = fits._asymptotes(angle, torque)
            free, resid = fits._fit(angle, torque)
            rss = [np.sum(fits._fit(angle, torque, exponent=i, level=level, centre=centre)[1] ** 2)
                   for i in (1.0, 1.5, 2.0)]
            print(f"{condition}_{preload:02d}lbf  {level:10.3f}  {free['exponent']:6.2f}"
                  f"  {free['knee']:8.3f}  {np.abs(resid).max() / free['level']:8.3f}  "
                  + "  ".join(f"{r:.4f}" for r in rss))


if __name__ == "__main__":
    main()
