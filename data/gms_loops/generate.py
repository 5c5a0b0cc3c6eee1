"""Generate *simulated* pre-sliding and sliding friction of a rotary joint from a two-element GMS model
-- not measured, known truth.

Usage, from the repository root: ``PYTHONPATH=. python data/gms_loops/generate.py [OUTDIR]`` writes
``gms_loops.csv`` and ``gms_loops.toml`` (default OUTDIR: this folder). Bit-identical on every run:
numpy float64, one fixed seed, fixed text formats.

What is simulated: six runs sampled every 10 ms: a small sinusoidal pre-sliding loop (±2 mrad,
1 Hz, two cycles), a large loop into gross sliding (±20 mrad, 0.5 Hz, one cycle), and four runs at
constant speed (3, 10, 30 and 100 mrad/s, 0.3 s each) that trace the Stribeck curve: 520 rows. The
friction torque follows the Generalized Maxwell-slip model (Al-Bender, Lampaert & Swevers 2005) with
two elements (the ``gms_n2`` law of :mod:`bayesfric.laws.slip`, each run starting relaxed at the
law's default start state), with Gaussian noise of 0.01 N*m. The law is the one the study fits, so
the data test the inference and the comparison (GMS with two elements against one element and
against rate-independent Maxwell-slip), not an independent tribological model.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

NAME = "gms_loops"
SEED = 20261124
LAW = "gms_n2"
#: Ground truth (SI: N*m, N*m, rad/s, N*m*s/rad, N*m/s, 1, rad); element shares alpha = w / sum(w) = 1/3, 2/3.
TRUTH = {"F_c": 1.0, "dF_s": 0.5, "v_s": 0.01, "sigma2": 2.0, "C": 50.0, "w": [1.0, 2.0], "dx": [1e-3, 2e-3]}
SIGMA = 0.01  # N*m
STEP = 0.01  # s


def runs() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(time, angle, velocity) of each run, time from 0 within the run."""
    out = []
    for amplitude, freq, duration in ((2e-3, 1.0, 2.0), (20e-3, 0.5, 2.0)):
        t = np.arange(0.0, duration, STEP)
        w = 2 * np.pi * freq
        out.append((t, amplitude * np.sin(w * t), amplitude * w * np.cos(w * t)))
    for speed in (3e-3, 10e-3, 30e-3, 100e-3):
        t = np.arange(0.0, 0.3, STEP)
        out.append((t, speed * t, np.full_like(t, speed)))
    return out


def table() -> dict[str, np.ndarray]:
    """Columns in SI units: angle, velocity, time, run, torque."""
    from bayesfric.datasets.synthetic import simulate
    from bayesfric.laws import get_law

    parts = runs()
    run = np.concatenate([np.full(p[0].size, i + 1) for i, p in enumerate(parts)])
    inputs = {"time": np.concatenate([p[0] for p in parts]), "velocity": np.concatenate([p[2] for p in parts])}
    truth = {k: np.asarray(v) for k, v in TRUTH.items()}
    ds = simulate(get_law(LAW), inputs, truth, sigma=SIGMA, seed=SEED, groups={"run": run}, trajectory="run")
    return {"angle": np.concatenate([p[1] for p in parts]), "velocity": inputs["velocity"], "time": inputs["time"],
            "run": run, "torque": np.asarray(ds["torque"].values)}


def toml_text() -> str:
    truth = ", ".join(f"{k} = {v}" for k, v in TRUTH.items())
    source = (f"data/gms_loops/generate.py: two-element GMS model ({LAW}), pre-sliding loops of 2 and 20 mrad and "
              f"four constant speeds; truth {truth} (SI); noise sd {SIGMA:g} N*m; seed {SEED}")
    description = ("Friction torque of a rotary joint: pre-sliding loops and constant-speed runs. SIMULATED, "
                   "not measured: see data/gms_loops/README.md.")
    return f'''[dataset]
name = "{NAME}"
title = "SIMULATED pre-sliding loops and Stribeck runs from a two-element GMS model (known truth)"
provenance = "simulated"
source = "{source}"
description = "{description}"
trajectory = "run"

[columns.angle_mrad]
role = "input"
quantity = "angle"
unit = "mrad"

[columns.velocity_mrad_s]
role = "input"
quantity = "velocity"
unit = "mrad/s"

[columns.time_s]
role = "input"
quantity = "time"
unit = "s"

[columns.run]
role = "group"

[columns.torque_Nm]
role = "response"
quantity = "torque"
unit = "N*m"
'''


def main(outdir: Path) -> None:
    """Write ``gms_loops.csv`` and ``gms_loops.toml`` into ``outdir``."""
    c = table()
    lines = ["# SIMULATED from a known truth (data/gms_loops/generate.py) -- not measured data",
             "angle_mrad,velocity_mrad_s,time_s,run,torque_Nm"]
    lines += [f"{a * 1e3:.9f},{v * 1e3:.9f},{t:.4f},{r:d},{f:.8f}"
              for a, v, t, r, f in zip(c["angle"], c["velocity"], c["time"], c["run"], c["torque"], strict=True)]
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent)
