"""The small SIMULATED bench data set several tests write: coulomb_viscous truth (T_C = 5 N·m,
c_v = 2 N·m·s/rad, σ = 0.2 N·m, seed 5) at given speeds, as ``bench.csv`` with its sidecar."""

from __future__ import annotations

from pathlib import Path

import numpy as np

SIDECAR = ('[dataset]\nname = "bench"\nprovenance = "simulated"\nsource = "test"\n'
           '[columns.speed]\nrole = "input"\nquantity = "velocity"\nunit = "rad/s"\n'
           '[columns.torque]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n')


def write_bench(folder: Path, v: np.ndarray, *, series: bool = False) -> Path:
    """Write ``folder/bench.csv`` (speed, torque and, with ``series``, a group column alternating
    0/1) and ``folder/bench.toml``; return the CSV's path."""
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.laws import get_law

    ds = simulate(get_law("coulomb_viscous"), {"velocity": v}, {"T_C": 5.0, "c_v": 2.0}, sigma=0.2, seed=5)
    pairs = zip(v, ds["torque"].values, strict=True)
    if series:
        rows = ["speed,torque,series"] + [f"{a:.10g},{b:.10g},{i % 2}" for i, (a, b) in enumerate(pairs)]
    else:
        rows = ["speed,torque"] + [f"{a:.10g},{b:.10g}" for a, b in pairs]
    path = Path(folder) / "bench.csv"
    path.write_text("\n".join(rows) + "\n")
    (Path(folder) / "bench.toml").write_text(SIDECAR + ('[columns.series]\nrole = "group"\n' if series else ""))
    return path
