"""Generate the *reconstructed* drum-motor roll-out (coast-down) tests (seed 003) -- not measured.

Usage: ``python data/drum_rollout/generate.py [OUTDIR]`` writes ``drum_rollout.csv`` and
``drum_rollout.toml`` (default OUTDIR: this folder). Bit-identical on every run: numpy float64,
fixed-step RK4, one fixed seed, fixed text formats.

What is simulated (README.md gives sources and reasons): a return pulley is spun up to a speed,
released at t = 0 and coasts down, ``J dω/dt = -τ(ω, θ)``, in two set-ups (Sec. 4): bearings
only, and bearings plus the two O-rings. The friction truth is a sum of mechanisms, richer than
the candidate laws (constant/Coulomb, Coulomb + viscous, O-ring ``k·ω + τ0`` of Eq. 6):

* bearing torque with a slight, saturating speed dependence (0.2-0.3 N·m, Fig. 7);
* a once-per-revolution ripple (load-zone/eccentricity of the shell on its bearings, cf. the
  ball-position ripple of Sec. 3.1 and Fig. 10) with a random phase per run;
* windage of the shell, quadratic in speed;
* O-ring torque with a weak non-linearity: a constant, a slightly sub-linear speed term and a
  breakaway rise of the elastomer contact at very low speed (Fig. 8: "non-linear");
* the pulley stays at rest once it stops (static friction holds; there is no drive torque).

The velocity is what an incremental encoder (8192 counts/rev after quadrature) gives as the
count difference over a 10 ms window, sampled on a 1 kHz clock and subsampled to a modest
number of rows per run (README.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from bayesfric.laws.drum import DRUM_INERTIA  # the one inertia shared with the coast-down laws

NAME = "drum_rollout"
SEED = 30030  # seed 003
PAPER = "Modeling a drum motor for illustrating wearout phenomena"
SHORT = "Modeling a drum motor for illustrating wearout phenomena (seed 003)"

RPM = 2.0 * np.pi / 60.0

# -- runs: (set-up, nominal release speed in rpm) -------------------------------------------------
SETUPS = ("bearings_only", "bearings_orings")
RELEASE_RPM = (400.0, 800.0, 1200.0)

# -- friction truth (N*m; omega in rad/s, theta in rad) -----------------------------------------
BEARING_STATIC = 0.21  # bearing torque at vanishing speed
BEARING_RISE = 0.06  # saturating rise with speed (lubricant drag in the rolling contacts)
BEARING_RISE_SPEED = 40.0  # rad/s
RIPPLE = 0.012  # once-per-revolution amplitude
WINDAGE = 8.0e-7  # N*m*s^2/rad^2, 0.013 N*m at 1200 rpm
ORING_CONSTANT = 0.72  # both O-rings, contact-pressure (Coulomb-like) share
ORING_SPEED_COEFF = 1.1e-3  # N*m at 1 rad/s of the speed term ...
ORING_SPEED_POWER = 0.85  # ... which grows slightly sub-linearly with speed
ORING_BREAKAWAY = 0.05  # extra elastomer friction at very low speed
ORING_BREAKAWAY_SPEED = 4.0  # rad/s

# -- integration, encoder, subsampling ------------------------------------------------------------
DT = 1.0e-3  # s, RK4 step = encoder sampling clock (1 kHz)
COUNTS_PER_REV = 8192
VELOCITY_WINDOW = 10  # samples (10 ms) of the count-difference velocity estimate
ROWS_PER_RUN = 48
TAIL = 1.06  # observe until 6 % past the stop, so every run shows the pulley at rest


def friction_torque(omega: np.ndarray, theta: np.ndarray, orings: np.ndarray,
                    phase: np.ndarray) -> np.ndarray:
    """Friction torque (N*m) retarding the pulley at ``omega`` >= 0, shaft angle ``theta``."""
    bearing = BEARING_STATIC + BEARING_RISE * (1.0 - np.exp(-omega / BEARING_RISE_SPEED))
    ripple = RIPPLE * np.sin(theta + phase)
    windage = WINDAGE * omega**2
    oring = (
        ORING_CONSTANT
        + ORING_SPEED_COEFF * omega**ORING_SPEED_POWER
        + ORING_BREAKAWAY * np.exp(-omega / ORING_BREAKAWAY_SPEED)
    )
    return bearing + ripple + windage + np.where(orings, oring, 0.0)


def coast_down(omega0: np.ndarray, orings: np.ndarray, phase: np.ndarray,
               n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """RK4 integration of all runs at once; returns angle and speed on the 1 kHz clock."""
    theta = np.zeros((n_steps + 1, omega0.size))
    omega = np.zeros((n_steps + 1, omega0.size))
    omega[0] = omega0

    def rhs(th, om):
        om = np.maximum(om, 0.0)
        return om, -friction_torque(om, th, orings, phase) / DRUM_INERTIA

    for k in range(n_steps):
        th, om = theta[k], omega[k]
        moving = om > 0.0
        k1t, k1o = rhs(th, om)
        k2t, k2o = rhs(th + 0.5 * DT * k1t, om + 0.5 * DT * k1o)
        k3t, k3o = rhs(th + 0.5 * DT * k2t, om + 0.5 * DT * k2o)
        k4t, k4o = rhs(th + DT * k3t, om + DT * k3o)
        new_theta = th + DT / 6.0 * (k1t + 2 * k2t + 2 * k3t + k4t)
        new_omega = om + DT / 6.0 * (k1o + 2 * k2o + 2 * k3o + k4o)
        theta[k + 1] = np.where(moving, new_theta, th)
        omega[k + 1] = np.where(moving, np.maximum(new_omega, 0.0), 0.0)
    return theta, omega


def encoder_velocity(theta: np.ndarray, omega0: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Count-difference velocity (rad/s) over ``VELOCITY_WINDOW`` samples, per run (columns).

    Before release the pulley turned at ``omega0``; ``offset`` is the random encoder phase.
    """
    before = -omega0 * DT * np.arange(VELOCITY_WINDOW, 0, -1)[:, None]
    angle = np.vstack([before, theta])
    counts = np.floor(angle * COUNTS_PER_REV / (2.0 * np.pi) + offset)
    diff = counts[VELOCITY_WINDOW:] - counts[:-VELOCITY_WINDOW]
    return diff * (2.0 * np.pi / COUNTS_PER_REV) / (VELOCITY_WINDOW * DT)


TITLE = (
    "Roll-out (coast-down) tests of a return pulley, bearings only / bearings + O-rings "
    f"(reconstructed from {SHORT})"
)
SOURCE = (
    f"{PAPER}: Sec. 4 (roll-out tests, two set-ups), Fig. 7 (bearings only: 0.2-0.3 N*m), "
    "Fig. 8 and text (with O-rings: about 0.95 N*m + 0.1 N*m per 1000 rpm, non-linear), "
    "Sec. 3.2 Eq. 6"
)
DESCRIPTION = (
    "Encoder speed of a coasting return pulley against time since release, three runs per "
    f"set-up. Pulley inertia {DRUM_INERTIA:g} kg*m^2. Synthetic values from a multi-mechanism "
    "truth calibrated to the paper's reported torques; see data/drum_rollout/README.md."
)


def toml_text() -> str:
    """The sidecar read by :func:`bayesfric.datasets.load_dataset`."""
    return f'''[dataset]
name = "{NAME}"
title = "{TITLE}"
provenance = "reconstructed"
source = "{SOURCE}"
description = "{DESCRIPTION}"
trajectory = "run"

[columns.time]
role = "input"
quantity = "time"
unit = "s"

[columns.initial_velocity]
role = "input"
quantity = "initial_velocity"
unit = "rpm"

[columns.run]
role = "group"

[columns.setup]
role = "group"

[columns.velocity]
role = "response"
quantity = "velocity"
unit = "rpm"
'''


def main(outdir: Path) -> None:
    """Write ``drum_rollout.csv`` and ``drum_rollout.toml`` into ``outdir``."""
    rng = np.random.default_rng(SEED)
    runs = [(setup, rpm) for setup in SETUPS for rpm in RELEASE_RPM]
    omega0 = np.array([rpm for _, rpm in runs]) * RPM
    orings = np.array([setup == "bearings_orings" for setup, _ in runs])
    phase = rng.uniform(0.0, 2.0 * np.pi, len(runs))
    offset = rng.uniform(0.0, 1.0, len(runs))
    # longest run: bearings only from the highest speed, decelerating at >= 0.21 N*m / J
    n_steps = int(np.ceil(TAIL * omega0.max() * DRUM_INERTIA / BEARING_STATIC / DT))
    theta, omega = coast_down(omega0, orings, phase, n_steps)
    velocity = encoder_velocity(theta, omega0, offset)
    lines = [
        f"# RECONSTRUCTED from {PAPER} (seed 003) -- not measured data",
        "time,initial_velocity,run,setup,velocity",
    ]
    for j, (setup, _) in enumerate(runs):
        stop = int(np.argmax(omega[:, j] <= 0.0))
        picks = np.unique(np.round(np.linspace(0, TAIL * stop, ROWS_PER_RUN)).astype(int))
        initial_rpm = velocity[0, j] / RPM
        for k in picks:
            lines.append(
                f"{k * DT:.3f},{initial_rpm:.4f},{j + 1:d},{setup},{velocity[k, j] / RPM:.4f}"
            )
    outdir.mkdir(parents=True, exist_ok=True)
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
