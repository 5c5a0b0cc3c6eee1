"""Subsampled PSIS-LOO above LOO_SUBSAMPLE_ROWS (issue 30, item 3): on a data set where the full
PSIS-LOO is also computed, the subsampled elpd lies within a few subsampling se of it, the se are
reported, and the result rebuilds from stored values as a study does. The checks above the limit
read the same rows and say so; the prior predictive check in chunks gives the same fractions."""

import numpy as np
import pytest

from bayesfric.compare import checks as checks_mod
from bayesfric.compare import evidence as evidence_mod
from bayesfric.compare import heldout as heldout_mod
from bayesfric.compare import loo_subsample as sub_mod
from bayesfric.compare.checks import loo_pit_check, prior_predictive_check, ranking_sensitivity
from bayesfric.compare.evidence import bridge_log_evidence
from bayesfric.compare.heldout import heldout_predictive
from bayesfric.compare.loo import extrapolation_penalty, loo_from_values, psis_loo
from bayesfric.compare.refit import CVResult, program_from_fit
from bayesfric.datasets.synthetic import simulate
from bayesfric.inference import fit
from bayesfric.laws import get_law
from bayesfric.model import build_program

ROWS, LIMIT, SIZE = 800, 500, 200


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(11)
    v = rng.choice([-1.0, 1.0], ROWS) * np.exp(rng.uniform(np.log(0.05), np.log(3.0), ROWS))
    return simulate(get_law("coulomb_viscous"), {"velocity": v}, {"T_C": 2.0, "c_v": 0.5}, sigma=0.1, seed=5)


@pytest.fixture(scope="module")
def results(data):
    """The full PSIS-LOO and the subsampled one (limit lowered to 500 rows, 200 scored) of one fit."""
    dt = fit(get_law("coulomb_viscous"), data, draws=300, tune=300, chains=2, seed=1)
    full = psis_loo(dt, data)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sub_mod, "LOO_SUBSAMPLE_ROWS", LIMIT)
        mp.setattr(sub_mod, "LOO_SUBSAMPLE_SIZE", SIZE)
        sub = psis_loo(dt, data)
        again = loo_from_values(dt, sub.elpd_i, sub.handling, sub.refit_failed, sub.refitted)
        no_data = psis_loo(dt)  # the program rebuilt from the fit alone: the same plpd
    return dt, full, sub, again, no_data


def test_subsampled_elpd_is_within_a_few_subsampling_se_of_the_full_one(results):
    _, full, sub, _, _ = results
    assert full.subsample is None and full.subsampling_se == 0.0
    assert sub.subsample is not None and sub.subsample.size == SIZE and sub.subsample.n_rows == ROWS
    assert sub.subsample.method == "plpd"
    assert 0 < sub.subsampling_se <= sub.se
    assert abs(sub.elpd - full.elpd) < 4 * sub.subsampling_se + 1e-6, (sub.elpd, full.elpd, sub.subsampling_se)
    assert abs(sub.se - full.se) < 0.2 * full.se
    assert abs(sub.p_loo - full.p_loo) < 2.0
    # exact rows carry the same PSIS values as the full run (same draws); the rest the approximation
    rows = sub.subsample.rows
    np.testing.assert_allclose(sub.elpd_i[rows], full.elpd_i[rows], rtol=0, atol=1e-8)
    assert np.isfinite(sub.elpd_i).all() and np.isnan(np.delete(sub.pareto_k, rows)).all()
    assert sub.elpd_data.subsampling_se == pytest.approx(sub.subsampling_se)


def test_the_subsample_is_stated_and_rebuilds_from_stored_values(results):
    _, _, sub, again, no_data = results
    assert f"subsampled: {SIZE} of {ROWS} rows, subsampling se" in str(sub)
    assert sub.subsampled.startswith(f"subsampled: {SIZE} of {ROWS} rows")
    assert again.elpd == pytest.approx(sub.elpd) and again.subsampling_se == pytest.approx(sub.subsampling_se)
    np.testing.assert_array_equal(again.subsample.rows, sub.subsample.rows)
    assert no_data.elpd == pytest.approx(sub.elpd, abs=1e-6)


def test_a_penalty_on_a_subsampled_loo_uses_only_the_rows_scored_exactly(results):
    _, _, sub, _, _ = results
    heldout = np.zeros(ROWS, dtype=bool)
    heldout[: ROWS // 2] = True
    blocked = CVResult(law=sub.law, scheme="blocked", elpd=0.0, se=0.0, elpd_i=sub.elpd_i - 0.5,
                       heldout=heldout, verdicts=[], seconds=0.0)
    penalty = extrapolation_penalty(sub, blocked)
    assert penalty.n_points == int(heldout[sub.subsample.rows].sum())
    assert penalty.per_point == pytest.approx(0.5)


# -- checks on a subsample of rows (step 2) -------------------------------------------------------
@pytest.fixture
def small_limit(monkeypatch):
    monkeypatch.setattr(sub_mod, "LOO_SUBSAMPLE_ROWS", LIMIT)
    monkeypatch.setattr(sub_mod, "LOO_SUBSAMPLE_SIZE", SIZE)


def test_checks_read_the_rows_loo_scored_exactly_and_say_how_many(results, small_limit):
    dt, full, sub, _, _ = results
    rows = sub_mod.subsample_rows(ROWS)
    np.testing.assert_array_equal(rows, np.sort(sub.subsample.rows))
    pit = loo_pit_check(dt)
    assert pit.pit.size == SIZE and pit.n_rows == ROWS and pit.subsampled
    assert f"random subsample of {SIZE} of {ROWS} rows" in pit.notes
    sens = ranking_sensitivity({"a": dt, "b": dt}, alphas=(0.5,))
    assert sens.details["rows"].startswith(f"a random subsample of {SIZE} of {ROWS} rows")
    # α = 1: the subsample's PSIS sum scaled to the data (r_eff 1 here, so not to the last digit)
    assert sens.elpd[1.0]["a"] == pytest.approx(full.elpd_i[rows].sum() * ROWS / SIZE, rel=1e-3)
    assert set(sens.elpd[0.5]) == {"a", "b"}


def test_checks_below_the_limit_read_every_row(results):
    dt, _, _, _, _ = results
    assert sub_mod.subsample_rows(ROWS) is None
    pit = loo_pit_check(dt)
    assert pit.pit.size == ROWS and not pit.subsampled and "subsample" not in pit.notes


def test_prior_predictive_check_in_chunks_of_draws_gives_the_same_fractions(data, monkeypatch):
    program = build_program(get_law("stribeck"), data)
    whole = prior_predictive_check(program, draws=60, seed=3)
    monkeypatch.setattr(checks_mod, "CHUNK_NUMBERS", 7 * (ROWS + 200))  # 7 draws a chunk, 9 chunks
    chunked = prior_predictive_check(program, draws=60, seed=3)
    assert chunked == whole


# -- bounded memory in the study path (step 3) ----------------------------------------------------
def test_heldout_predictive_in_chunks_of_draws_equals_the_one_chunk_result(results, data, monkeypatch):
    dt = results[0]
    program = build_program(get_law("coulomb_viscous"), data)
    post = dt["posterior"]
    samples = {k: np.asarray(post[k].values)[None] for k in post.data_vars}
    heldout = np.zeros((1, ROWS), dtype=bool)
    heldout[0, ROWS // 3:] = True
    whole = heldout_predictive(program, samples, heldout)
    monkeypatch.setattr(heldout_mod, "CHUNK_NUMBERS", 140 * ROWS)  # 140 draws a chunk, the last one short
    chunked = heldout_predictive(program, samples, heldout)
    np.testing.assert_array_equal(chunked.mu, whole.mu)
    np.testing.assert_array_equal(chunked.noise_var, whole.noise_var)


def test_bridge_evidence_in_chunks_of_points_equals_the_one_call_result(results, data, monkeypatch):
    dt = results[0]
    program = program_from_fit(dt, data)
    whole = bridge_log_evidence(program, dt, seed=2)
    monkeypatch.setattr(evidence_mod, "CHUNK_NUMBERS", 55 * ROWS)  # 55 points a call, the last one padded
    chunked = bridge_log_evidence(program, dt, seed=2)
    assert chunked.log_z == pytest.approx(whole.log_z, rel=1e-12, abs=1e-9)
    assert chunked.error == pytest.approx(whole.error, rel=1e-9)


def test_compare_laws_shows_the_subsampling_se(results, data):
    """The public ranking table carries the subsampling error of a subsampled LOO (NaN otherwise)."""
    import bayesfric

    dt, _, sub, _, _ = results
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sub_mod, "LOO_SUBSAMPLE_ROWS", LIMIT)
        mp.setattr(sub_mod, "LOO_SUBSAMPLE_SIZE", SIZE)
        table = bayesfric.compare_laws({"cv": dt}, data)
    assert table.loc["cv", "subsampling_se"] == pytest.approx(sub.subsampling_se)
    assert table.loc["cv", "elpd_loo"] == pytest.approx(sub.elpd)
    assert np.isnan(bayesfric.compare_laws({"cv": dt}, data).loc["cv", "subsampling_se"])
