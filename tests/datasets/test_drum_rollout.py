"""The reconstructed drum roll-out data set (seed 003) shows the paper's friction torques.

The torque is recovered from the coast-downs the way a roll-out test is evaluated:
τ = −J dω/dt, with dω/dt from local least-squares quadratics over 7 consecutive samples (moving
part of each run only), pooled per set-up and averaged in 100 rpm speed bins.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bayesfric.datasets import load_builtin, select, trajectory_starts
from bayesfric.laws.drum import DRUM_INERTIA

DATA_DIR = Path(__file__).resolve().parents[2] / "data" / "drum_rollout"
RPM = 2.0 * np.pi / 60.0
WINDOW = 7  # samples per local quadratic
BIN_RPM = 100.0


def torque_from_coastdown(time: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(speed, friction torque) at the centres of local quadratic fits on the moving part."""
    moving = np.flatnonzero(omega > 0)
    half = WINDOW // 2
    speeds, torques = [], []
    for centre in moving[half : len(moving) - half]:
        sl = slice(centre - half, centre + half + 1)
        dt = time[sl] - time[centre]
        _, slope, value = np.polyfit(dt, omega[sl], 2)
        speeds.append(value)
        torques.append(-DRUM_INERTIA * slope)
    return np.array(speeds), np.array(torques)


def binned_torque_curve(data, setup: str) -> tuple[np.ndarray, np.ndarray]:
    """Torque against speed (rpm) for one set-up: all its runs pooled, 100 rpm bin means."""
    part = select(data, {"setup": setup})
    speeds, torques = [], []
    for run in np.unique(part["run"].values):
        one = select(part, {"run": run})
        s, t = torque_from_coastdown(one["time"].values, one["velocity"].values)
        speeds.append(s / RPM)
        torques.append(t)
    speed_rpm, torque = np.concatenate(speeds), np.concatenate(torques)
    bins = np.floor(speed_rpm / BIN_RPM).astype(int)
    keys = np.unique(bins)
    centres = np.array([speed_rpm[bins == b].mean() for b in keys])
    means = np.array([torque[bins == b].mean() for b in keys])
    return centres, means


@pytest.fixture(scope="module")
def data():
    return load_builtin("drum_rollout")


def test_provenance_and_layout(data):
    assert data.attrs["provenance"] == "reconstructed"
    assert "reconstructed from" in data.attrs["title"]
    assert data.attrs["response"] == "velocity"
    assert data.attrs["trajectory"] == "run"
    assert data.sizes["obs"] <= 300
    assert set(data["setup"].values.tolist()) == {"bearings_only", "bearings_orings"}
    for setup in ("bearings_only", "bearings_orings"):
        assert len(np.unique(select(data, {"setup": setup})["run"].values)) >= 3
    assert f"{DRUM_INERTIA:g} kg*m^2" in data.attrs["description"]
    first = DATA_DIR.joinpath("drum_rollout.csv").read_text().splitlines()[0]
    assert first.startswith("# RECONSTRUCTED") and "not measured" in first


def test_runs_are_ordered_coastdowns_that_stop(data):
    starts = trajectory_starts(data)
    assert starts.sum() == len(np.unique(data["run"].values))
    for run in np.unique(data["run"].values):
        one = select(data, {"run": run})
        t, w, w0 = one["time"].values, one["velocity"].values, one["initial_velocity"].values
        assert t[0] == 0.0 and np.all(np.diff(t) > 0)
        assert np.all(w0 == w0[0]) and w[0] == pytest.approx(w0[0])
        assert np.all(np.diff(w) <= 0) and np.all(w >= 0)
        assert w[-1] == 0.0 and w[-2] >= 0.0  # at rest by the end of each run


def test_bearings_only_torque_is_0p2_to_0p3_and_nearly_speed_independent(data):
    """Fig. 7: 0.2-0.3 N*m, 'nearly independent on rotational speed'."""
    speed, torque = binned_torque_curve(data, "bearings_only")
    assert np.all((torque > 0.18) & (torque < 0.32))
    assert np.ptp(torque) < 0.1
    assert np.median(torque) == pytest.approx(0.25, abs=0.05)


def test_orings_torque_is_0p95_plus_0p1_per_1000_rpm(data):
    """Sec. 4: about 0.95 N*m constant plus about 0.1 N*m per 1000 rpm."""
    speed, torque = binned_torque_curve(data, "bearings_orings")
    slope, intercept = np.polyfit(speed / 1000.0, torque, 1)
    assert intercept == pytest.approx(0.95, abs=0.05)
    assert slope == pytest.approx(0.1, abs=0.04)


def test_orings_add_most_of_the_friction(data):
    s_b, t_b = binned_torque_curve(data, "bearings_only")
    s_o, t_o = binned_torque_curve(data, "bearings_orings")
    extra = t_o - np.interp(s_o, s_b, t_b)
    assert np.all(extra > 0.6)


def test_regeneration_is_bit_identical(tmp_path):
    subprocess.run(
        [sys.executable, str(DATA_DIR / "generate.py"), str(tmp_path)], check=True, timeout=300
    )
    for name in ("drum_rollout.csv", "drum_rollout.toml"):
        assert (tmp_path / name).read_bytes() == (DATA_DIR / name).read_bytes()
