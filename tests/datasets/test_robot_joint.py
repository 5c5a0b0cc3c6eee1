"""The reconstructed RX90 joint-1 Stribeck data set (seed 004) shows every finding of the paper.

Each finding is checked the way the paper obtained it: the classical law (Eq. 5) by linear least
squares in (T_C, T_s, c_v) with δ = 0.33 and q̇_s = 0.024 rad/s fixed (Eq. 6-8); the joint law
(Eq. 41) by the paper's four steps of Sec. 6 (log-log fit of the viscous part above 0.5 rad/s,
then linear least squares in (T_a0, c_v) over a small grid of δ_a and q̇_s standing in for the
manual fine-tuning). Fits use the mean over the three series, as the paper's Fig. 12 does.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bayesfric.datasets import load_builtin, select

DATA_DIR = Path(__file__).resolve().parents[2] / "data" / "robot_joint"
PAPER_DELTA, PAPER_V_S = 0.33, 0.024  # Sec. 2.2: values of δ and q̇_s found by the authors
LOW_RANGE = 0.5  # rad/s, upper end of the paper's low-velocity fit (model 2)


def classical_design(speed: np.ndarray, delta: float, v_s: float) -> np.ndarray:
    """Matrix A of Eq. 7: columns multiply (T_C, T_s, c_v) in Eq. 5 for positive speeds."""
    decay = np.exp(-((speed / v_s) ** delta))
    return np.column_stack([1.0 - decay, decay, speed])


def fit_classical(speed, torque, delta=PAPER_DELTA, v_s=PAPER_V_S) -> np.ndarray:
    """Eq. 8: least-squares (T_C, T_s, c_v) of Eq. 5 with δ and q̇_s fixed."""
    coef, *_ = np.linalg.lstsq(classical_design(speed, delta, v_s), torque, rcond=None)
    return coef


def joint_law(speed, t_a0, v_s, delta_a, c_v, viscous_power):
    """Eq. 41 for positive speeds: T_a0 exp(-(q̇/q̇_s)^δa) + c_v q̇^(1-δv)."""
    return t_a0 * np.exp(-((speed / v_s) ** delta_a)) + c_v * speed**viscous_power


def fit_joint_law(speed, torque):
    """Sec. 6, steps 1-4: returns (T_a0, q̇_s, δ_a, c_v, 1-δ_v)."""
    high = speed >= LOW_RANGE
    slope, _ = np.polyfit(np.log(speed[high]), np.log(torque[high]), 1)  # step 1
    best = None
    for delta_a in np.arange(0.2, 1.21, 0.05):  # steps 2 and 4: δ_a and q̇_s tuned on a grid
        for v_s in np.geomspace(0.005, 0.3, 40):
            design = np.column_stack(
                [np.exp(-((speed / v_s) ** delta_a)), speed**slope]
            )  # step 3: T_a0 and c_v by linear least squares
            (t_a0, c_v), *_ = np.linalg.lstsq(design, torque, rcond=None)
            model = joint_law(speed, t_a0, v_s, delta_a, c_v, slope)
            if np.any(model <= 0):
                continue
            score = np.sum(np.log(model / torque) ** 2)  # the log-scale view of Fig. 12(c)
            if best is None or score < best[0]:
                best = (score, (t_a0, v_s, delta_a, c_v, slope))
    return best[1]


def rms_relative_error(model, measured) -> float:
    """Root-mean-square relative error."""
    return float(np.sqrt(np.mean((model / measured - 1.0) ** 2)))


@pytest.fixture(scope="module")
def data():
    return load_builtin("robot_joint")


@pytest.fixture(scope="module")
def mean_curve(data):
    """Mean torque over the three series per speed (the paper's averaged Stribeck curve)."""
    speeds = np.unique(data["velocity"].values)
    torque = np.array([data["torque"].values[data["velocity"].values == v].mean() for v in speeds])
    return speeds, torque


def test_provenance_and_layout(data):
    assert data.attrs["provenance"] == "reconstructed"
    assert "reconstructed from" in data.attrs["title"]
    assert data.attrs["response"] == "torque"
    assert sorted(set(data["series"].values.tolist())) == [1, 2, 3]
    assert data.sizes["obs"] <= 300
    speeds = np.unique(data["velocity"].values)
    assert speeds.min() > 0 and 3.9 <= speeds.max() <= 4.1  # positive direction, up to ~4 rad/s
    assert np.sum(speeds <= LOW_RANGE) > np.sum(speeds > LOW_RANGE)  # dense below 0.5 rad/s
    first = DATA_DIR.joinpath("robot_joint.csv").read_text().splitlines()[0]
    assert first.startswith("# RECONSTRUCTED") and "not measured" in first


def test_normalised_column_is_torque_over_the_stated_maximum(data):
    ratio = data["torque"].values / data["torque_normalised"].values
    assert np.allclose(ratio, ratio[0], rtol=1e-4)
    assert f"{ratio[0]:.0f} N*m" in data.attrs["description"]


def test_stribeck_dip_at_low_speed(mean_curve):
    """Fig. 4(b): torque falls from the lowest speeds to a minimum, then rises again."""
    speed, torque = mean_curve
    i_min = int(np.argmin(torque))
    assert 0.02 < speed[i_min] < 0.3
    assert torque[0] > 1.2 * torque[i_min]
    assert torque[speed <= LOW_RANGE][-1] > 1.5 * torque[i_min]


def test_viscous_growth_is_sub_linear_at_high_speed(mean_curve):
    """Fig. 4(a): log-log slope of torque against speed above 0.5 rad/s clearly below 1."""
    speed, torque = mean_curve
    high = speed >= LOW_RANGE
    slope, _ = np.polyfit(np.log(speed[high]), np.log(torque[high]), 1)
    assert 0.3 < slope < 0.8


def test_classical_fit_on_low_range_extrapolates_poorly(mean_curve):
    """Model 2 (0-0.5 rad/s): accurate inside its range, poor above 0.5 rad/s."""
    speed, torque = mean_curve
    low = speed <= LOW_RANGE
    coef = fit_classical(speed[low], torque[low])
    model = classical_design(speed, PAPER_DELTA, PAPER_V_S) @ coef
    inside = rms_relative_error(model[low], torque[low])
    outside = rms_relative_error(model[~low], torque[~low])
    assert inside < 0.05
    assert outside > 0.25 and outside > 5 * inside
    assert coef[1] > coef[0]  # a positive Stribeck effect inside the low range


def test_classical_fit_on_full_range_has_static_below_coulomb(mean_curve):
    """Model 1 (0-4 rad/s): T_s < T_C, the 'negative Stribeck effect' of Sec. 2.2."""
    speed, torque = mean_curve
    t_c, t_s, c_v = fit_classical(speed, torque)
    assert t_s < t_c
    assert c_v > 0


def test_joint_law_fits_the_full_range_with_even_relative_errors(mean_curve):
    """Fig. 12(c): Eq. 41 fits 0-4 rad/s, relative errors equally small at low and high speed."""
    speed, torque = mean_curve
    model = joint_law(speed, *fit_joint_law(speed, torque))
    low = speed <= LOW_RANGE
    err_low = rms_relative_error(model[low], torque[low])
    err_high = rms_relative_error(model[~low], torque[~low])
    assert err_low < 0.05 and err_high < 0.05
    assert max(err_low, err_high) < 3 * min(err_low, err_high)
    full = classical_design(speed, PAPER_DELTA, PAPER_V_S) @ fit_classical(speed, torque)
    assert rms_relative_error(model, torque) < 0.5 * rms_relative_error(full, torque)


def test_series_differ_by_a_small_warm_up_drift(data):
    """Sec. 6: three series after warm-up; they agree to a few per cent."""
    per_series = [
        select(data, {"series": s})["torque"].values for s in (1, 2, 3)
    ]
    high_speed_means = [t[-5:].mean() for t in per_series]
    spread = np.ptp(high_speed_means) / np.mean(high_speed_means)
    assert 0.005 < spread < 0.1


def test_regeneration_is_bit_identical(tmp_path):
    subprocess.run(
        [sys.executable, str(DATA_DIR / "generate.py"), str(tmp_path)], check=True, timeout=120
    )
    for name in ("robot_joint.csv", "robot_joint.toml"):
        assert (tmp_path / name).read_bytes() == (DATA_DIR / name).read_bytes()
