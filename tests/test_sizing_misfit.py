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
