"""The reconstructed Dahl (1977) duplex-pair data set honours every fact it claims (README §1).

Least-squares fits of the Dahl closed forms (report Eq. 6-8, exponent i = 1, 1.5, 2, and the
general power form) are done per loop with scipy, not by MCMC, following the report's procedure
(§IV): the running level F_c and the loop centre are read off the horizontal asymptotes, x' is
measured from each rate-reversal point, and the knee x_c is fitted.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from bayesfric.datasets import load_builtin, select
from bayesfric.quantities import ureg

DATA = Path(__file__).resolve().parents[2] / "data" / "dahl_duplex"
PRELOADS_LBF = (6, 12, 18, 24, 30, 36)
IN_OZ = ureg.Quantity(1.0, "in*ozf").to("N*m").magnitude
PLATEAU_DEG = 2.5  # x' beyond which a branch is on its horizontal asymptote (within ~3 %)
METER_STIFFNESS = ureg.Quantity(0.28, "ft*lbf/deg").to("in*ozf/deg").magnitude  # §III


@pytest.fixture(scope="module")
def ds():
    return load_builtin("dahl_duplex")


def _loop(ds, condition: str, preload_lbf: int):
    """Angle (deg) and torque (in·oz) of one loop, in recorded order."""
    sub = select(ds, {"loop": f"{condition}_{preload_lbf:02d}lbf"})
    return np.rad2deg(sub["angle"].values), sub["torque"].values / IN_OZ


def _branches(angle: np.ndarray) -> list[tuple[np.ndarray, int]]:
    """Reversal-to-reversal branches: (indices including the reversal point, direction)."""
    step = np.sign(np.diff(angle))
    cuts = [0] + [k for k in range(1, step.size) if step[k] != step[k - 1]] + [angle.size - 1]
    return [(np.arange(s, e + 1), int(np.sign(angle[e] - angle[s])))
            for s, e in zip(cuts[:-1], cuts[1:], strict=True)]


def _u(x, knee, exponent):
    """Dahl closed form 1 - dF/F_c from a saturated reversal (u(0) = 2), Eq. 6-8 and general i."""
    if abs(exponent - 1.0) < 1e-12:
        return 2.0 * np.exp(-x / knee)
    return (2.0 ** (1.0 - exponent) + (exponent - 1.0) * x / knee) ** (-1.0 / (exponent - 1.0))


def _asymptotes(angle, torque):
    """Running level F_c and centre from the horizontal asymptotes (plateau means), §IV-V."""
    upper, lower = [], []
    for idx, d in _branches(angle):
        plateau = idx[np.abs(angle[idx] - angle[idx[0]]) > PLATEAU_DEG]
        (upper if d > 0 else lower).extend(torque[plateau])
    return 0.5 * (np.mean(upper) - np.mean(lower)), 0.5 * (np.mean(upper) + np.mean(lower))


def _fit(angle, torque, exponent=None, level=None, centre=None):
    """Least-squares Dahl fit; returns (params dict, residuals). Free: x_c, and i if None,
    F_c and centre if not given."""
    branches = _branches(angle)
    free_i, free_level = exponent is None, level is None

    def model(p):
        knee = p[0]
        i = p[1] if free_i else exponent
        fc, m = (p[-2], p[-1]) if free_level else (level, centre)
        out = np.empty_like(torque)
        for idx, d in branches:
            out[idx] = m + d * fc * (1.0 - _u(np.abs(angle[idx] - angle[idx[0]]), knee, i))
        return out

    p0, lo, hi = [0.2], [1e-3], [5.0]
    if free_i:
        p0, lo, hi = p0 + [1.5], lo + [0.5], hi + [3.5]
    if free_level:
        p0, lo, hi = p0 + [0.5 * np.ptp(torque), 0.0], lo + [0.0, -np.inf], hi + [np.inf, np.inf]
    res = least_squares(lambda p: model(p) - torque, p0, bounds=(lo, hi))
    names = ["knee"] + (["exponent"] if free_i else [])
    names += ["level", "centre"] if free_level else []
    return dict(zip(names, res.x, strict=True)), res.fun


def test_provenance_and_declared_paper_units(ds):
    assert ds.attrs["provenance"] == "reconstructed"
    assert "reconstructed from Dahl 1977" in ds.attrs["title"]
    assert (DATA / "dahl_duplex.csv").read_text().startswith("# RECONSTRUCTED from Dahl 1977")
    assert ds["preload"].attrs["original_unit"] == "lbf"  # a force, not pint's mass "lb"
    assert ds["angle"].attrs["original_unit"] == "deg"
    assert ds["torque"].attrs["original_unit"] == "in*ozf"
    # conversions done by the loader, checked by hand: 1 lbf = 4.448222 N, 1 in·ozf = 7.0616e-3 N·m
    assert np.unique(ds["preload"].values) == pytest.approx(
        [p * 4.4482216152605 for p in PRELOADS_LBF], rel=1e-9)
    assert IN_OZ == pytest.approx(0.0254 * 0.45359237 * 9.80665 / 16, rel=1e-12)


def test_design_loops_preloads_conditions(ds):
    assert ds.attrs["trajectory"] == "loop"
    assert set(ds["condition"].values) == {"new", "worn"}
    assert ds.sizes["obs"] <= 500
    for condition in ("new", "worn"):
        for p in PRELOADS_LBF:
            angle, _ = _loop(ds, condition, p)
            assert 35 <= angle.size <= 50
            assert len(_branches(angle)) == 3  # 1.5 cycles starting at an extreme
            assert angle[0] == pytest.approx(-angle.max(), abs=1e-6)
    # every loop is one contiguous block (trajectory order)
    labels = ds["loop"].values
    assert len(set(labels)) == int(np.sum(labels[1:] != labels[:-1])) + 1 == 12


def test_drive_quantisation_and_meter_range(ds):
    angle = np.rad2deg(ds["angle"].values)
    quantum = 22.5 / 2048  # Table I: 0.0110 deg on the ±11.25 deg range
    assert np.abs(angle).max() <= 11.25
    assert np.abs(angle / quantum - np.round(angle / quantum)).max() < 1e-3
    torque = ds["torque"].values / IN_OZ
    assert np.abs(torque).max() < 20.0  # 0-20 in·oz scale (§III)
    assert np.abs(torque / 0.001 - np.round(torque / 0.001)).max() < 1e-6  # 0.001 in·oz


def test_running_friction_rises_with_preload_and_jumps_at_36lb(ds):
    for condition in ("new", "worn"):
        levels = np.array([_asymptotes(*_loop(ds, condition, p))[0] for p in PRELOADS_LBF])
        steps = np.diff(levels)
        if condition == "new":
            assert np.all(steps > 0), levels  # Fig. 12, new bearings
        assert steps[-1] > 2.0 * np.median(steps[:-1]), levels  # sudden increase at 36 lb (§V)


def test_wear_lowers_running_friction_at_mid_and_high_preload(ds):
    for p in (18, 24, 30, 36):
        new = _asymptotes(*_loop(ds, "new", p))[0]
        worn = _asymptotes(*_loop(ds, "worn", p))[0]
        assert worn < 0.95 * new, (p, new, worn)


def test_worn_waviness_5_to_15_percent(ds):
    peaks = {}
    for condition in ("new", "worn"):
        for p in PRELOADS_LBF:
            angle, torque = _loop(ds, condition, p)
            params, resid = _fit(angle, torque)
            peaks[condition, p] = np.abs(resid).max() / params["level"]
    worn = np.array([peaks["worn", p] for p in PRELOADS_LBF])
    new = np.array([peaks["new", p] for p in PRELOADS_LBF])
    # §V: old-bearing wave peaks 5-15 % above the average (sampled peaks may fall a bit short)
    assert np.all((worn > 0.04) & (worn < 0.16)), worn
    assert np.all(new < 0.045), new
    assert np.median(worn) > 2.0 * np.median(new)


def test_exponent_about_constant_average_1p5(ds):
    exponents = np.array([_fit(*_loop(ds, "new", p))[0]["exponent"] for p in PRELOADS_LBF])
    assert np.mean(exponents) == pytest.approx(1.5, abs=0.1)  # §V: average about 1.5
    assert np.ptp(exponents) < 0.3  # "approximately constant"


def test_knee_constant_and_independent_of_preload(ds):
    knees = np.array([_fit(*_loop(ds, "new", p), exponent=1.5)[0]["knee"] for p in PRELOADS_LBF])
    assert np.std(knees) / np.mean(knees) < 0.1
    slope = np.polyfit(PRELOADS_LBF, knees, 1)[0]
    assert abs(slope * 30.0) < 0.1 * np.mean(knees)  # change over 6-36 lb < 10 %


def test_rest_slope_an_order_of_magnitude_below_meter_stiffness(ds):
    angle, torque = _loop(ds, "new", 24)
    params, _ = _fit(angle, torque, exponent=1.5)
    rest_slope = params["level"] / params["knee"]  # σ = F_c / x_c (Eq. 5)
    assert 5.0 < METER_STIFFNESS / rest_slope < 20.0


def test_fits_with_i_1_and_1p5_beat_i_2(ds):
    for p in PRELOADS_LBF:
        angle, torque = _loop(ds, "new", p)
        level, centre = _asymptotes(angle, torque)
        rss = {i: np.sum(_fit(angle, torque, exponent=i, level=level, centre=centre)[1] ** 2)
               for i in (1.0, 1.5, 2.0)}
        assert rss[1.0] < rss[2.0] and rss[1.5] < rss[2.0], (p, rss)


def test_regeneration_is_bit_identical(tmp_path):
    subprocess.run([sys.executable, str(DATA / "generate.py"), str(tmp_path)], check=True)
    for name in ("dahl_duplex.csv", "dahl_duplex.toml"):
        assert (tmp_path / name).read_bytes() == (DATA / name).read_bytes(), name
