"""Print the derived numbers quoted in README §4 (calibration and the paper's statements).

Usage: ``python data/pitch_bearing/summary.py``.
"""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> None:
    """Print the derived targets, the truth coefficients and the statements on the shipped file."""
    spec = importlib.util.spec_from_file_location("pitch_generate", HERE / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    from bayesfric.laws.ball_loads import PITCH_BEARING

    k = gen.load_slope_knm_per_mnm()
    print("targets in units of k:", {key: f"{v} = {float(v):.4f}" for key, v in
                                      gen.derived_targets().items()})
    print(f"k = 2.2 mu / 1.15 = {k:.4f} kN*m per MN*m;  T(0) = {5 / 3 * k:.3f},"
          f" T(2) = {46 / 13 * k:.3f}, T(6) = {23 / 3 * k:.3f} kN*m")
    coef = gen.truth_coefficients()
    p1, s43 = gen.ball_load_sums()
    print(f"P1(M) [MN] = {[round(float(x) / 1e6, 4) for x in p1]}")
    print(f"seal torque {coef['seal']:.3f} kN*m; c_P1 = {coef['c_p1']:.4e} kN*m/N"
          f" (mu_s = {coef['c_p1'] * 1e3 / (PITCH_BEARING.pitch_diameter / 2):.5f});"
          f" c_S43 = {coef['c_s43']:.4e} kN*m/N^(4/3)")
    print(f"at 6 MNm: P1 term {coef['c_p1'] * p1[6]:.2f}, Sum Q^(4/3) term"
          f" {coef['c_s43'] * s43[6]:.2f} kN*m")
    with (HERE / "pitch_bearing.csv").open() as fh:
        rows = [(int(r["bending_moment"]), float(r["pitch_speed"]), r["blade"],
                 int(r["repetition"]), float(r["torque"]))
                for r in csv.DictReader(line for line in fh if not line.startswith("#"))]
    print("shipped file:", {key: round(v, 4) for key, v in gen.paper_statements(rows).items()})
    differences = [round(float(x), 4) for x in gen.speed_differences(rows)]
    print("speed differences 1.04 vs 0.5 rpm:", differences)
    means = gen.speed_averaged_means(rows)
    print("speed-averaged means [kN*m]:", {m: round(v, 3) for m, v in means.items()})


if __name__ == "__main__":
    main()
