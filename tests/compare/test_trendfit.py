"""Lack of fit along service time (bayesfric.compare.trendfit) and the statement a time to exceed
leads with (bayesfric.sizing.bend): the curvature t-test by hand, its false alarm and power by
simulation on synthetic campaign levels, and the statements' words."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bayesfric.compare.trendfit import ALPHA, Bend, curvature_test
from bayesfric.sizing.bend import CARRY, law_attrs, lead, point_bend, statement

pytestmark = pytest.mark.fast

HOURS = np.arange(7) * 500.0  # the benchmark's seven trained campaigns


def _residuals(levels: np.ndarray) -> np.ndarray:
    """Levels minus their least-squares line: what a fitted linear trend leaves."""
    design = np.column_stack([np.ones_like(HOURS), HOURS])
    return levels - design @ np.linalg.lstsq(design, levels, rcond=None)[0]


def test_the_statistic_is_the_quadratic_terms_t_of_the_levels_themselves():
    """Frisch-Waugh: the deviations from a fitted line, regressed on 1, x, x², give the quadratic
    term's t of a quadratic fit to the levels, with G − 3 degrees of freedom."""
    rng = np.random.default_rng(0)
    levels = 0.7 + 2e-4 * HOURS + 3e-8 * HOURS**2 + 0.02 * rng.normal(size=7)
    design = np.column_stack([np.ones(7), HOURS, HOURS**2])
    coef, rss, *_ = np.linalg.lstsq(design, levels, rcond=None)
    se = np.sqrt(rss[0] / 4 * np.linalg.inv(design.T @ design)[2, 2])
    bend = curvature_test(HOURS, _residuals(levels))
    assert bend.t == pytest.approx(coef[2] / se, rel=1e-9) and bend.df == 4 and bend.campaigns == 7
    assert bend.p_up == pytest.approx(stats.t.sf(bend.t, 4)) and bend.p_up + bend.p_down == pytest.approx(1.0)
    assert curvature_test(HOURS, levels).t == pytest.approx(bend.t)  # a line in the deviations changes nothing


def test_false_alarm_and_power_on_synthetic_levels():
    """Levels scattering 3 % about a line: each direction flagged in ALPHA of data sets. About a
    parabola whose quadratic term is 3 standard errors: flagged upward as often as the noncentral
    t says, never downward."""
    rng = np.random.default_rng(1)
    n, sd = 2000, 0.03
    null = [curvature_test(HOURS, _residuals(0.7 + 1e-4 * HOURS + sd * rng.normal(size=7))).direction
            for _ in range(n)]
    band = 3 * np.sqrt(ALPHA * (1 - ALPHA) / n)
    assert abs(np.mean(np.asarray(null) == "upward") - ALPHA) < band
    assert abs(np.mean(np.asarray(null) == "downward") - ALPHA) < band
    x = (HOURS - 1500.0) / 1500.0
    q = x**2 - np.mean(x**2)
    c = 3.0 * sd / np.sqrt(np.sum(q**2))  # ncp 3 (q is orthogonal to 1 and x)
    alt = np.asarray([curvature_test(HOURS, _residuals(0.7 + c * x**2 + sd * rng.normal(size=7))).direction
                      for _ in range(n)])
    power = 1 - stats.nct.cdf(stats.t.ppf(1 - ALPHA, 4), 4, 3.0)
    assert abs(np.mean(alt == "upward") - power) < 3 * np.sqrt(power * (1 - power) / n)
    assert np.mean(alt == "downward") < 0.005


def test_too_few_campaigns_are_not_tested():
    assert curvature_test(HOURS[:3], [0.0, 0.1, 0.0]) is None
    assert curvature_test([0.0, 0.0, 1.0, 1.0], [0.0, 0.1, 0.0, 0.1]) is None  # two distinct times
    assert curvature_test(np.append(HOURS[:3], np.nan), [0.0, 0.1, 0.0, 0.2]) is None


def test_a_bend_at_the_operating_point_is_campaign_friction_against_the_trends():
    trend = np.log(3.0 + HOURS / 3000.0)
    campaigns = trend + 0.03 * ((HOURS - 1500.0) / 1500.0) ** 2 + 1e-3 * np.array([1, -1, 0, 1, -1, 0, 1])
    assert point_bend(HOURS, campaigns, trend).direction == "upward"
    assert point_bend(HOURS, 2 * trend - campaigns, trend).direction == "downward"
    assert point_bend(HOURS, campaigns, None) is None  # a walk


def test_an_upward_bend_marks_the_answer_and_says_what_would_settle_it():
    up = law_attrs(Bend(0.05, 0.01, 5.0, 4, 0.004, 0.996, 7), "linear")
    assert up["bend"] == "upward" and up["shape_calibrated"] == 0
    text = up["statement"]
    assert text.startswith("The campaign levels bend upward") and "EARLIER" in text
    assert "not calibrated for this shape" in text and 'trend_form = "loglinear"' in text
    assert "a test campaign nearer the horizon" in text and "t = 5.00" in text
    assert "none is built in" in law_attrs(Bend(0.05, 0.01, 5.0, 4, 0.004, 0.996, 7), "loglinear")["statement"]
    down = law_attrs(Bend(-0.05, 0.01, -5.0, 4, 0.996, 0.004, 7), "linear")
    assert down["shape_calibrated"] == 1 and "errs safe" in down["statement"] and "later" in down["statement"]
    flat = law_attrs(Bend(0.0, 0.01, 0.0, 4, 0.5, 0.5, 7), "linear")
    assert flat["bend"] == "none" and flat["statement"] == "" and flat["shape_calibrated"] == 1
    walk = law_attrs(None, "walk")
    assert walk["bend"] == "not tested" and "random walk" in walk["bend_test"]
    assert statement("none", "linear", "") == ""


def test_an_average_leads_with_it_only_where_every_law_carrying_weight_bends():
    up = law_attrs(Bend(0.05, 0.01, 5.0, 4, 0.004, 0.996, 7), "linear") | {"form": "linear"}
    up2 = law_attrs(Bend(0.04, 0.01, 4.0, 4, 0.008, 0.992, 7), "loglinear") | {"form": "loglinear"}
    flat = law_attrs(Bend(0.0, 0.01, 0.0, 4, 0.5, 0.5, 7), "linear") | {"form": "linear"}
    both = lead({"a": up, "b": up2}, {"a": 0.6, "b": 0.4})
    assert both["shape_calibrated"] == 0 and both["statement"].startswith("In every law carrying")
    assert "a 0.60, b 0.40" in both["statement"] and 'trend_form = "loglinear"' in both["statement"]
    mixed = lead({"a": up, "b": flat}, {"a": 0.6, "b": 0.4})
    assert mixed["bend"] == "mixed" and mixed["statement"] == "" and mixed["shape_calibrated"] == 1
    light = lead({"a": up, "b": flat}, {"a": 0.9, "b": 0.9 * CARRY / 2})  # b below CARRY of the weight
    assert light["shape_calibrated"] == 0
    walk = lead({"a": up, "w": law_attrs(None, "walk")}, {"a": 0.5, "w": 0.5})
    assert walk["statement"] == "" and walk["bend"] == "mixed"
