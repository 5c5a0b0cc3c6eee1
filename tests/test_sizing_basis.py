"""Which weights and misses answer a sizing question (issue #28): the direction a question
extrapolates in, the fallback when no blocked fold tests it, and the measured miss by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesfric import compare
from bayesfric.compare.heldout import HeldOut
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.sizing import LOO, choose_basis
from bayesfric.sizing.calibration import GROWTH, OFFSET, Miss, Scheme, matching, measure_miss, relative_sd
from tests.sizing_helpers import PASSED

DATA = {"temperature": np.linspace(292.0, 311.0, 20), "velocity": np.linspace(10.0, 150.0, 20)}
WARM = Scheme("train ≤ 30 °C", "temperature", "upper")
COLD = Scheme("train ≥ 23 °C", "temperature", "lower")
WEIGHTS = {"a": {LOO: 0.3, WARM.label: 0.9, COLD.label: 0.2}, "b": {LOO: 0.7, WARM.label: 0.1, COLD.label: 0.8}}


def _basis(grid, schemes, misses=None):
    return choose_basis(grid, DATA, schemes, ["a", "b"], WEIGHTS, misses or {}, {})


def test_a_cold_start_is_weighed_by_the_fold_that_scores_cold():
    cold_start = {"temperature": np.array([278.15]), "velocity": np.array([140.0])}
    basis = _basis(cold_start, [WARM, COLD])
    assert basis.schemes == (COLD,) and basis.weights == pytest.approx({"a": 0.2, "b": 0.8})
    assert not basis.uncovered and "extrapolate in this direction" in basis.note


def test_no_fold_in_the_direction_falls_back_to_loo_and_says_so_first():
    cold_start = {"temperature": np.array([278.15]), "velocity": np.array([140.0])}
    misses = {"a": {WARM.label: Miss(WARM.label, 1e-3, 1e-3, 1e-4, 10, 0.5)}}
    basis = _basis(cold_start, [WARM], misses)
    assert basis.key == "stacking LOO" and basis.weights == pytest.approx({"a": 0.3, "b": 0.7})
    assert [(s.axis, s.direction) for s in basis.uncovered] == [("temperature", "lower")]
    assert basis.note.startswith("NO blocked fold tests temperature below the data")
    # the fallback rate is unit-free: per (tested range)^GROWTH of the full data (19 K wide)
    assert basis.fallback_rate == pytest.approx(1e-3 * 19.0**GROWTH)


def test_inside_the_envelope_loo_weights_and_no_widening():
    inside = {"temperature": np.array([300.0]), "velocity": np.array([50.0])}
    basis = _basis(inside, [WARM, COLD])
    assert basis.key == "stacking LOO" and not basis.schemes and not basis.uncovered
    assert relative_sd(inside, DATA, {}, [WARM, COLD], [], math.nan, [])[0] == 0.0


def test_signed_inputs_are_judged_on_their_magnitude():
    data = {"velocity": np.linspace(-4.0, 4.0, 17)}
    scheme = Scheme("|v| high", "velocity", "upper", use_abs=True)
    matched, uncovered = matching({"velocity": np.array([-6.0])}, data, [scheme])
    assert matched == [scheme] and not uncovered  # −6 rad/s lies beyond |v| ≤ 4 as +6 does


def test_relative_sd_grows_with_the_distance_by_hand():
    rate = 2e-4
    misses = {WARM.label: Miss(WARM.label, rate, rate, 1e-5, 10, 0.5)}
    grid = {"temperature": np.array([311.0 + 9.5]), "velocity": np.array([50.0])}  # 0.5 tested ranges above
    rel = relative_sd(grid, DATA, misses, [WARM], [WARM], math.nan, [])
    assert rel[0] == pytest.approx(rate * (19.0 * (0.5 + OFFSET)) ** GROWTH)


def _cv(y, mu, heldout):
    index = np.flatnonzero(heldout)
    return compare.CVResult("law", "blocked", 0.0, 0.0, np.zeros(y.size), heldout, [PASSED], 0.0,
                            predictive=HeldOut(index, np.zeros(index.size, dtype=int), mu, np.full(index.size, 1e-4)))


def test_the_miss_rate_is_recovered_and_is_zero_for_a_law_that_does_not_miss():
    v = np.linspace(1.0, 2.0, 21)
    ds = make_dataset({"velocity": v}, np.ones(v.size))
    heldout = v > 1.5
    scheme = Scheme("blocked", "velocity", "upper")
    d = (v[heldout] - 1.5) / 0.5
    mean = 10.0 * np.ones(heldout.sum())
    mu = mean + 1e-3 * np.random.default_rng(0).standard_normal((400, mean.size))  # tight fold posterior
    truth = mean * (1 + 0.05 * (0.5 * (d + OFFSET)) ** GROWTH)  # a 5 % miss rate per (input unit)^GROWTH
    y = np.ones(v.size)
    y[heldout] = truth
    miss = measure_miss(_cv(y, mu, heldout), ds.assign(torque=("obs", y)), scheme)
    assert miss.beta == pytest.approx(0.05, rel=0.05) and miss.rate == pytest.approx(0.05, rel=0.05)
    y[heldout] = mu.mean(axis=0)  # no miss at all
    none = measure_miss(_cv(y, mu, heldout), ds.assign(torque=("obs", y)), scheme)
    assert none.rate == 0.0


def test_a_new_group_answer_inside_the_envelope_is_weighed_by_leave_one_group_out():
    from bayesfric.sizing import NEW_GROUP

    inside = {"temperature": np.array([300.0]), "velocity": np.array([100.0])}
    grouped = {"a": {**WEIGHTS["a"], NEW_GROUP: 0.95}, "b": {**WEIGHTS["b"], NEW_GROUP: 0.05}}
    basis = choose_basis(inside, DATA, [WARM, COLD], ["a", "b"], grouped, {}, {})
    assert basis.key == "stacking leave-one-group-out" and basis.weights == pytest.approx({"a": 0.95, "b": 0.05})
    assert "a whole group it had not seen" in basis.note and not basis.schemes
    cold_start = {"temperature": np.array([278.15]), "velocity": np.array([140.0])}  # a blocked fold scores it
    assert choose_basis(cold_start, DATA, [WARM, COLD], ["a", "b"], grouped, {}, {}).weights == pytest.approx(
        {"a": 0.2, "b": 0.8})
    assert _basis(inside, [WARM, COLD]).key == "stacking LOO"  # no group terms: LOO as before
