"""Fold builders: partitions, blocked envelopes, trajectory rule."""

import numpy as np
import pytest

from bayesfric.compare.folds import blocked_masks, grouped_masks, kfold_masks
from bayesfric.datasets.loader import DataError


@pytest.fixture
def speeds(dataset_factory):
    v = np.linspace(0.1, 4.0, 37)
    return dataset_factory({"velocity": v}, 1.0 + 0.5 * v,
                           groups={"series": np.arange(37) % 3})


@pytest.fixture
def loops(dataset_factory):
    """Eight ordered trajectories of 5 points each; preload constant per trajectory."""
    traj = np.repeat(np.arange(8), 5)
    preload = np.repeat([10.0, 20.0, 30.0, 40.0, 10.0, 20.0, 30.0, 40.0], 5)
    amplitude = np.repeat([1e-3, 2e-3, 3e-3, 4e-3, 1e-3, 2e-3, 3e-3, 4e-3], 5)
    angle = np.tile(np.linspace(-1.0, 1.0, 5), 8) * amplitude
    return dataset_factory({"angle": angle, "preload": preload}, angle * preload,
                           groups={"loop": traj, "pair": traj // 4,
                                   "half": np.tile([0, 0, 1, 1, 1], 8)},
                           trajectory="loop")


def test_kfold_holds_each_point_out_exactly_once(speeds):
    folds = kfold_masks(speeds, k=5, seed=3)
    assert folds.train.shape == (5, 37)
    np.testing.assert_array_equal(folds.heldout.sum(axis=0), np.ones(37))
    np.testing.assert_array_equal(folds.train, ~folds.heldout)
    sizes = folds.heldout.sum(axis=1)
    assert sizes.max() - sizes.min() <= 1
    np.testing.assert_array_equal(kfold_masks(speeds, k=5, seed=3).train, folds.train)
    assert not np.array_equal(kfold_masks(speeds, k=5, seed=4).train, folds.train)


def test_grouped_folds_leave_one_level_out(speeds):
    folds = grouped_masks(speeds, "series")
    assert folds.n_folds == 3
    np.testing.assert_array_equal(folds.heldout.sum(axis=0), np.ones(37))
    series = speeds["series"].values
    for k in range(3):
        assert np.unique(series[folds.heldout[k]]).size == 1
        assert np.unique(series[folds.train[k]]).size == 2


@pytest.mark.parametrize("direction", ["upper", "lower"])
def test_blocked_trains_inside_and_scores_strictly_outside(speeds, direction):
    v = speeds["velocity"].values
    folds = blocked_masks(speeds, "velocity", threshold=2.5, direction=direction)
    train, held = v[folds.train[0]], v[folds.heldout[0]]
    if direction == "upper":
        assert train.max() <= 2.5 < held.min()
    else:
        assert train.min() >= 2.5 > held.max()
    assert folds.train[0].sum() + folds.heldout[0].sum() == v.size


def test_blocked_quantile_sets_threshold_from_the_data(speeds):
    v = speeds["velocity"].values
    folds = blocked_masks(speeds, "velocity", quantile=0.75)
    threshold = np.quantile(v, 0.75)
    np.testing.assert_array_equal(folds.heldout[0], v > threshold)


def test_blocked_uses_speed_when_both_directions_present(dataset_factory):
    v = np.concatenate([-np.linspace(0.1, 4, 20), np.linspace(0.1, 4, 20)])
    ds = dataset_factory({"velocity": v}, np.sign(v))
    folds = blocked_masks(ds, "velocity", threshold=3.0)
    np.testing.assert_array_equal(folds.heldout[0], np.abs(v) > 3.0)
    assert "|velocity|" in folds.scheme
    signed = blocked_masks(ds, "velocity", threshold=3.0, use_abs=False)
    np.testing.assert_array_equal(signed.heldout[0], v > 3.0)


def test_trajectories_are_never_split(loops):
    traj = loops["loop"].values
    for folds in (kfold_masks(loops, k=4, seed=1), grouped_masks(loops, "pair"),
                  blocked_masks(loops, "preload", threshold=25.0),
                  blocked_masks(loops, "angle", quantile=0.5),
                  blocked_masks(loops, "preload", threshold=25.0, direction="lower")):
        for mask in np.concatenate([folds.train, folds.heldout]):
            for t in np.unique(traj):
                assert np.unique(mask[traj == t]).size == 1, folds.scheme


def test_blocked_on_trajectories_uses_per_trajectory_value(loops):
    folds = blocked_masks(loops, "angle", threshold=2.5e-3)  # both signs: |angle| detected
    angle = np.abs(loops["angle"].values)
    assert angle[folds.train[0]].max() <= 2.5e-3
    # whole loops of amplitude 3e-3 and 4e-3 are scored, their inner points included
    np.testing.assert_array_equal(np.unique(loops["loop"].values[folds.heldout[0]]), [2, 3, 6, 7])
    assert angle[folds.heldout[0]].min() == 0.0


def test_blocked_on_trajectories_rejects_threshold_every_trajectory_crosses(loops):
    with pytest.raises(DataError, match="no training"):
        blocked_masks(loops, "angle", threshold=5e-4, use_abs=True)  # every loop reaches 1e-3


def test_blocked_preload_trains_on_low_preload_trajectories(loops):
    folds = blocked_masks(loops, "preload", quantile=0.5)
    preload = loops["preload"].values
    assert preload[folds.train[0]].max() <= 20.0 < preload[folds.heldout[0]].min()


def test_grouping_that_splits_a_trajectory_is_refused(loops):
    with pytest.raises(DataError, match="splits a trajectory"):
        grouped_masks(loops, "half")


def test_bad_arguments(speeds):
    with pytest.raises(ValueError, match="exactly one"):
        blocked_masks(speeds, "velocity")
    with pytest.raises(DataError, match="no input"):
        blocked_masks(speeds, "temperature", threshold=1.0)
    with pytest.raises(DataError, match="no training or no held-out"):
        blocked_masks(speeds, "velocity", threshold=10.0)
    with pytest.raises(ValueError):
        kfold_masks(speeds, k=1)


def test_leave_future_out_splits_each_trajectory_at_its_first_sample_beyond_the_cut(loops):
    """Angle runs -a .. +a along each loop: the future starts at the first angle above the cut."""
    folds = blocked_masks(loops, "angle", threshold=1.5e-3, future=True)
    # per loop the angles are a·[-1, -0.5, 0, 0.5, 1]; a·0.5 > 1.5e-3 for a = 4e-3, a·1 for a ≥ 2e-3
    expected = np.zeros(40, dtype=bool)
    for loop, amplitude in enumerate([1e-3, 2e-3, 3e-3, 4e-3] * 2):
        first = {1e-3: None, 2e-3: 4, 3e-3: 4, 4e-3: 3}[amplitude]
        if first is not None:
            expected[loop * 5 + first: loop * 5 + 5] = True
    np.testing.assert_array_equal(folds.heldout[0], expected)
    np.testing.assert_array_equal(folds.train[0], ~expected)
    assert folds.scheme.startswith("leave-future-out: each trajectory split where angle first > 0.0015")


def test_leave_future_out_on_one_record_is_the_tail_in_row_order(speeds):
    folds = blocked_masks(speeds, "velocity", quantile=0.75, future=True)
    cut = np.quantile(speeds["velocity"].values, 0.75)
    first = int(np.argmax(speeds["velocity"].values > cut))
    np.testing.assert_array_equal(folds.heldout[0], np.arange(37) >= first)
    assert "the record" in folds.scheme


def test_leave_future_out_that_never_crosses_is_an_error(loops):
    with pytest.raises(DataError, match="no training or no held-out point"):
        blocked_masks(loops, "angle", threshold=1.0, future=True)
