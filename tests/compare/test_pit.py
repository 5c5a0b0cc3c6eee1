"""The LOO-PIT direction classifier on synthetic PIT values of known shape.

A predictive N(μ, s²) for data from N(0, 1) gives PIT u = Φ((y − μ) / s): s < 1 (too narrow)
makes u U-shaped and spreads the normal scores by 1/s, s > 1 (too wide) makes it hump-shaped,
μ ≠ 0 shifts it (μ < 0: predictions too low, u piles near 1).
"""

import numpy as np
import pytest
from scipy.stats import norm

from bayesfric.compare.pit import BIAS_MARGIN, SCALE_MARGIN, pit_shape


def pit(n: int, mu: float = 0.0, s: float = 1.0, seed: int = 0) -> np.ndarray:
    y = np.random.default_rng(seed).standard_normal(n)
    return norm.cdf((y - mu) / s)


@pytest.mark.parametrize("seed", range(5))
def test_known_shapes_are_named(seed):
    assert pit_shape(pit(2000, s=0.5, seed=seed)).directions == ["too narrow"]
    assert pit_shape(pit(2000, s=2.0, seed=seed)).directions == ["too wide"]
    assert pit_shape(pit(2000, mu=-0.8, seed=seed)).directions == ["biased (predictions too low)"]
    assert pit_shape(pit(2000, mu=0.8, seed=seed)).directions == ["biased (predictions too high)"]
    assert pit_shape(pit(2000, mu=-1.0, s=0.5, seed=seed)).directions == ["too narrow",
                                                                         "biased (predictions too low)"]
    assert pit_shape(pit(2000, mu=0.6, s=2.0, seed=seed)).directions == ["too wide",
                                                                        "biased (predictions too high)"]
    assert pit_shape(pit(2000, seed=seed)).directions == []  # calibrated


def test_scale_reads_the_width_error():
    """Intervals s times the right width: the scores spread 1/s times wider (within 5 %)."""
    for s in (0.5, 0.8, 1.0, 1.25, 2.0):
        assert pit_shape(pit(20_000, s=s)).scale == pytest.approx(1 / s, rel=0.05)
    assert pit_shape(pit(20_000, mu=-1.0)).scale == pytest.approx(1.0, rel=0.05)  # a shift does not spread


def test_hand_computed_shares_and_mean():
    """Twelve values: 4 below 1/4, 4 above 3/4, mean 1/2; normal scores of the quartiles by hand."""
    u = np.array([0.01, 0.05, 0.1, 0.2, 0.4, 0.45, 0.55, 0.6, 0.8, 0.9, 0.95, 0.99])
    shape = pit_shape(u)
    assert (shape.lower, shape.upper, shape.outside) == (4 / 12, 4 / 12, 8 / 12)
    assert shape.mean == pytest.approx(0.5)
    z = norm.ppf(u)  # sorted; numpy's linear quantile at 0.25 of 12 values: z[2] + 0.75 (z[3] − z[2])
    q25 = z[2] + 0.75 * (z[3] - z[2])
    assert shape.scale == pytest.approx(2 * -q25 / (2 * norm.ppf(0.75)))  # symmetric: IQR = −2 q25
    assert shape.scale == pytest.approx(1.411, abs=1e-3)  # q25 = −1.2816 + 0.75 · 0.4400 = −0.9516
    # 0.411 above 1 clears the 0.15 margin but not 2 se = 2 · 1.166 / sqrt(12) = 0.673: not named
    assert not shape.narrow
    assert pit_shape(np.tile(u, 10)).narrow  # n = 120: 2 se = 0.213 < 0.411


def test_thresholds_are_the_stated_ones():
    """With many values the margins alone decide: the scale just above / below 1 + margin, the
    mean just inside / outside 1/2 ± margin."""
    n = 200_000
    assert pit_shape(pit(n, s=1 / (1 + SCALE_MARGIN + 0.03))).narrow
    assert not pit_shape(pit(n, s=1 / (1 + SCALE_MARGIN - 0.03))).narrow
    assert pit_shape(pit(n, s=1 + SCALE_MARGIN + 0.03)).wide
    assert not pit_shape(pit(n, s=1 + SCALE_MARGIN - 0.03)).wide
    rng = np.random.default_rng(1)
    for shift, named in ((BIAS_MARGIN + 0.01, "low"), (BIAS_MARGIN - 0.01, ""), (-BIAS_MARGIN - 0.01, "high")):
        u = np.mod(rng.uniform(0, 1, n) * 0.5 + 0.25 + shift, 1.0)  # mean 0.5 + shift
        assert pit_shape(u).bias == named


def test_small_calibrated_samples_stay_quiet():
    """Calibrated PIT at n = 40 (a small study): a direction is named in fewer than 1 in 10 samples."""
    named = sum(bool(pit_shape(pit(40, seed=s)).directions) for s in range(200))
    assert named < 20


def test_words_state_the_numbers():
    text = pit_shape(pit(2000, s=0.5)).text()
    assert text.startswith("predictive intervals too narrow: the observations scatter 2.0× as widely")
    assert "systematically too low" in pit_shape(pit(2000, mu=-1.0)).text()
    assert "too wide" in pit_shape(pit(2000, s=2.0)).text()
    assert pit_shape(pit(2000)).label == "no single direction"
    assert pit_shape(np.array([0.3])).directions == []
    assert pit_shape(np.array([0.0, 1.0, 0.0, 1.0] * 100)).narrow  # values of exactly 0 and 1 are clipped
