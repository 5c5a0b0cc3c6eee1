"""Extrapolation distance per direction: a point is measured against the data on its own side of
zero (bayesfric.sizing.distance), so data reaching +0.5 but only −0.13 rad/s put −0.35 rad/s
beyond them, where the distance on |v| alone said it was inside."""

from __future__ import annotations

import numpy as np
import pytest

from bayesfric import sizing
from bayesfric.sizing.distance import point_distance
from tests.sizing_helpers import hand_fit

#: Asymmetric data: the positive side reaches 0.5 rad/s, the negative side only -0.13 rad/s.
ASYM = np.array([-0.13, -0.08, -0.02, 0.01, 0.1, 0.3, 0.5])


def test_a_point_is_measured_against_the_data_of_its_own_sign():
    width = 0.5 - 0.01  # the unit: the tested range of |v| over both sides
    d = point_distance([0.35, -0.35, 0.8, -0.8, -0.1], ASYM)
    np.testing.assert_allclose(d, [0.0, (0.35 - 0.13) / width, 0.3 / width, (0.8 - 0.13) / width, 0.0])


def test_symmetric_and_one_signed_data_keep_the_distance_they_had():
    sym = np.array([-2.0, -1.0, -0.1, 0.1, 1.0, 2.0])
    np.testing.assert_allclose(point_distance([4.0, -4.0, 0.05], sym), [2 / 1.9, 2 / 1.9, 0.05 / 1.9])
    one = np.linspace(0.1, 2.0, 12)
    np.testing.assert_allclose(point_distance([4.0, 0.0], one), [2 / 1.9, 0.1 / 1.9])
    np.testing.assert_array_equal(point_distance([3.0, 3.5], np.array([3.0, 3.0])), [0.0, np.inf])


@pytest.mark.parametrize(("at", "expected"), [("0.35 rad/s", 0.0), ("-0.35 rad/s", (0.35 - 0.13) / 0.49)])
def test_an_answer_reports_the_distance_of_its_direction(at, expected):
    draws = {"T_C": np.full((2, 50), 1.0), "sigma": np.full((2, 50), 0.1)}
    fit = hand_fit("coulomb", draws, {"velocity": ASYM})
    question = sizing.check_question(sizing.make_question({"velocity": at}, 0.9), ["velocity"], ["velocity"],
                                     "torque")
    answer = sizing.answer_question(question, [sizing.LawSource("coulomb", fit, {})], {"velocity": ASYM}, seed=0)
    assert answer.distance["velocity"][0] == pytest.approx(expected)
