"""Leave-future-out on one long trajectory: the state is carried across the split."""

import numpy as np
import pytest
from scipy.stats import norm

from bayesfric.compare.folds import blocked_masks
from bayesfric.compare.refit import RefitEngine, cross_validate
from bayesfric.datasets.synthetic import simulate
from bayesfric.laws import get_law
from bayesfric.model import build_program


@pytest.mark.slow
def test_one_recording_is_cross_validated_past_to_future():
    """Two hysteresis cycles recorded as ONE trajectory; train on the first 60 % of the time.

    The future's pointwise predictive density must be close to that of a perfect prediction
    (within 1 nat per point on average): it is scored from the bristle state the past inputs
    produced. Restarting the trajectory at the split would put the torque at the start value
    instead, many noise widths from the data.
    """
    law = get_law("dahl")
    t = np.linspace(0.0, 20.0, 160)
    angle = 2e-3 * np.sin(2 * np.pi * t / 10.0)
    truth = {"F_c0": 0.05, "gamma": 1.0, "x_c0": 4e-4, "i": 1.5}
    sigma = 1e-3
    ds = simulate(law, {"angle": angle, "preload": np.full(t.size, 89.0), "time": t}, truth, sigma=sigma,
                  seed=4, groups={"run": np.zeros(t.size, dtype=int)}, trajectory="run")
    folds = blocked_masks(ds, "time", threshold=12.0, future=True)
    assert folds.heldout[0].sum() == int((t > 12.0).sum())
    engine = RefitEngine.build(build_program(law, ds), draws=500, tune=500, chains=2, seed=1)
    result = cross_validate(engine, folds, seed=1)
    scored = result.elpd_i[result.heldout]
    assert np.isfinite(scored).all()
    # a perfectly predicted point with noise σ scores log N(0 | 0, σ) − ½ on average
    oracle = norm.logpdf(0.0, 0.0, sigma) - 0.5
    assert scored.mean() > oracle - 1.0, (scored.mean(), oracle)
