"""What a fit keeps per data row (issue 30, item 2): the storage rule, the chunked computations
against the all-at-once ones, the thinned fit's attrs, and its readers (arviz, PSIS-LOO, LOO-PIT)."""

import json

import arviz as az
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

import bayesfric
from bayesfric import limits
from bayesfric.compare import loo_pit_check, prior_sensitivity, psis_loo
from bayesfric.datasets.synthetic import simulate
from bayesfric.inference import fit, pointwise, save_fit
from bayesfric.laws import get_law
from bayesfric.model import build_program

ROWS = 120
SETTINGS = dict(draws=100, tune=150, chains=2, seed=4)


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(7)
    v = rng.choice([-1.0, 1.0], ROWS) * np.exp(rng.uniform(np.log(0.05), np.log(3.0), ROWS))
    return simulate(get_law("coulomb_viscous"), {"velocity": v}, {"T_C": 2.0, "c_v": 0.5}, sigma=0.1, seed=3)


def small_rule(mp: pytest.MonkeyPatch) -> None:
    """The thinned rule at test size: 2 chains × 100 draws × 120 rows is above FULL_NUMBERS;
    each group keeps at most 30 draws (every 7th of each chain: 15 a chain), in chunks of 5 draws."""
    mp.setattr(pointwise, "FULL_NUMBERS", 1000)
    mp.setattr(pointwise, "STORED_NUMBERS", ROWS * 30)
    mp.setattr(pointwise, "CHUNK_NUMBERS", ROWS * 5)


@pytest.fixture(scope="module")
def fits(data):
    """The same fit (same seed, same draws) stored in full and thinned."""
    full = fit(get_law("coulomb_viscous"), data, **SETTINGS)
    with pytest.MonkeyPatch.context() as mp:
        small_rule(mp)
        thin = fit(get_law("coulomb_viscous"), data, **SETTINGS)
    return full, thin


def test_the_rule_keeps_small_fits_whole_and_bounds_large_ones():
    small = pointwise.storage(rows=4000, chains=4, draws=1000)
    assert small.full and small.every == 1 and small.kept_total == 4000 and small.n_prior_predictive == 500
    for rows in (10**4, 10**5, 10**6, 10**7):
        info = pointwise.storage(rows=rows, chains=4, draws=1000)
        assert not info.full
        assert info.kept_total * rows <= max(pointwise.STORED_NUMBERS, 4 * rows)  # at least a draw a chain
        if info.every > 1:  # the smallest stride that fits
            assert 4 * len(range(0, 1000, info.every - 1)) * rows > pointwise.STORED_NUMBERS
        assert info.n_prior_predictive * rows <= max(pointwise.STORED_NUMBERS, 4 * rows)
        assert info.chunk * rows <= max(pointwise.CHUNK_NUMBERS, rows) and info.kept_total % info.chunk == 0
    info = pointwise.storage(rows=10**5, chains=4, draws=1000)
    assert (info.every, info.kept_total) == (13, 308)
    assert info.flat_index()[:3].tolist() == [0, 13, 26] and info.flat_index()[77] == 1000
    # the memory rule of limits follows it: bounded whatever the rows above the threshold
    sizes = [limits.fit_bytes(chains=4, tune=1000, draws=1000, kept=1000, params=6, rows=r) for r in (10**4, 10**6)]
    assert sizes[0] == sizes[1] < 2 * 1024**3
    assert limits.sampler_problem("nuts", {"draws": 1000, "tune": 1000, "chains": 4}, 6, 10**6,
                                  memory=8 * 1024**3) is None


@pytest.mark.parametrize("rows", [7, 64])
def test_chunked_log_mean_likelihood_equals_the_all_at_once_one(rows, monkeypatch):
    """The sampler's held-out scores: log mean_s p(y_i | θ_s) by a scan over chunks of draws
    equals the log-sum-exp over all draws at once (a row with -inf for every draw included)."""
    rng = np.random.default_rng(rows)
    y = jnp.asarray(rng.normal(size=rows))
    flat = {"mu": jnp.asarray(rng.normal(size=60)), "log_s": jnp.asarray(rng.normal(scale=0.3, size=60))}

    def pointwise_ll(d):
        ll = jax.scipy.stats.norm.logpdf(y, d["mu"], jnp.exp(d["log_s"]))
        return ll.at[0].set(-jnp.inf)

    whole = pointwise.log_mean_likelihood(pointwise_ll, flat, rows)
    monkeypatch.setattr(pointwise, "CHUNK_NUMBERS", rows * 7)  # chunks of 6 draws (the largest divisor of 60)
    chunked = jax.jit(lambda f: pointwise.log_mean_likelihood(pointwise_ll, f, rows))(flat)
    assert np.isneginf(chunked[0]) and np.isneginf(whole[0])
    np.testing.assert_allclose(np.asarray(chunked)[1:], np.asarray(whole)[1:], rtol=1e-13, atol=1e-13)


def test_a_thinned_fit_holds_the_full_fits_values_at_its_kept_draws(fits):
    full, thin = fits
    info = json.loads(thin.attrs["pointwise_storage"])
    assert info["thinned"] and info["every"] == 7 and info["kept_draws"] == 30 and info["prior_predictive_draws"] == 30
    assert info["dtypes"] == dict.fromkeys(pointwise.GROUPS, "float32")
    assert not json.loads(full.attrs["pointwise_storage"])["thinned"]
    kept = np.arange(0, 100, 7)
    assert thin["log_likelihood"]["draw"].values.tolist() == kept.tolist()
    assert thin["posterior_predictive"]["response"].shape == (2, kept.size, ROWS)
    xr.testing.assert_equal(thin["posterior"].to_dataset(), full["posterior"].to_dataset())
    for group in ("log_likelihood", "posterior_predictive"):
        stored = thin[group]["response"].values
        assert stored.dtype == np.float32
        np.testing.assert_array_equal(stored, full[group]["response"].values[:, kept].astype(np.float32))
    np.testing.assert_array_equal(thin["prior_predictive"]["response"].values,
                                  full["prior_predictive"]["response"].values[:, :30].astype(np.float32))
    for group in ("prior", "log_prior"):
        xr.testing.assert_equal(thin[group].to_dataset(), full[group].to_dataset())


def test_values_float32_would_round_too_far_stay_float64(fits, data):
    """With tolerances of zero no group may be rounded: the tables come back in float64, equal to
    the all-at-once computation at the kept draws."""
    full, _ = fits
    program = build_program(get_law("coulomb_viscous"), data)
    post = full["posterior"]
    flat = {k: post[k].values.reshape(200, *post[k].shape[2:]) for k in ("T_C", "c_v", "sigma")}
    key_pp, key_prior = jax.random.split(jax.random.PRNGKey(SETTINGS["seed"] + 1))
    with pytest.MonkeyPatch.context() as mp:
        small_rule(mp)
        mp.setattr(pointwise, "LOG_LIKELIHOOD_TOLERANCE", 0.0)
        mp.setattr(pointwise, "PREDICTIVE_TOLERANCE", 0.0)
        info = pointwise.storage(ROWS, 2, 100)
        (ll, _, pp, _, prior_pp), dtypes = pointwise.thinned_tables(program, info, flat, key_pp, key_prior)
    assert dtypes == dict.fromkeys(pointwise.GROUPS, "float64")
    index = info.flat_index()
    for got, group in ((ll, "log_likelihood"), (pp, "posterior_predictive")):
        np.testing.assert_allclose(np.asarray(got), full[group]["response"].values.reshape(200, ROWS)[index],
                                   rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.asarray(prior_pp), full["prior_predictive"]["response"].values[0, :30],
                               rtol=1e-12, atol=1e-12)


def test_loo_and_checks_run_on_a_thinned_fit_and_on_it_saved(fits, tmp_path):
    full, thin = fits
    plain = az.loo(thin, var_name="response")  # arviz on what the fit holds
    assert plain.n_samples == 30 and np.isfinite(plain.elpd)
    view = pointwise.stored_draws(thin)
    assert view["posterior"].sizes["draw"] == 15 and view["log_likelihood"]["response"].dtype == np.float64
    assert pointwise.stored_draws(full) is full
    thinned, whole = psis_loo(thin), psis_loo(full)
    assert thinned.elpd_i.shape == (ROWS,)
    assert abs(thinned.elpd - whole.elpd) < whole.se / 2  # 30 of 200 draws: same answer within its error
    pit = loo_pit_check(thin)
    assert pit.pit.shape == (ROWS,) and np.all((pit.pit >= 0) & (pit.pit <= 1 + 1e-12))  # arviz's round-off
    assert set(prior_sensitivity(thin).index) >= {"T_C", "c_v"}
    path = save_fit(thin, tmp_path / "thin.nc")
    opened = xr.open_datatree(path, engine="h5netcdf")
    assert opened["log_likelihood"]["response"].dtype == np.float32
    assert az.loo(opened, var_name="response").n_samples == 30
    again = psis_loo(bayesfric.load_fit(path)[0])
    np.testing.assert_allclose(again.elpd_i, thinned.elpd_i)


def test_log_likelihood_on_demand_matches_the_stored_full_one(fits, data):
    """Every draw's pointwise log-likelihood, computed from a thinned fit's posterior in chunks."""
    full, thin = fits
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pointwise, "CHUNK_NUMBERS", ROWS * 9)
        block = pointwise.log_likelihood(thin, data, obs=slice(10, 40))
    assert block.dims == ("chain", "draw", "obs") and block.shape == (2, 100, 30)
    np.testing.assert_allclose(block.values, full["log_likelihood"]["response"].values[:, :, 10:40],
                               rtol=1e-12, atol=1e-12)


def test_psis_loo_over_every_draw_of_a_thinned_fit_by_blocks_of_rows(fits, data):
    """docs/data.md's recipe: az.loo over blocks of rows, the log-likelihood computed on demand,
    gives a thinned fit the PSIS-LOO of all its draws, as the full fit's stored one."""
    full, thin = fits
    posterior = thin["posterior"].to_dataset()
    elpd_i = []
    for start in range(0, ROWS, 50):
        block = pointwise.log_likelihood(thin, data, obs=slice(start, start + 50))
        part = xr.DataTree.from_dict({"posterior": posterior, "log_likelihood": block.to_dataset()})
        elpd_i.append(az.loo(part, pointwise=True, var_name="response").elpd_i.values)
    whole = az.loo(full, pointwise=True, var_name="response")
    np.testing.assert_allclose(np.concatenate(elpd_i), whole.elpd_i.values, rtol=1e-10)


def test_the_fit_report_says_what_a_thinned_fit_keeps(fits):
    from bayesfric.report.tables import fit_report

    full, thin = fits
    law = get_law("coulomb_viscous")
    assert "kept per data row: 1 in 7 draws of each chain (30 of 200)" in fit_report(thin, law)
    assert "kept per data row" not in fit_report(full, law)
