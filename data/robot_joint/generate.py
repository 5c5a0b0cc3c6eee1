"""Generate the *reconstructed* Stribeck curve of Stäubli RX90 joint 1 (seed 004) -- not measured.

Usage: ``python data/robot_joint/generate.py [OUTDIR]`` writes ``robot_joint.csv`` and
``robot_joint.toml`` (default OUTDIR: this folder). Bit-identical on every run: numpy float64,
one fixed seed, fixed text formats.

What is simulated (README.md gives sources and reasons): the mean joint torque over the
constant-velocity part of trapezoidal moves at many positive joint speeds from 0.001 to 4 rad/s
(dense below 0.5 rad/s), three series after warm-up. The friction truth is a sum of mechanisms,
richer than every candidate law (Eq. 1-5, 35, 39, 41 of the paper):

* asperity (boundary) friction of the pre-stressed joint bearings, Stribeck decay
  ``T_a0 exp(-(v/v_s)^d_a)`` (Eq. 39, asperity part);
* Newtonian viscous friction of the helical gear pair with film-height power law
  ``c_v v^(1 - d_v)`` (Eq. 35, viscous part);
* limiting-shear-stress viscous friction of the pre-stressed cycloid stage and bearings,
  ``T_l (1 - exp(-v / v_l))`` (Eq. 39, viscous part);
* a small linear viscous term (lip seals);
* drift between series: the joint keeps warming, so viscous terms fall and the asperity term
  rises slightly from series 1 to 3;
* residual noise of the averages (position-dependent friction and torque ripple not fully
  averaged out, current-sensor noise).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

NAME = "robot_joint"
SEED = 40040  # seed 004
PAPER = "Velocity dependence of joint friction in robotic manipulators with gear transmissions"
SHORT = "Velocity dependence of joint friction in robotic manipulators (seed 004)"

#: Assumed maximum torque of RX90 joint 1 (N*m) used to turn the paper's normalised torque into
#: N*m. The paper (Sec. 2.2, Fig. 4) publishes only normalised values and no public data sheet
#: lists this number; see README.md.
MAX_JOINT_TORQUE = 250.0

#: Joint speeds (rad/s): dense below 0.5 rad/s as in Fig. 4(b), up to the ~4 rad/s of Fig. 4(a).
JOINT_SPEEDS = np.array(
    [0.001, 0.002, 0.004, 0.007, 0.01, 0.015, 0.02, 0.03, 0.04, 0.05, 0.065, 0.08, 0.1,
     0.125, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5,
     0.6, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5, 2.75, 3.0, 3.25, 3.5, 3.75, 4.0]
)  # fmt: skip
N_SERIES = 3  # Sec. 6: three series after an initial warm-up motion

# -- friction truth, normalised by MAX_JOINT_TORQUE (speed v in rad/s) ------------------------
ASPERITY_T0 = 0.040  # static asperity torque of the pre-stressed bearings
ASPERITY_V_S = 0.03  # Stribeck velocity, rad/s
ASPERITY_DELTA = 0.5  # Stribeck shape exponent
GEAR_C_V = 0.050  # helical-gear viscous torque at 1 rad/s
GEAR_POWER = 0.5  # 1 - d_v with film-height power d_v = 0.5 (Sec. 3.2.1: 0.5-0.7)
CYCLOID_T_L = 0.010  # limiting-shear viscous torque of the cycloid stage
CYCLOID_V_L = 0.15  # its speed scale, rad/s
SEAL_VISCOUS = 0.002  # linear viscous torque per rad/s of the lip seals
# -- drift between series (warm-up continues) and noise -------------------------------------
VISCOUS_DRIFT = -0.025  # relative change of the viscous terms per series
ASPERITY_DRIFT = 0.01  # relative change of the asperity term per series
NOISE_REL = 0.012  # relative noise of one averaged torque
NOISE_ABS = 0.0004  # absolute noise, fraction of the maximum torque


def friction_truth(speed: np.ndarray, series: int) -> np.ndarray:
    """Normalised friction torque of joint 1 for positive ``speed`` (rad/s) in ``series`` 1..3."""
    k = series - 1
    asperity = ASPERITY_T0 * np.exp(-((speed / ASPERITY_V_S) ** ASPERITY_DELTA))
    gear = GEAR_C_V * speed**GEAR_POWER
    cycloid = CYCLOID_T_L * (1.0 - np.exp(-speed / CYCLOID_V_L))
    seal = SEAL_VISCOUS * speed
    return (1.0 + ASPERITY_DRIFT * k) * asperity + (1.0 + VISCOUS_DRIFT * k) * (
        gear + cycloid + seal
    )


TITLE = (
    "Stribeck curve of Staeubli RX90 joint 1, three series "
    f"(reconstructed from {SHORT})"
)
SOURCE = (
    f"{PAPER}: Sec. 2.2 and Fig. 4 (trapezoidal moves, averaged torque, normalised, "
    "0-4 rad/s), Eq. 5-8 (classical fit, delta = 0.33, v_s = 0.024 rad/s), Sec. 5-6, Eq. 41 "
    "and Fig. 12 (joint law, three series after warm-up)"
)
DESCRIPTION = (
    "Mean friction torque of joint 1 over the constant-velocity part of trapezoidal moves "
    "against joint speed (positive direction only), three series. Synthetic values from a "
    "multi-mechanism truth calibrated to the paper's findings; torque in N*m assumes a joint-1 "
    f"maximum torque of {MAX_JOINT_TORQUE:g} N*m (torque_normalised is the paper's scale). "
    "See data/robot_joint/README.md."
)


def toml_text() -> str:
    """The sidecar read by :func:`bayesfric.datasets.load_dataset`."""
    return f'''[dataset]
name = "{NAME}"
title = "{TITLE}"
provenance = "reconstructed"
source = "{SOURCE}"
description = "{DESCRIPTION}"

[columns.joint_speed]
role = "input"
quantity = "velocity"
unit = "rad/s"

[columns.series]
role = "group"

[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"

[columns.torque_normalised]
role = "aux"
unit = "1"
'''


def main(outdir: Path) -> None:
    """Write ``robot_joint.csv`` and ``robot_joint.toml`` into ``outdir``."""
    rng = np.random.default_rng(SEED)
    lines = [
        f"# RECONSTRUCTED from {PAPER} (seed 004) -- not measured data",
        "joint_speed,series,torque,torque_normalised",
    ]
    for series in range(1, N_SERIES + 1):
        truth = friction_truth(JOINT_SPEEDS, series)
        noise = NOISE_REL * truth * rng.standard_normal(truth.size)
        noise += NOISE_ABS * rng.standard_normal(truth.size)
        normalised = np.round(truth + noise, 6)
        for speed, value in zip(JOINT_SPEEDS, normalised, strict=True):
            lines.append(
                f"{speed:.4g},{series:d},{value * MAX_JOINT_TORQUE:.5g},{value:.6f}"
            )
    outdir.mkdir(parents=True, exist_ok=True)
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
