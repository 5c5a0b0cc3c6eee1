"""Generate the *reconstructed* unwinder friction map (seed 002) -- not measured data.

Usage: ``python data/unwinder/generate.py [OUTDIR]`` writes ``unwinder.csv`` and
``unwinder.toml`` (default OUTDIR: this folder). The output is bit-identical on every run: numpy
float64, one fixed seed, fixed text formats.

What is simulated (README.md gives the sources and the reasons for every number):

* the speed profile of seed 002 Fig. 5 -- 100..1400 rpm in 100 rpm steps held 30 s, repeated
  with 6 min at 1400 rpm in between -- for two experiments, belt removed (mass 1) and belt on;
* the gearbox oil temperature from a lumped thermal model (heat capacity, loss to ambient)
  driven by the friction power of mass 1, calibrated to 19 -> 38 degC over the 9500 s profile;
* a friction "truth" that is a sum of mechanisms (so no candidate law is the truth): motor and
  seal Coulomb torque, shaft-fan windage (quadratic in speed), gear churning/viscous drag scaling
  as viscosity^m * speed^b with the viscosity of an ISO VG 220 oil from the Walther equation,
  a belt-load term on the gearbox output bearing and the roller-bearing torque of mass 2;
* drive torque-estimate fluctuations (AR(1) at the 1 s logging rate) that the 30 s steady-state
  averages only partly remove, and PT-100 noise.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

NAME = "unwinder"
SEED = 20020  # seed 002
PAPER = "Non-linear Friction Characterisation of the Unwinding Group in a Web Processing Machine"
SHORT = "Non-linear Friction Characterisation of the Unwinding Group (seed 002)"

# -- speed profile (seed 002 Sec. IV, Fig. 5) ----------------------------------------------------
SPEEDS_RPM = np.arange(100.0, 1401.0, 100.0)  # 14 steps
STEP_S = 30  # each speed held 30 s
INTERVAL_S = 360  # 6 min at 1400 rpm between staircases
PROFILE_S = 9500  # duration of the imposed profile
N_CYCLES = 12  # the most staircases that fit 9500 s: 12 * 420 + 11 * 360 = 9000 s
GEAR_RATIO = 6.51  # Sec. II (used only to place mass-2 torques at the motor shaft)
RPM = 2.0 * np.pi / 60.0

# -- lubricant: ISO VG 220 mineral gear oil (assumption), Walther equation (ASTM D341) --------
NU40, NU100 = 220.0, 19.4  # mm^2/s at 40 and 100 degC (ISO 3448 VG 220, VI ~ 95)


def walther_viscosity(temp_c: np.ndarray) -> np.ndarray:
    """Kinematic viscosity (mm^2/s) through the two anchor points, ASTM D341 form."""
    t1, t2 = 313.15, 373.15
    y1, y2 = np.log10(np.log10(NU40 + 0.7)), np.log10(np.log10(NU100 + 0.7))
    b = (y1 - y2) / (np.log10(t2) - np.log10(t1))
    a = y1 + b * np.log10(t1)
    return 10.0 ** (10.0 ** (a - b * np.log10(temp_c + 273.15))) - 0.7


# -- friction truth at the motor shaft (N*m; omega in rad/s, temperature in degC) -------------
COULOMB_MASS1 = 0.008  # motor bearings + radial shaft seals
FAN_COEFF = 1.4e-6  # motor cooling fan, N*m*s^2/rad^2 (0.03 N*m, 4.4 W at 1400 rpm)
CHURN_AT_REF = 0.86  # gear churning + tooth/bearing viscous drag at 1400 rpm and 20 degC
CHURN_VISC_POWER = 0.195  # torque ~ viscosity^m
CHURN_SPEED_POWER = 0.98  # torque ~ speed^b (slightly sub-linear: film thinning, aeration)
OMEGA_REF = 1400.0 * RPM
BELT_LOAD_TORQUE = 0.012  # extra output-bearing torque from the belt pre-tension (belt on)
# Mass 2 (roller bearings, belt meshing) referred to the motor shaft through the gear ratio:
# at the roller these are 0.163 N*m (= 0.025 * 6.51) and 0.055 N*m*s/rad (= 0.0013 * 6.51**2).
ROLLER_COULOMB = 0.025  # N*m at the motor shaft
ROLLER_VISCOUS = 0.0013  # N*m*s/rad at the motor shaft


def mass1_torque(omega: np.ndarray, temp_c: np.ndarray) -> np.ndarray:
    """Friction torque of motor + gearbox (belt removed), N*m at the motor shaft."""
    viscosity_ratio = walther_viscosity(temp_c) / walther_viscosity(np.asarray(20.0))
    churn = (
        CHURN_AT_REF
        * viscosity_ratio**CHURN_VISC_POWER
        * (omega / OMEGA_REF) ** CHURN_SPEED_POWER
    )
    return COULOMB_MASS1 + FAN_COEFF * omega**2 + churn


def mass2_torque(omega: np.ndarray) -> np.ndarray:
    """Roller-bearing and belt torque of mass 2 plus the belt load on mass 1, at the motor."""
    return BELT_LOAD_TORQUE + ROLLER_COULOMB + ROLLER_VISCOUS * omega


# -- thermal model of the gearbox oil -----------------------------------------------------------
HEAT_CAPACITY = 1.6e4  # J/K: gear unit housing, gears and about 1.5 l of oil
THERMAL_RESISTANCE = 0.318  # K/W to ambient (natural convection of a small gear unit)
AMBIENT_C = {"belt_off": 19.0, "belt_on": 19.3}  # the two experiments ran on different days

# -- measurement noise ---------------------------------------------------------------------------
TORQUE_NOISE_ABS = 0.0085  # N*m, 1 s samples of the drive's torque estimate
TORQUE_NOISE_REL = 0.013  # fraction of the torque
NOISE_CORR_S = 6.0  # correlation time of the controller fluctuations
PT100_NOISE = 0.05  # degC per 1 s sample


def speed_profile() -> tuple[np.ndarray, np.ndarray]:
    """Motor speed set-point at 1 s resolution and the step index (-1 outside the staircases)."""
    speed = np.full(PROFILE_S, SPEEDS_RPM[-1])
    step = np.full(PROFILE_S, -1)
    cycle_len = len(SPEEDS_RPM) * STEP_S + INTERVAL_S
    for cycle in range(N_CYCLES):
        for i, rpm in enumerate(SPEEDS_RPM):
            start = cycle * cycle_len + i * STEP_S
            speed[start : start + STEP_S] = rpm
            step[start : start + STEP_S] = cycle * len(SPEEDS_RPM) + i
    return speed, step


def run_experiment(setup: str, rng: np.random.Generator) -> list[tuple]:
    """Simulate one experiment and return its 30 s steady-state averages."""
    speed_rpm, step = speed_profile()
    omega = speed_rpm * RPM
    temp = np.empty(PROFILE_S)
    torque = np.empty(PROFILE_S)
    t_oil = AMBIENT_C[setup]
    for k in range(PROFILE_S):  # explicit Euler, dt = 1 s (time constant R*C ~ 5100 s)
        temp[k] = t_oil
        loss = mass1_torque(omega[k], t_oil)
        torque[k] = loss + (mass2_torque(omega[k]) if setup == "belt_on" else 0.0)
        t_oil += (loss * omega[k] - (t_oil - AMBIENT_C[setup]) / THERMAL_RESISTANCE) / HEAT_CAPACITY
    phi = np.exp(-1.0 / NOISE_CORR_S)
    white = rng.standard_normal(PROFILE_S)
    fluct = np.empty(PROFILE_S)
    fluct[0] = white[0]
    for k in range(1, PROFILE_S):
        fluct[k] = phi * fluct[k - 1] + np.sqrt(1.0 - phi**2) * white[k]
    measured_torque = torque + (TORQUE_NOISE_ABS + TORQUE_NOISE_REL * torque) * fluct
    measured_temp = temp + PT100_NOISE * rng.standard_normal(PROFILE_S)
    rows = []
    for s in range(N_CYCLES * len(SPEEDS_RPM)):
        idx = np.flatnonzero(step == s)
        rows.append(
            (
                float(speed_rpm[idx[0]]),
                float(measured_temp[idx].mean()),
                setup,
                float(measured_torque[idx].mean()),
                float(idx.mean() + 0.5),
                s // len(SPEEDS_RPM) + 1,
            )
        )
    return rows


TITLE = (
    "Unwinder friction map, belt off / belt on "
    f"(reconstructed from {SHORT})"
)
SOURCE = (
    f"{PAPER}: Sec. II (gear ratio 6.51, motor 1440 rpm), Sec. IV and Fig. 5-7 (profile, "
    "30 s averages, 19-38 degC), Sec. V and Fig. 9-13 (findings)"
)
DESCRIPTION = (
    "Steady-state friction torque at the motor shaft of a web-machine unwinder against motor "
    "speed and gearbox oil temperature; setup belt_off = mass 1 (motor + gearbox), belt_on = "
    "whole group; cycle = staircase number. Synthetic values from a multi-mechanism truth "
    "calibrated to the paper's reported findings; see data/unwinder/README.md."
)


def toml_text() -> str:
    """The sidecar read by :func:`bayesfric.datasets.load_dataset`."""
    return f'''[dataset]
name = "{NAME}"
title = "{TITLE}"
provenance = "reconstructed"
source = "{SOURCE}"
description = "{DESCRIPTION}"

[columns.motor_speed]
role = "input"
quantity = "velocity"
unit = "rpm"

[columns.oil_temperature]
role = "input"
quantity = "temperature"
unit = "degC"

[columns.setup]
role = "group"

[columns.torque]
role = "response"
quantity = "torque"
unit = "N*m"

[columns.time]
role = "aux"
quantity = "time"
unit = "s"

[columns.cycle]
role = "group"
'''


def main(outdir: Path) -> None:
    """Write ``unwinder.csv`` and ``unwinder.toml`` into ``outdir``."""
    rng = np.random.default_rng(SEED)
    rows = run_experiment("belt_off", rng) + run_experiment("belt_on", rng)
    lines = [
        f"# RECONSTRUCTED from {PAPER} (seed 002) -- not measured data",
        "motor_speed,oil_temperature,setup,torque,time,cycle",
    ]
    for speed, temp, setup, torque, time, cycle in rows:
        lines.append(f"{speed:.0f},{temp:.3f},{setup},{torque:.5f},{time:.1f},{cycle:d}")
    outdir.mkdir(parents=True, exist_ok=True)
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
