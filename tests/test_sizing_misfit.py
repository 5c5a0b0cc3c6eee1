"""The law's misfit inside the envelope (bayesfric.sizing.misfit): by hand, and on a fitted law."""

from __future__ import annotations

import numpy as np
import pytest

from bayesfric.sizing.calibration import LAMBDA
from bayesfric.sizing.misfit import BANDWIDTH, LocalMisfit


def test_the_rate_by_hand_on_two_rows():
    # two rows at scaled positions 0 and 1; the query at 0.05 tested ranges
    m = LocalMisfit({"velocity": np.array([0.0, 1.0])}, {"velocity": (False, 2.0)},
                    r=np.array([0.04, -0.02]), s=np.array([0.01, 0.01]))
    g = 0.1 / 2.0
    w = np.exp(-0.5 * (np.array([g, 1.0 - g]) ** 2 - g**2) / BANDWIDTH**2)
    mean = (w @ [0.04, -0.02]) / w.sum()
    se2 = (w**2 @ [1e-4, 1e-4]) / w.sum() ** 2
    assert m.at({"velocity": np.array([0.1])})[0] == pytest.approx(np.sqrt(mean**2 - LAMBDA * se2), rel=1e-12)


def test_a_bias_at_the_top_of_the_data_is_measured_and_carried_beyond_it():
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 1.0, 200)
    r = np.where(x > 0.8, 0.03, 0.0) + rng.normal(0, 0.01, x.size)  # 3 % low at the top only
    m = LocalMisfit({"velocity": x}, {"velocity": (False, 1.0)}, r=r, s=np.full(x.size, 0.01))
    rate = m.at({"velocity": np.array([0.3, 0.95, 2.0])})
    assert rate[0] < 0.005  # no misfit in the middle
    assert rate[1] == pytest.approx(0.03, abs=0.006)
    assert rate[2] == pytest.approx(0.03, abs=0.006)  # beyond the data: the nearest edge's misfit


def test_signed_inputs_are_read_on_their_magnitude():
    x = np.array([-1.0, -0.5, 0.5, 1.0])
    m = LocalMisfit({"velocity": np.abs(x)}, {"velocity": (True, 1.0)}, r=np.full(4, 0.05), s=np.zeros(4))
    assert m.at({"velocity": np.array([-0.9, 0.9])}) == pytest.approx([0.05, 0.05])


def test_the_shift_keeps_the_sign_of_the_bias():
    x = np.linspace(0.0, 1.0, 50)
    for bias in (0.04, -0.04):
        m = LocalMisfit({"velocity": x}, {"velocity": (False, 1.0)}, r=np.full(x.size, bias), s=np.zeros(x.size))
        shift = m.shift({"velocity": np.array([0.5, 3.0])})
        assert shift == pytest.approx([bias, bias])
        assert m.at({"velocity": np.array([0.5])})[0] == pytest.approx(abs(bias))


def test_widen_moves_the_curve_by_the_shift_and_spreads_it():
    from bayesfric.sizing.calibration import widen

    mu = np.full((2, 4000, 2), [10.0, -10.0])  # a curve measured in both directions
    new_mu, new_y, var = widen(mu, mu.copy(), np.array([0.05, 0.05]), np.random.default_rng(0),
                               shift=np.array([0.02, 0.02]))
    assert new_mu.mean(axis=(0, 1)) == pytest.approx([10.2, -10.2], abs=0.03)  # 2 % further from zero
    assert new_mu.std(axis=(0, 1)) == pytest.approx([0.5, 0.5], rel=0.05)
    assert var == pytest.approx(0.25)
    assert np.array_equal(new_mu, new_y)


def test_beyond_the_data_the_misfit_is_exactly_the_nearest_edges():
    rng = np.random.default_rng(1)
    x = np.linspace(0.1, 2.0, 30)
    m = LocalMisfit({"velocity": x / 1.9}, {"velocity": (False, 1.9)}, r=rng.normal(0, 0.03, x.size),
                    s=np.full(x.size, 0.03))
    edge = m.shift({"velocity": np.array([2.0, 0.1])})
    beyond = m.shift({"velocity": np.array([4.0, 9.0, 0.0])})
    assert beyond == pytest.approx([edge[0], edge[0], edge[1]], rel=1e-12)
