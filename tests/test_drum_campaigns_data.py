"""The reconstructed multi-campaign drum roll-out data set (seeds 003, 004) and its truth file.

The data set (``data/drum_campaigns/``) is a RECONSTRUCTION: the return pulley's coast-downs in
seven test campaigns over 0-6000 service hours, with O-ring and bearing friction growing with wear.
These tests check that the generator reproduces the shipped files, the loader reads them as
reconstructed, the campaigns are ordered with numeric hours, and the truth file's crossing time
follows from its own trend.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bayesfric.datasets import load_builtin, select, trajectory_starts
from bayesfric.laws.drum import DRUM_INERTIA

DATA_DIR = Path(__file__).resolve().parents[1] / "data" / "drum_campaigns"
RPM = 2.0 * np.pi / 60.0
WINDOW = 7  # samples per local quadratic (as tests/datasets/test_drum_rollout.py)


@pytest.fixture(scope="module")
def data():
    return load_builtin("drum_campaigns")


@pytest.fixture(scope="module")
def truth():
    return json.loads(DATA_DIR.joinpath("truth.json").read_text())


def trend_value(coeffs: list[float], hours, scale: float) -> np.ndarray:
    u = np.asarray(hours, dtype=float) / scale
    return coeffs[0] + coeffs[1] * u + coeffs[2] * u**2


def mean_torque(truth: dict, omega: float, params: dict) -> float:
    """The truth's revolution-averaged torque (README.md §3), from truth.json alone."""
    f = truth["fixed"]
    return (
        params["bearing_static"]
        + params["bearing_rise"] * (1.0 - np.exp(-omega / f["bearing_rise_speed"]))
        + f["windage"] * omega**2
        + params["oring_constant"]
        + params["oring_speed_coeff"] * omega ** f["oring_speed_power"]
        + f["oring_breakaway"] * np.exp(-omega / f["oring_breakaway_speed"])
    )


def trend_torque(truth: dict, hours) -> np.ndarray:
    scale = truth["trend"]["hour_scale_h"]
    params = {k: trend_value(v, hours, scale) for k, v in truth["trend"].items() if k != "hour_scale_h"}
    return mean_torque(truth, truth["query"]["speed_rpm"] * RPM, params)


def torque_near(time: np.ndarray, omega: np.ndarray, speed: float) -> float:
    """τ = −J dω/dt from a local quadratic over WINDOW samples centred nearest ``speed`` (rad/s)."""
    moving = np.flatnonzero(omega > 0)
    half = WINDOW // 2
    centres = moving[half : len(moving) - half]
    centre = centres[np.argmin(np.abs(omega[centres] - speed))]
    sl = slice(centre - half, centre + half + 1)
    _, slope, _ = np.polyfit(time[sl] - time[centre], omega[sl], 2)
    return -DRUM_INERTIA * slope


def test_provenance_and_layout(data):
    assert data.attrs["provenance"] == "reconstructed"
    assert "reconstructed from" in data.attrs["title"]
    assert data.attrs["response"] == "velocity"
    assert data.attrs["trajectory"] == "run"
    assert data.sizes["obs"] <= 1200
    assert f"{DRUM_INERTIA:g} kg*m^2" in data.attrs["description"]
    first = DATA_DIR.joinpath("drum_campaigns.csv").read_text().splitlines()[0]
    assert first.startswith("# RECONSTRUCTED") and "not measured" in first
    sidecar = DATA_DIR.joinpath("drum_campaigns.toml").read_text()
    assert '[columns.hours]\nrole = "group"\nunit = "h"' in sidecar
    readme = DATA_DIR.joinpath("README.md").read_text()
    assert readme.startswith("# drum_campaigns — RECONSTRUCTED data, not measured")


def test_campaigns_are_ordered_with_numeric_hours(data, truth):
    hours = data["hours"].values
    assert np.issubdtype(hours.dtype, np.integer)  # plain numbers, read as integer group labels
    assert np.all(np.diff(hours) >= 0)  # rows ordered by campaign
    campaigns = [c["hours"] for c in truth["campaigns"]]
    assert np.unique(hours).tolist() == campaigns and len(campaigns) >= 5
    assert np.all(np.diff(campaigns) > 0)
    runs = data["run"].values
    assert trajectory_starts(data).sum() == len(np.unique(runs))
    for h in campaigns:
        part = select(data, {"hours": h})
        assert len(np.unique(part["run"].values)) == 3
        assert np.unique(part["run"].values).size * 50 >= part.sizes["obs"]  # <= 50 samples per run
    for run in np.unique(runs):
        one = select(data, {"run": run})
        t, w, w0 = one["time"].values, one["velocity"].values, one["initial_velocity"].values
        assert len(np.unique(one["hours"].values)) == 1  # a coast-down belongs to one campaign
        assert t[0] == 0.0 and np.all(np.diff(t) > 0)
        assert np.all(w0 == w0[0]) and w[0] == pytest.approx(w0[0])
        assert np.all(np.diff(w) <= 0) and w[-1] == 0.0


def test_truth_crossing_follows_from_its_trend(truth):
    q = truth["query"]
    capacity, crossing = q["capacity_Nm"], q["crossing_hours"]
    lo, hi = 0.0, 50000.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if trend_torque(truth, mid) >= capacity else (mid, hi)
    assert crossing == pytest.approx(hi, abs=1e-2)
    assert trend_torque(truth, crossing - 1.0) < capacity <= trend_torque(truth, crossing + 1.0)
    hours = np.array(q["trend_torque_hours"], dtype=float)
    np.testing.assert_allclose(q["trend_torque_Nm"], trend_torque(truth, hours), atol=2e-6)
    assert np.all(np.diff(q["trend_torque_Nm"]) > 0)
    last = truth["campaigns"][-1]["hours"]
    assert 1.3 * last <= crossing <= 2.0 * last  # a forecast beyond the measured campaigns
    assert q["crossing_over_last_campaign"] == pytest.approx(crossing / last, abs=1e-4)
    # h = 0 is drum_rollout's bearings + O-rings truth: about 0.95 N*m + 0.1 N*m per 1000 rpm
    assert trend_torque(truth, 0.0) == pytest.approx(0.95 + 0.1 * 1.4, abs=0.03)


def test_campaign_parameters_scatter_about_the_trend(truth):
    scale = truth["trend"]["hour_scale_h"]
    speed = truth["query"]["speed_rpm"] * RPM
    for c in truth["campaigns"]:
        for name in ("oring_constant", "oring_speed_coeff", "bearing_static"):
            ratio = c[name] / trend_value(truth["trend"][name], c["hours"], scale)
            assert 0.8 < ratio < 1.25, (c["hours"], name)
        assert c["torque_at_query_Nm"] == pytest.approx(mean_torque(truth, speed, c), abs=2e-6)
        assert c["trend_torque_at_query_Nm"] == pytest.approx(trend_torque(truth, c["hours"]), abs=2e-6)


def test_coastdowns_show_each_campaigns_torque(data, truth):
    """τ = −J dω/dt near 1000 rpm on the 1200 rpm runs: each campaign's truth, rising over hours."""
    speed = 1000.0 * RPM
    measured = []
    for c in truth["campaigns"]:
        part = select(data, {"hours": c["hours"]})
        run = max(np.unique(part["run"].values), key=lambda r: select(part, {"run": r})["velocity"].values[0])
        one = select(part, {"run": run})
        tau = torque_near(one["time"].values, one["velocity"].values, speed)
        expected = mean_torque(truth, speed, c)
        assert tau == pytest.approx(expected, abs=0.03), c["hours"]  # ripple + quantisation
        measured.append(tau)
    assert measured[-1] - measured[0] > 0.3


def test_regeneration_is_bit_identical(tmp_path):
    subprocess.run([sys.executable, str(DATA_DIR / "generate.py"), str(tmp_path)], check=True, timeout=300)
    for name in ("drum_campaigns.csv", "drum_campaigns.toml", "truth.json"):
        assert (tmp_path / name).read_bytes() == (DATA_DIR / name).read_bytes(), name
