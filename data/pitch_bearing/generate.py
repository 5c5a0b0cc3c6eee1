"""Generate the RECONSTRUCTED pitch-bearing friction torques of seed 000 (not measured data).

Usage::

    python data/pitch_bearing/generate.py [OUTDIR]

writes ``pitch_bearing.csv`` and ``pitch_bearing.toml`` into OUTDIR (default: this folder). The
output is bit-identical on every run: numpy float64, one fixed ``np.random.default_rng`` seed,
fixed text formats; the two ball-load sums taken from :mod:`bayesfric.laws.ball_loads` (JAX, x64)
are rounded to 10 significant digits before use.

Truth (richer than Palmgren, SKF, Rothe Erde, Rothe Erde + T0 and Wang): a zero-load seal/grease
torque with a small speed-proportional part (zero on average over the tested speeds), a
sliding/rolling term proportional to P1 = Σ|Q| (seed 000 Eq. 2), a Johnson deformation term
proportional to Σ Q^(4/3) (Eq. 10 with b ∝ Q^(1/3)), which bends the load curve slightly upwards,
an offset per load-speed block of 20 repetitions, a slow drift within each block, and
heavy-tailed single-measurement scatter from the oscillation-induced torque vibrations that grows
with pitch speed and with the blade's inertia. Coefficients are calibrated so that the paper's
statements hold exactly for the noise-free speed-averaged means (README §4).
"""

from __future__ import annotations

import json
import sys
from fractions import Fraction
from functools import cache
from pathlib import Path

import numpy as np

NAME = "pitch_bearing"
FIRST_SEED = 20170519  # seeds FIRST_SEED, FIRST_SEED + 1, ... are tried in order (accept())
MAX_TRIES = 200

# -- facts of seed 000 -------------------------------------------------------------------------
MOMENTS_MNM = (0, 1, 2, 3, 4, 5, 6)  # §3.2: steps of 1 MNm; 0 = tests without the blade (§2.1)
TOP_SPEED_RPM = 1.04  # §3.2: normalised to the mean at 1.04 rpm and 6 MNm
REPETITIONS = 20  # §3.2: at least 20 repetitions per load-speed combination
ROPE_ARM_M = 30.0  # §2.1: load frame centre 30 m from the blade root
RE_SLOPE_EXCESS = Fraction(115, 100)  # §3.2: Eq. 15 slope 15 % above the measured slope
RE_DEVIATION_2 = Fraction(35, 100)  # §3.2: Eq. 15 deviates 35 % from the measurement at 2 MNm
RE_DEVIATION_6 = Fraction(10, 100)  # §3.2: and 10 % at 6 MNm

# -- assumptions (README §2) -------------------------------------------------------------------
SPEEDS_RPM = (0.5, 1.04)  # 3.0 and 6.24 deg/s: ends of the Fig. 8 range, at every moment
EXTRA_SPEED_RPM = 0.75  # 4.5 deg/s, only at 5 MNm (the Fig. 8 speed sweep)
ROTHE_ERDE_MU = Fraction(4, 1000)  # Rothe Erde catalogue, ball slewing bearings (README §2)
SPEED_EFFECT = 0.03  # seal/grease torque change per relative speed change (averages to 0)
BLOCK_OFFSET_SD = 0.008  # relative offset of one block of 20 repetitions
DRIFT_SD = 0.005  # relative drift from first to last repetition of a block
VIBRATION_KNM = (1.0, 2.0)  # single-measurement scatter with blade: a + b·(n / 1.04 rpm), kN·m
VIBRATION_NO_BLADE_KNM = (0.6, 0.4)  # without blade (smaller oscillating inertia)
VIBRATION_DF = 6  # Student-t degrees of freedom of the scatter (a few large excursions)


def derived_targets() -> dict[str, Fraction]:
    """Speed-averaged mean torques at 0, 2 and 6 MNm in units of the measured load slope k.

    With RE(M) = 2.2 μ M (Eq. 15, F_A = F_R = 0) and the chord slope k = (T(6) - T(0))/6:
    RE slope = 1.15 k; T(6) = RE(6)/(1 - 0.10); T(2) = RE(2)/(1 - 0.35); T(0) = T(6) - 6k.
    """
    re6, re2 = 6 * RE_SLOPE_EXCESS, 2 * RE_SLOPE_EXCESS
    t6 = re6 / (1 - RE_DEVIATION_6)
    t2 = re2 / (1 - RE_DEVIATION_2)
    return {"T0": t6 - 6, "T2": t2, "T6": t6}


def load_slope_knm_per_mnm() -> float:
    """Measured chord slope k in kN·m per MN·m: the Eq. 15 slope 2.2 μ divided by 1.15."""
    return float(Fraction(22, 10) * ROTHE_ERDE_MU / RE_SLOPE_EXCESS * 1000)


@cache
def ball_load_sums() -> tuple[np.ndarray, np.ndarray]:
    """P1 = Σ|Q| (N) and Σ Q^(4/3) (N^(4/3)) over all contacts at every tested moment.

    Rope shear force M / 30 m acts as radial force, no axial force (README §2).
    """
    from bayesfric.runtime import configure

    configure()  # x64
    from bayesfric.laws.ball_loads import PITCH_BEARING, contact_loads, sum_ball_loads

    moment = np.asarray(MOMENTS_MNM, dtype=float) * 1e6
    radial = moment / ROPE_ARM_M
    p1 = np.asarray(sum_ball_loads(moment, 0.0, radial, PITCH_BEARING), dtype=np.float64)
    q = np.asarray(contact_loads(moment, 0.0, radial, PITCH_BEARING), dtype=np.float64)
    s43 = np.sum(q ** (4.0 / 3.0), axis=(-3, -2, -1))

    def tidy(x):
        return np.array([float(f"{v:.10g}") for v in x])

    return tidy(p1), tidy(s43)


def truth_coefficients() -> dict[str, float]:
    """Seal torque (kN·m), P1 and Σ Q^(4/3) coefficients solving the three derived targets."""
    k = load_slope_knm_per_mnm()
    targets = {key: float(v) * k for key, v in derived_targets().items()}
    p1, s43 = ball_load_sums()
    i2, i6 = MOMENTS_MNM.index(2), MOMENTS_MNM.index(6)
    matrix = np.array([[p1[i2], s43[i2]], [p1[i6], s43[i6]]])
    rhs = np.array([targets["T2"] - targets["T0"], targets["T6"] - targets["T0"]])
    c_p1, c_s43 = np.linalg.solve(matrix, rhs)
    if c_p1 <= 0 or c_s43 <= 0:
        raise RuntimeError("calibration gave a non-physical (negative) friction coefficient")
    return {"seal": targets["T0"], "c_p1": float(c_p1), "c_s43": float(c_s43)}


def cells() -> list[tuple[int, float]]:
    """(moment MNm, speed rpm) of every load-speed block, in measurement order."""
    out = []
    for m in MOMENTS_MNM:
        speeds = sorted(SPEEDS_RPM + ((EXTRA_SPEED_RPM,) if m == 5 else ()))
        out += [(m, s) for s in speeds]
    return out


def build_rows(seed: int) -> list[tuple]:
    """Rows (moment, speed, blade, repetition, torque kN·m) before normalisation."""
    rng = np.random.default_rng(seed)
    coef = truth_coefficients()
    p1, s43 = ball_load_sums()
    mean_speed = float(np.mean(SPEEDS_RPM))
    rows = []
    for m, speed in cells():
        i = MOMENTS_MNM.index(m)
        seal = coef["seal"] * (1.0 + SPEED_EFFECT * (speed - mean_speed) / mean_speed)
        truth = seal + coef["c_p1"] * p1[i] + coef["c_s43"] * s43[i]
        blade = "without" if m == 0 else "with"
        a, b = VIBRATION_NO_BLADE_KNM if m == 0 else VIBRATION_KNM
        scatter = a + b * speed / TOP_SPEED_RPM
        offset = BLOCK_OFFSET_SD * rng.standard_normal()
        drift = DRIFT_SD * rng.standard_normal()
        reps = np.arange(1, REPETITIONS + 1)
        ramp = (reps - 1) / (REPETITIONS - 1) - 0.5
        t_noise = rng.standard_t(VIBRATION_DF, REPETITIONS) * np.sqrt(
            (VIBRATION_DF - 2) / VIBRATION_DF)
        torque = truth * (1.0 + offset + drift * ramp) + scatter * t_noise
        rows += [(m, speed, blade, int(r), float(t)) for r, t in zip(reps, torque, strict=True)]
    return rows


def speed_averaged_means(rows: list[tuple]) -> dict[int, float]:
    """Per moment: the mean over speeds of the block means (Fig. 7, "averaged over speeds")."""
    blocks: dict[tuple[int, float], list[float]] = {}
    for m, speed, _, _, t in rows:
        blocks.setdefault((m, speed), []).append(t)
    return {m: float(np.mean([np.mean(v) for (mm, _), v in blocks.items() if mm == m]))
            for m in MOMENTS_MNM}


def paper_statements(rows: list[tuple]) -> dict[str, float]:
    """The seed's statements evaluated on ``rows`` as the paper did (README §4)."""
    means = speed_averaged_means(rows)
    slope = (means[6] - means[0]) / 6.0
    re_slope = float(Fraction(22, 10) * ROTHE_ERDE_MU) * 1000.0  # kN·m per MN·m, Eq. 15
    return {
        "slope_ratio": re_slope / slope,
        "deviation_2": 1.0 - 2.0 * re_slope / means[2],
        "deviation_6": 1.0 - 6.0 * re_slope / means[6],
        "zero_load_over_slope": means[0] / slope,
    }


def speed_differences(rows: list[tuple]) -> np.ndarray:
    """Per moment: relative change of the block mean from the lowest to the highest speed."""
    blocks: dict[tuple[int, float], list[float]] = {}
    for m, speed, _, _, t in rows:
        blocks.setdefault((m, speed), []).append(t)
    lo, hi = min(SPEEDS_RPM), max(SPEEDS_RPM)
    return np.array([np.mean(blocks[m, hi]) / np.mean(blocks[m, lo]) - 1.0 for m in MOMENTS_MNM])


def accept(rows: list[tuple]) -> bool:
    """Condition the random draw on the seed's reported outcome (README §3): the block at
    1.04 rpm and 6 MNm has the highest mean, the Eq. 15 comparison is within 0.02 of
    15 % / 35 % / 10 %, and the speed differences show no systematic sign (one-sample t-test
    over the seven moments, p > 0.05)."""
    from scipy.stats import ttest_1samp

    blocks: dict[tuple[int, float], list[float]] = {}
    for m, speed, _, _, t in rows:
        blocks.setdefault((m, speed), []).append(t)
    means = {key: np.mean(v) for key, v in blocks.items()}
    top = max(means, key=means.get)
    stated = paper_statements(rows)
    return (top == (MOMENTS_MNM[-1], TOP_SPEED_RPM)
            and abs(stated["slope_ratio"] - float(RE_SLOPE_EXCESS)) < 0.02
            and abs(stated["deviation_2"] - float(RE_DEVIATION_2)) < 0.02
            and abs(stated["deviation_6"] - float(RE_DEVIATION_6)) < 0.02
            and ttest_1samp(speed_differences(rows), 0.0).pvalue > 0.05)


def accepted_rows() -> tuple[int, list[tuple]]:
    """The first seed from FIRST_SEED whose draw passes :func:`accept`, and its rows."""
    for seed in range(FIRST_SEED, FIRST_SEED + MAX_TRIES):
        rows = build_rows(seed)
        if accept(rows):
            return seed, rows
    raise RuntimeError(f"no accepted draw in {MAX_TRIES} seeds")


DATASET_META = {
    "name": NAME,
    "title": (
        "Friction torque of a 3 MW-class pitch bearing vs blade-root bending moment and pitch"
        " speed (reconstructed from Friction torque of wind-turbine pitch bearings, seed 000)"
    ),
    "provenance": "reconstructed",
    "source": (
        "Friction torque of wind-turbine pitch bearings - comparison of experimental results with"
        " available models (Fraunhofer IWES test rig; seed 000): Sec. 2.1, 2.6 (Eq. 15), 3.2"
        " (Fig. 6-9). Not read off the figures: reconstructed from the text's statements, see"
        " data/pitch_bearing/README.md"
    ),
    "description": (
        "RECONSTRUCTED, not measured. 20 single measurements (mean torque over the middle 5 deg of"
        " a 10 deg oscillation) per load-speed block: bending moment 0-6 MNm (0 = without blade)"
        " at 0.5 and 1.04 rpm, plus 0.75 rpm at 5 MNm. Absolute scale from the Rothe Erde"
        " catalogue coefficient mu = 0.004; torque_normalised is divided by the mean at 1.04 rpm"
        " and 6 MNm as in the paper. Truth: seal torque + P1 term + Sum Q^(4/3) term, small speed"
        " term, block offsets, drift, heavy-tailed vibration scatter."
    ),
}
COLUMNS = {
    "bending_moment": {"role": "input", "quantity": "bending_moment", "unit": "MN*m"},
    "pitch_speed": {"role": "input", "quantity": "velocity", "unit": "rpm"},
    "blade": {"role": "group"},
    "repetition": {"role": "group"},
    "torque": {"role": "response", "quantity": "torque", "unit": "kN*m"},
    "torque_normalised": {"role": "aux", "unit": "1"},
}


def toml_text() -> str:
    """The sidecar text (deterministic; strings are ASCII, quoted as TOML basic strings)."""
    lines = ["[dataset]"] + [f"{k} = {json.dumps(v)}" for k, v in DATASET_META.items()]
    for col, spec in COLUMNS.items():
        lines += ["", f"[columns.{col}]"] + [f"{k} = {json.dumps(v)}" for k, v in spec.items()]
    return "\n".join(lines) + "\n"


def write(outdir: Path) -> None:
    """Write ``pitch_bearing.csv`` and ``pitch_bearing.toml`` into ``outdir``."""
    outdir.mkdir(parents=True, exist_ok=True)
    seed, rows = accepted_rows()
    written = [float(f"{t:.4f}") for *_, t in rows]  # kN·m to 0.1 N·m, as written
    reference = np.mean([t for (m, s, *_), t in zip(rows, written, strict=True)
                         if m == MOMENTS_MNM[-1] and s == TOP_SPEED_RPM])
    lines = [
        "# RECONSTRUCTED from Friction torque of wind-turbine pitch bearings (seed 000)"
        " - not measured data; see data/pitch_bearing/README.md",
        f"# generator seed {seed} (first accepted from {FIRST_SEED})",
        ",".join(COLUMNS),
    ]
    for (m, speed, blade, rep, _), t in zip(rows, written, strict=True):
        lines.append(f"{m:d},{speed:.2f},{blade},{rep:d},{t:.4f},{t / reference:.6f}")
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())


if __name__ == "__main__":
    write(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
