"""The truth adapters of benchmarks/check_sizing_truth.py agree with the shipped data (no study run).

Each adapter evaluates a data generator's noise-free mean friction at SI inputs. At every tested
point of the shipped CSV (loaded in SI, as a study loads it) the measured mean must lie within
the generator's own noise of that truth; hand checks pin the unit conversions (rpm, degC, MN·m,
kN·m, normalised torque) at points where the generator's own numbers give the answer.
"""

from __future__ import annotations

import csv
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "check_sizing_truth.py"
SELECT = {"robot_joint": {}, "pitch_bearing": {}, "unwinder": {"setup": "belt_off"}}


@pytest.fixture(scope="module")
def cst():
    """The script, imported by path."""
    spec = importlib.util.spec_from_file_location("check_sizing_truth", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


@pytest.mark.parametrize("dataset", sorted(SELECT))
def test_truth_within_noise_of_the_data(cst, dataset):
    """Measured means scatter around the truth as the generator's noise says (|z| small, rms z ≈ 1)."""
    blocks = cst.cross_check(cst.ADAPTERS[dataset], SELECT[dataset])
    z = np.array([b.z for b in blocks])
    ref = cst.ADAPTERS[dataset].reference(blocks)
    assert abs(ref.z) < 3.0, ref
    assert np.max(np.abs(z)) < 4.5
    assert 0.6 < np.sqrt(np.mean(z**2)) < 1.6
    assert abs(z.mean()) < 4.0 / np.sqrt(z.size)  # no unit or offset error: no bias


def test_robot_joint_is_mean_of_series_in_newton_metres(cst):
    gen = cst.generator("robot_joint")
    truth = cst.truth_over_series(cst.ADAPTERS["robot_joint"], {"velocity": np.array([1.0, -2.0])}, {})
    assert truth.shape == (gen.N_SERIES, 2)
    expected = [gen.friction_truth(np.array([1.0, 2.0]), s) * gen.MAX_JOINT_TORQUE for s in (1, 2, 3)]
    np.testing.assert_allclose(truth, expected, rtol=1e-12)
    one = cst.truth_over_series(cst.ADAPTERS["robot_joint"], {"velocity": np.array([1.0])}, {"series": 2})
    np.testing.assert_allclose(one, [expected[1][:1]], rtol=1e-12)


def test_unwinder_reference_point_kelvin_and_rad_per_s(cst):
    """At 20 degC (293.15 K) and the churn reference speed the viscosity ratio is 1 exactly."""
    gen = cst.generator("unwinder")
    x = {"temperature": np.array([293.15]), "velocity": np.array([gen.OMEGA_REF])}
    truth = cst.truth_over_series(cst.ADAPTERS["unwinder"], x, {"setup": "belt_off"})
    expected = gen.COULOMB_MASS1 + gen.FAN_COEFF * gen.OMEGA_REF**2 + gen.CHURN_AT_REF
    np.testing.assert_allclose(truth, [[expected]], rtol=1e-12)
    np.testing.assert_allclose(gen.OMEGA_REF, 1400.0 * 2.0 * np.pi / 60.0)  # velocity input is rad/s


def test_pitch_bearing_matches_the_calibration_targets(cst):
    """Ball-load sums as the generator's; speed-averaged truth at 0, 2, 6 MN·m = its derived targets."""
    gen = cst.generator("pitch_bearing")
    p1, s43 = gen.ball_load_sums()
    q1, q43 = cst.solve_load_sums(gen, np.asarray(gen.MOMENTS_MNM, dtype=float) * 1e6)  # the solve itself
    np.testing.assert_allclose(q1, p1, rtol=1e-8, atol=1e-6)
    np.testing.assert_allclose(q43, s43, rtol=1e-8, atol=1e-6)
    speeds = np.asarray(gen.SPEEDS_RPM) * 2.0 * np.pi / 60.0  # rad/s
    k = gen.load_slope_knm_per_mnm()
    for key, mnm in (("T0", 0.0), ("T2", 2.0), ("T6", 6.0)):
        x = {"bending_moment": np.full(speeds.size, mnm * 1e6), "velocity": speeds}
        truth = cst.truth_over_series(cst.ADAPTERS["pitch_bearing"], x, {})
        assert truth.mean() == pytest.approx(float(gen.derived_targets()[key]) * k * 1e3, rel=1e-8)


def _fake_report(folder: Path, truth: np.ndarray, calibrated: tuple[float, float] | None) -> None:
    header = ["question", "label", "point", "velocity", "velocity [rad/s]", "distance[velocity]", "unit", "role",
              "mean_fn_q5", "mean_fn_q95"] + (["calibrated_q5", "calibrated_q95"] if calibrated else [])
    (folder / "robot_joint").mkdir(parents=True)
    with (folder / "robot_joint" / "sizing.csv").open("w", newline="", encoding="utf-8") as fh:
        out = csv.writer(fh)
        out.writerow(header)
        for j, v in enumerate((0.5, 6.0)):
            band = [truth[j] * 0.99, truth[j] * 1.01]
            cal = [truth[j] * c for c in calibrated] if calibrated else []
            out.writerow([1, "joint 1 over 0.5–6 rad/s", j + 1, v, v, 0.0, "N*m", "average", *band, *cal])
            out.writerow([1, "joint 1 over 0.5–6 rad/s", j + 1, v, v, 0.0, "N*m", "law", 0.0, 0.0, *cal])


@pytest.mark.parametrize(("calibrated", "status"), [(None, 0), ((0.9, 1.1), 0), ((1.05, 1.2), 1), ("missing", 2)])
def test_exit_status(cst, tmp_path, calibrated, status):
    """0: inside or no calibrated columns; 1: truth outside the calibrated band; 2: no report."""
    truth = cst.truth_over_series(cst.ADAPTERS["robot_joint"], {"velocity": np.array([0.5, 6.0])}, {}).mean(axis=0)
    if calibrated != "missing":
        _fake_report(tmp_path, truth, calibrated)
    assert cst.main(["--reports", str(tmp_path), "--studies", "robot_joint"]) == status
