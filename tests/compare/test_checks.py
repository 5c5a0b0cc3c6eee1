"""Prior predictive plausibility, LOO-PIT, power-scaling prior sensitivity and ranking stability."""

import dataclasses

import numpy as np
import pytest

from bayesfric.compare.checks import (
    loo_pit_check,
    power_scaled_loo,
    prior_predictive_check,
    prior_sensitivity,
    ranking_sensitivity,
    sign_rule,
)
from bayesfric.inference import fit
from bayesfric.laws import get_law
from bayesfric.model import Noise, build_program
from bayesfric.priors import Prior

VELOCITY = np.linspace(-2.0, 2.0, 24)
TRUTH = {"T_C": 1.0, "c_v": 0.8}
SETTINGS = dict(draws=300, tune=300, chains=2)


@pytest.fixture(scope="module")
def viscous_data():
    from bayesfric.datasets.synthetic import simulate

    return simulate(get_law("coulomb_viscous"), {"velocity": VELOCITY}, TRUTH, sigma=0.1, seed=3)


@pytest.fixture(scope="module")
def fits(viscous_data):
    """The true law and a clearly misspecified one (no viscous term) on the same data."""
    return {name: fit(get_law(name), viscous_data, seed=1, **SETTINGS)
            for name in ("coulomb_viscous", "coulomb")}


# Tests below fit laws with NUTS (compile + sample, ~10 s per fit on 2 shared cores): slow.


# -- prior predictive ------------------------------------------------------------------------------
def test_default_priors_of_classical_laws_are_plausible(viscous_data):
    for name in ("coulomb_viscous", "stribeck"):
        report = prior_predictive_check(build_program(get_law(name), viscous_data), draws=200)
        assert report.implausible == 0.0 and report.non_finite == 0.0, report


def test_a_sign_agnostic_prior_is_flagged_at_the_expected_rate(viscous_data):
    # T_C ~ Normal(0, 1): friction of 'coulomb' has the wrong sign exactly when T_C < 0 (p = 1/2)
    program = build_program(get_law("coulomb"), viscous_data,
                            priors={"T_C": Prior("Normal", loc=0.0, scale=1.0)})
    report = prior_predictive_check(program, draws=400, seed=2)
    assert report.sign_rule.startswith("opposes motion")
    assert abs(report.wrong_sign - 0.5) < 0.1  # binomial sd 0.025
    assert report.implausible == report.wrong_sign


def test_static_below_kinetic_is_checked_where_the_law_declares_both(viscous_data):
    stribeck = get_law("stribeck")
    default = prior_predictive_check(build_program(stribeck, viscous_data), draws=200)
    assert default.static_below_kinetic == 0.0  # T_s = T_C + dT_s with dT_s >= 0 by construction
    free = build_program(stribeck, viscous_data, priors={"dT_s": Prior("Normal", loc=0.0, scale=0.5)})
    report = prior_predictive_check(free, draws=400, seed=1)
    assert abs(report.static_below_kinetic - 0.5) < 0.1  # T_s < T_C exactly when dT_s < 0
    coulomb = prior_predictive_check(build_program(get_law("coulomb"), viscous_data), draws=50)
    assert coulomb.static_below_kinetic is None


def test_load_driven_laws_must_not_give_negative_torque(dataset_factory):
    law = get_law("rothe_erde")
    ds = dataset_factory({"bending_moment": np.linspace(0.0, 6e6, 10)}, np.linspace(1e3, 5e3, 10))
    assert sign_rule(build_program(law, ds)).startswith("load-driven")


# -- posterior predictive and sensitivity ----------------------------------------------------------
@pytest.mark.slow
def test_loo_pit_separates_a_calibrated_fit_from_an_overconfident_one(viscous_data, fits):
    good = loo_pit_check(fits["coulomb_viscous"])
    assert good.pit.shape == (VELOCITY.size,) and np.all((good.pit >= 0) & (good.pit <= 1))
    assert good.within_band and good.ks_pvalue > 0.01
    # a "known" noise sd of a third of the true one: PIT values pile up near 0 and 1
    overconfident = fit(get_law("coulomb_viscous"), viscous_data, seed=1,
                        noise=Noise(sigma=0.03), **SETTINGS)
    bad = loo_pit_check(overconfident)
    assert not bad.within_band and bad.ks_pvalue < 0.01


@pytest.mark.slow
def test_prior_sensitivity_detects_a_conflicting_prior(viscous_data, fits):
    weak = prior_sensitivity(fits["coulomb_viscous"])
    assert set(weak.index) >= {"T_C", "c_v", "sigma"}
    assert weak.loc["T_C", "prior"] < 0.05
    strong = fit(get_law("coulomb_viscous"), viscous_data, seed=1,
                 priors={"T_C": Prior("Normal", loc=1.6, scale=0.05)}, **SETTINGS)
    assert prior_sensitivity(strong).loc["T_C", "prior"] > 0.05


@pytest.mark.slow
def test_power_scaling_by_one_is_plain_loo(fits):
    import arviz as az

    dt = fits["coulomb_viscous"]
    assert power_scaled_loo(dt, 1.0).elpd == pytest.approx(az.loo(dt).elpd, abs=0.05)


@pytest.mark.slow
def test_ranking_sensitivity_reuses_the_plain_loo_it_is_given(fits):
    """A study hands over each fit's PSIS-LOO (``LooResult.psis``): the α = 1 results are taken
    from it, and every number is the one computed from scratch."""
    from bayesfric.compare.loo import psis_loo

    baseline = {name: psis_loo(dt).psis for name, dt in fits.items()}
    assert ranking_sensitivity(fits, baseline=baseline) == ranking_sensitivity(fits)
    marked = {name: dataclasses.replace(b, elpd=b.elpd + 100.0) for name, b in baseline.items()}
    assert ranking_sensitivity(fits, baseline=marked).elpd[1.0] == {n: b.elpd for n, b in marked.items()}


@pytest.mark.slow
def test_ranking_of_clearly_different_laws_is_stable_under_prior_scaling(fits):
    result = ranking_sensitivity(fits, alphas=(0.5, 2.0))
    assert set(result.elpd) == {1.0, 0.5, 2.0}
    assert result.ranking[1.0] == ["coulomb_viscous", "coulomb"]
    assert not result.changed
    weaker = result.elpd[0.5]["coulomb_viscous"]
    assert weaker != result.elpd[1.0]["coulomb_viscous"]  # the reweighting did something


def test_ranking_sensitivity_names_the_laws_whose_reweighting_has_high_pareto_k():
    """k̂ above 0.7 (or NaN) at some α makes that law's reweighted elpd approximate, and the
    study's sensitivity sentence says for which law and α."""
    from bayesfric.compare.checks import RankingSensitivity
    from bayesfric.report.findings import _high_k_note

    ks = {1.0: {"a": 0.3, "b": 0.4}, 0.5: {"a": 0.71, "b": 0.2}, 2.0: {"a": 0.9, "b": float("nan")}}
    sens = RankingSensitivity(elpd={}, ranking={}, max_pareto_k=ks, changed=False)
    assert sens.unreliable() == {"a": [0.5, 2.0], "b": [2.0]}
    assert _high_k_note(sens) == "; approximate for a (α = 0.5, 2), b (α = 2): Pareto k̂ above 0.7"
    calm = RankingSensitivity(elpd={}, ranking={}, max_pareto_k={1.0: {"a": 0.1}}, changed=False)
    assert calm.unreliable() == {} and _high_k_note(calm) == ""
