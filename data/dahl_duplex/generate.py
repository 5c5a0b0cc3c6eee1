"""Generate the RECONSTRUCTED Dahl (1977) duplex-pair hysteresis loops (not measured data).

Usage::

    python data/dahl_duplex/generate.py [OUTDIR]

writes ``dahl_duplex.csv`` and ``dahl_duplex.toml`` into OUTDIR (default: this folder). The output
is bit-identical on every run: numpy float64, one fixed ``np.random.default_rng`` seed, fixed text
formats. Every number below is either a fact of the report (SAMSO-TR-77-132, cited by section,
figure or table) or an assumption justified in ``README.md``.

Truth (richer than the Dahl laws with one exponent i): per loop a Dahl solid-friction state
``dT/dθ = σ_d (1 - T/T_c,d · d)^i · d`` integrated exactly over every 0.011° quantum of the drive,
with an exponent that varies with preload around 1.5, running levels that differ slightly between
the two directions, a small rate-proportional (viscous-like) torque, a per-loop meter offset and
gain error, angle-periodic torque waviness for the worn bearings, Gaussian meter noise and the
0.001 in·oz reading resolution.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

NAME = "dahl_duplex"
SEED = 19770310  # report date, 10 March 1977

# -- facts of the report ---------------------------------------------------------------------
PRELOADS_LBF = (6, 12, 18, 24, 30, 36)  # §III Bearing Test Fixture / Fig. 12
CONDITIONS = ("new", "worn")  # §III: worn ("old") set of Fig. 10, new set of Fig. 11
DRIVE_RANGE_DEG = 11.25  # Table I, range used (§III Drive Servo)
QUANTUM_DEG = 2.0 * DRIVE_RANGE_DEG / 2048  # Table I lists 0.0110 deg (2048 levels on ±11.25°)
DRIVE_FREQUENCY_HZ = 0.05  # §III Drive Servo: triangular waveform at 0.05 Hz
RESOLUTION_IN_OZ = 0.001  # §III Torque Meter: threshold below 0.001 in·oz
METER_FULL_SCALE_IN_OZ = 20.0  # §III Torque Meter: used on the 0–20 in·oz scale
PLOT_DEG_PER_IN = 0.563  # Fig. 11 x-axis scale (OCR), deg per graph inch
PLOT_IN_OZ_PER_IN = 0.356  # Fig. 11 torque-axis scale (OCR reading), in·oz per graph inch
PLOT_LOOP_HEIGHT_IN = 7.0  # Fig. 11: the 24 lb loop spans about 7 graph inches of torque

# -- assumptions (README §2) -------------------------------------------------------------------
AMPLITUDE_DEG = round(2.53 / QUANTUM_DEG) * QUANTUM_DEG  # Fig. 11: x' spans ~9 in x 0.563 deg/in
RATE_DEG_S = 4.0 * AMPLITUDE_DEG * DRIVE_FREQUENCY_HZ  # triangle: 2 sweeps of 2A per period
POINTS_PER_HALF_CYCLE = 13  # digitised points per reversal-to-reversal branch
HALF_CYCLES = 3  # 1.5 cycles, starting at the -A extreme
KNEE_DEG = 0.22  # x_c = F_c/σ; σ ≈ 1/10 of the meter's 0.28 ft·lbf/deg (§III Torque Meter)
KNEE_SCATTER = 0.03  # relative loop-to-loop scatter of x_c
EXPONENT_MEAN, EXPONENT_SCATTER = 1.5, 0.06  # §V: i about constant, average about 1.5
DIRECTION_ASYMMETRY = 0.02  # T_c,+ = T_c (1 + a), T_c,- = T_c (1 - a)
VISCOUS_IN_OZ_PER_DEG_S = 0.03  # small rate-proportional torque (§III: rates kept low)
OFFSET_SD_IN_OZ = 0.01  # residual of the bias-torque removal, per loop
GAIN_SD = 0.005  # per-loop gain error (well inside the ±2 % FS bound)
NOISE_SD_IN_OZ = 0.006  # random meter/plot-reading noise per point
WORN_FACTOR = (1.05, 0.90, 0.84, 0.80, 0.79, 0.80)  # worn/new running level per preload (Fig. 12)
WAVINESS_RANGE = (0.05, 0.15)  # §V: old-bearing wave peaks 5 to 15 % above the average level
WAVELENGTHS_DEG = (0.83, 0.31)  # angle periods of the waviness (assumed)


def running_level_new(preload_lbf: np.ndarray) -> np.ndarray:
    """Running (Coulomb) torque T_c of the new pair in in·oz: linear rise plus the 36 lb jump.

    Approximate reconstruction of Fig. 12 anchored at T_c(24 lb) ≈ 1.2 in·oz from Fig. 11 (the
    loop spans about 7 graph inches of 0.356 in·oz, i.e. 2 T_c ≈ 2.4–2.5 in·oz).
    """
    p = np.asarray(preload_lbf, dtype=float)
    heavy_jump = 0.45 / (1.0 + np.exp(-(p - 34.0) / 0.75))
    return 0.33 + 0.036 * p + heavy_jump


def dahl_branch(state: float, travel_deg: np.ndarray, direction: int, level_pos: float,
                level_neg: float, knee_deg: float, exponent: float) -> np.ndarray:
    """Exact Dahl state after each cumulative ``travel_deg`` from ``state`` in one direction.

    Solves ``du/dx = -u^i / x_c`` with ``u = 1 - d T / T_c,d`` in closed form (report Eq. 3–5).
    """
    level = level_pos if direction > 0 else level_neg
    u0 = 1.0 - direction * state / level
    if abs(exponent - 1.0) < 1e-12:
        u = u0 * np.exp(-travel_deg / knee_deg)
    else:
        u = (u0 ** (1.0 - exponent) + (exponent - 1.0) * travel_deg / knee_deg) ** (
            -1.0 / (exponent - 1.0))
    return direction * level * (1.0 - u)


def drive_path() -> tuple[np.ndarray, np.ndarray]:
    """Quantised triangular drive: angles (deg) of every quantum step and the step direction."""
    steps = int(round(2 * AMPLITUDE_DEG / QUANTUM_DEG))
    angles = [np.array([-AMPLITUDE_DEG])]
    directions = [np.array([1])]
    for half in range(HALF_CYCLES):
        d = 1 if half % 2 == 0 else -1
        k = np.arange(1, steps + 1)
        angles.append(-d * AMPLITUDE_DEG + d * k * QUANTUM_DEG)
        directions.append(np.full(steps, d))
    return np.concatenate(angles), np.concatenate(directions)


def simulate_loop(rng: np.random.Generator, level: float, exponent: float, waviness: float):
    """One 1.5-cycle trajectory on the full quantised drive: (angle, time, torque, branch)."""
    angle, direction = drive_path()
    knee = KNEE_DEG * (1.0 + KNEE_SCATTER * rng.standard_normal())
    level_pos, level_neg = level * (1 + DIRECTION_ASYMMETRY), level * (1 - DIRECTION_ASYMMETRY)
    steps = int(round(2 * AMPLITUDE_DEG / QUANTUM_DEG))
    travel = np.arange(1, steps + 1) * QUANTUM_DEG
    # one full settling cycle from the negative running level, then the recorded 1.5 cycles
    state = -level_neg
    for d in (1, -1):
        state = dahl_branch(state, travel, d, level_pos, level_neg, knee, exponent)[-1]
    friction = [np.array([state])]
    for half in range(HALF_CYCLES):
        d = 1 if half % 2 == 0 else -1
        branch = dahl_branch(state, travel, d, level_pos, level_neg, knee, exponent)
        friction.append(branch)
        state = branch[-1]
    friction = np.concatenate(friction)
    rate_deg_s = RATE_DEG_S
    time = np.arange(angle.size) * QUANTUM_DEG / rate_deg_s
    phases = rng.uniform(0.0, 2.0 * np.pi, 2)
    ripple = (0.6 * np.sin(2 * np.pi * angle / WAVELENGTHS_DEG[0] + phases[0])
              + 0.4 * np.sin(2 * np.pi * angle / WAVELENGTHS_DEG[1] + phases[1]))
    torque = friction + VISCOUS_IN_OZ_PER_DEG_S * rate_deg_s * direction + waviness * level * ripple
    gain = 1.0 + GAIN_SD * rng.standard_normal()
    torque = torque * gain + OFFSET_SD_IN_OZ * rng.standard_normal()
    branch_index = np.concatenate([[-1], np.repeat(np.arange(HALF_CYCLES), steps)])
    return angle, time, torque, friction, branch_index


def digitise(angle: np.ndarray, clean: np.ndarray, branch: np.ndarray, level: float) -> np.ndarray:
    """Indices of points equally spaced in arc length along each branch of the plotted trace.

    Mimics reading a trace off an x-y plot like Fig. 11: 0.563 deg per graph inch, and a torque
    scale chosen so that the loop (2 T_c) spans about 7 graph inches, as the 24 lb loop does at
    0.356 in·oz/in. Equal arc length puts about half of the points on the steep part after each
    reversal.
    """
    torque_per_in = 2.0 * level / PLOT_LOOP_HEIGHT_IN
    picks = [0]
    for b in range(HALF_CYCLES):
        idx = np.flatnonzero(branch == b)
        idx = np.concatenate([[idx[0] - 1], idx])  # start at the reversal point
        x, y = angle[idx] / PLOT_DEG_PER_IN, clean[idx] / torque_per_in
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
        targets = arc[-1] * np.arange(1, POINTS_PER_HALF_CYCLE + 1) / POINTS_PER_HALF_CYCLE
        chosen = idx[np.searchsorted(arc, targets - 1e-12)]
        picks.extend(int(c) for c in chosen)
    picks = np.asarray(picks)
    if np.any(np.diff(picks) <= 0):
        raise RuntimeError("digitised points are not strictly ordered")
    return picks


def direction_into(angle: np.ndarray) -> np.ndarray:
    """Sign of the motion arriving at each point (the first point: of the motion leaving it)."""
    step = np.sign(np.diff(angle))
    return np.concatenate([step[:1], step])


def build_rows() -> list[tuple]:
    """All rows of the table, ordered by loop (condition, preload) and time."""
    rng = np.random.default_rng(SEED)
    exponents = {c: EXPONENT_MEAN + EXPONENT_SCATTER * rng.standard_normal(len(PRELOADS_LBF))
                 for c in CONDITIONS}
    rows = []
    for condition in CONDITIONS:
        for k, preload in enumerate(PRELOADS_LBF):
            level = float(running_level_new(preload))
            waviness = 0.0
            if condition == "worn":
                level *= WORN_FACTOR[k]
                waviness = rng.uniform(*WAVINESS_RANGE)
            level *= 1.0 + 0.02 * rng.standard_normal()  # loop-to-loop level scatter
            angle, time, torque, clean, branch = simulate_loop(
                rng, level, float(exponents[condition][k]), waviness)
            keep = digitise(angle, clean, branch, level)
            noisy = torque[keep] + NOISE_SD_IN_OZ * rng.standard_normal(keep.size)
            reading = np.round(noisy / RESOLUTION_IN_OZ) * RESOLUTION_IN_OZ
            loop = f"{condition}_{preload:02d}lbf"
            rate = RATE_DEG_S * direction_into(angle[keep])
            for j in range(keep.size):
                rows.append((loop, condition, preload, time[keep[j]], angle[keep[j]], rate[j],
                             reading[j]))
    return rows


CSV_HEADER = "loop,condition,preload,time,drive_angle,drive_rate,torque"
DATASET_META = {
    "name": NAME,
    "title": (
        "Torque-angle hysteresis loops of a duplex ball-bearing pair at 6-36 lb preload, new and"
        " worn (reconstructed from Dahl 1977, Measurement of solid friction parameters of ball"
        " bearings)"
    ),
    "provenance": "reconstructed",
    "source": (
        "P. R. Dahl, Measurement of Solid Friction Parameters of Ball Bearings, SAMSO-TR-77-132,"
        " The Aerospace Corporation, 1977: Sec. III (test fixture, torque meter, drive servo),"
        " Sec. IV-V, Fig. 10-12, Table I, Eq. 3-8. Not read off the figures point by point:"
        " reconstructed, see data/dahl_duplex/README.md"
    ),
    "description": (
        "RECONSTRUCTED, not measured. Per preload (6-36 lbf) and condition (new/worn) 1.5 cycles"
        " of the quantised triangular drive (0.05 Hz, +-2.53 deg), 40 digitised points each, in"
        " the report's units (deg, in*ozf, lbf). Truth: Dahl solid-friction state with a"
        " preload-dependent exponent around 1.5, direction asymmetry, a small viscous-like term,"
        " meter offset/gain/noise and 0.001 in*oz resolution, angle-periodic waviness (worn)."
    ),
    "trajectory": "loop",
}
COLUMNS = {
    "loop": {"role": "group"},
    "condition": {"role": "group"},
    "preload": {"role": "input", "quantity": "preload", "unit": "lbf", "group": True},
    "time": {"role": "input", "quantity": "time", "unit": "s"},
    "drive_angle": {"role": "input", "quantity": "angle", "unit": "deg"},
    "drive_rate": {"role": "input", "quantity": "velocity", "unit": "deg/s"},
    "torque": {"role": "response", "quantity": "torque", "unit": "in*ozf"},
}


def toml_text() -> str:
    """The sidecar text (deterministic; strings are ASCII, quoted as TOML basic strings)."""

    def value(v) -> str:
        return "true" if v is True else json.dumps(v)

    lines = ["[dataset]"] + [f"{k} = {value(v)}" for k, v in DATASET_META.items()]
    for col, spec in COLUMNS.items():
        lines += ["", f"[columns.{col}]"] + [f"{k} = {value(v)}" for k, v in spec.items()]
    return "\n".join(lines) + "\n"


def write(outdir: Path) -> None:
    """Write ``dahl_duplex.csv`` and ``dahl_duplex.toml`` into ``outdir``."""
    outdir.mkdir(parents=True, exist_ok=True)
    lines = [
        "# RECONSTRUCTED from Dahl 1977 (SAMSO-TR-77-132) - not measured data; "
        "see data/dahl_duplex/README.md",
        CSV_HEADER,
    ]
    for loop, condition, preload, time, angle, rate, torque in build_rows():
        lines.append(
            f"{loop},{condition},{preload:d},{time:.4f},{angle:.6f},{rate:.6f},{torque:.3f}")
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    write(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
