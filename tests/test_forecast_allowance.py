"""The model-form allowance of a forecast over service time (bayesfric.sizing.forecast): the
misses of leave-future-out folds by hand, the rate recovered from misses built to grow with the
reach squared, the allowance's growth, and the widened curves' spread."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr

from bayesfric.compare.heldout import HeldOut
from bayesfric.sizing.calibration import GROWTH, LAMBDA, OFFSET, Miss
from bayesfric.sizing.forecast import allowance, forecast_miss, forecast_pieces, study_misses, widen_curves

pytestmark = pytest.mark.fast

HOURS = np.repeat([0.0, 1000.0, 2000.0, 3000.0, 4000.0], 4)  # 5 campaigns of 4 rows


def _kept(beta: float, rng: np.random.Generator, sd: float = 0.01) -> tuple[HeldOut, np.ndarray]:
    """Folds forecasting 3000 h (trained to 2000 h) and 4000 h (to 3000 h); the truth misses the
    forecast mean 10 by ``beta * 10 * u**2``."""
    rows = np.flatnonzero(HOURS >= 3000)
    fold = (HOURS[rows] == 4000).astype(int)
    u = (HOURS[rows] - np.where(fold == 0, 2000.0, 3000.0)) + OFFSET * np.where(fold == 0, 2000.0, 3000.0)
    mu = 10.0 + sd * rng.normal(size=(400, rows.size))
    y = np.full(HOURS.size, 10.0)
    y[rows] = 10.0 + beta * 10.0 * u**GROWTH
    return HeldOut(rows, fold, mu, np.full(rows.size, 1e-6)), y


def test_each_forecast_is_measured_from_its_own_folds_last_campaign():
    kept, y = _kept(1e-9, np.random.default_rng(0))
    p = forecast_pieces(kept, HOURS, y)
    # 3000 h from a fold trained to 2000 h: reach 1000 + 0.4 * 2000; 4000 h from 3000 h: 1000 + 0.4 * 3000
    np.testing.assert_allclose(p.u, np.repeat([1800.0, 2200.0], 4))
    np.testing.assert_allclose(p.d, np.repeat([0.5, 1000.0 / 3000.0], 4))
    np.testing.assert_allclose(p.e, y[kept.index] - kept.mu.mean(axis=0))
    assert p.cov[0, 4] == 0.0 and p.cov[0, 1] != 0.0  # folds' draws are independent, a fold's shared


def test_the_rate_of_misses_that_grow_with_the_reach_squared_is_recovered():
    kept, y = _kept(2e-9, np.random.default_rng(1))
    ds = xr.Dataset({"torque": ("obs", y)}, coords={"hours": ("obs", HOURS)}, attrs={"response": "torque"})
    miss = forecast_miss(SimpleNamespace(predictive=kept, reliable=True, scheme="lfo"), ds, "hours")
    assert miss.beta == pytest.approx(2e-9, rel=0.02)
    assert miss.rate == pytest.approx(np.sqrt(miss.beta**2 - LAMBDA * miss.se**2))
    assert miss.n == 8 and miss.scheme == "lfo"


def test_a_forecast_within_its_band_gets_no_allowance_and_failed_folds_none():
    kept, y = _kept(0.0, np.random.default_rng(2), sd=0.5)
    ds = xr.Dataset({"torque": ("obs", y)}, coords={"hours": ("obs", HOURS)}, attrs={"response": "torque"})
    ok = SimpleNamespace(predictive=kept, reliable=True, scheme="lfo")
    assert forecast_miss(ok, ds, "hours").rate == 0.0
    failed = SimpleNamespace(predictive=kept, reliable=False, scheme="lfo")
    got = study_misses({"a": {"lfo": ok}, "b": {"lfo": failed}, "c": {}}, ["lfo"], ds, "hours")
    assert got["a"][0].rate == 0.0 and got["a"][1] == ""
    assert got["b"] == (None, "its leave-future-out folds failed the diagnostics gate")
    assert got["c"][0] is None and "no leave-future-out" in got["c"][1]


def test_the_allowance_grows_with_the_reach_past_the_last_campaign():
    miss = Miss("lfo", 1e-8, 1e-8, 0.0, 8, 0.5)
    t = np.array([4000.0, 5000.0, 8000.0])
    rel = allowance(miss, t, first=0.0, last=4000.0)
    np.testing.assert_allclose(rel, 1e-8 * np.array([1600.0, 2600.0, 5600.0]) ** 2)  # OFFSET * 4000 = 1600
    np.testing.assert_array_equal(allowance(None, t, first=0.0, last=4000.0), 0.0)


def test_widened_curves_scatter_by_the_allowance_shared_along_service_time():
    curves = np.full((20000, 3), 2.0)
    out = widen_curves(curves, np.array([0.0, 0.1, 0.2]), np.random.default_rng(3))
    np.testing.assert_array_equal(out[:, 0], 2.0)
    np.testing.assert_allclose(out.std(axis=0), [0.0, 0.2, 0.4], rtol=0.02)
    np.testing.assert_allclose((out[:, 2] - 2.0), 2.0 * (out[:, 1] - 2.0))  # one normal per draw
