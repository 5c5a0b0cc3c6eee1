"""Both backends return the same DataTree contract; the gate; saving; noise models."""

import json
from dataclasses import replace
from pathlib import Path

import arviz as az
import numpy as np
import pytest
import xarray as xr

import bayesfric
from bayesfric.datasets.synthetic import simulate
from bayesfric.inference import GATE, check, fit, save_fit, verdict_of
from bayesfric.inference.diagnostics import Verdict, check_folds
from bayesfric.laws import get_law
from bayesfric.model import Noise

GROUPS = {"posterior", "sample_stats", "log_likelihood", "posterior_predictive", "prior",
          "prior_predictive", "observed_data", "constant_data"}
PROVENANCE = {"law", "priors", "data_hash", "sampler", "sampler_settings", "seed", "versions", "diagnostics"}


@pytest.fixture(scope="module")
def small_ds():
    v = np.linspace(-3, 3, 30)
    return simulate(get_law("coulomb_viscous"), {"velocity": v}, {"T_C": 2.0, "c_v": 0.5}, sigma=0.1, seed=3,
                    groups={"series": np.tile([1, 2, 3], 10)})


@pytest.mark.parametrize("sampler", ["nuts", "emcee"])
def test_datatree_contract(small_ds, sampler, tmp_path):
    settings = dict(draws=300, tune=300, chains=2) if sampler == "nuts" else dict(draws=600, tune=600, walkers=16)
    dt = fit(get_law("coulomb_viscous"), small_ds, sampler=sampler, seed=1, **settings)
    assert GROUPS <= set(dt.children)
    assert PROVENANCE <= set(dt.attrs)
    assert dt.attrs["sampler"] == sampler and dt.attrs["law"] == "coulomb_viscous"
    assert dt["log_likelihood"]["response"].dims[-1] == "obs"
    assert dt["posterior_predictive"]["response"].shape[-1] == 30
    assert set(dt["posterior"].data_vars) >= {"T_C", "c_v", "sigma"}
    assert set(dt["prior"].data_vars) >= {"T_C", "c_v", "sigma"}
    assert "series" in dt["observed_data"].coords
    # verdict stored with the fit equals a fresh check
    # the stored verdict is the gate's, with why chains that disagree are not modes (inference.modes)
    assert replace(verdict_of(dt), mode_note="") == check(dt)
    path = save_fit(dt, tmp_path / "sub" / "fit.nc")
    assert not list(path.parent.glob(".*.tmp"))
    plain = xr.open_datatree(path)
    summary = az.summary(plain)
    assert {"T_C", "c_v", "sigma"} <= set(summary.index)
    again, program = bayesfric.load_fit(path)
    assert program.law.name == dt.attrs["law"]
    np.testing.assert_array_equal(again["posterior"]["T_C"].values, dt["posterior"]["T_C"].values)


def test_gate_flags_unmixed_chains(small_ds):
    dt = fit(get_law("coulomb"), small_ds, draws=200, tune=200, chains=2, seed=0)
    post = dt["posterior"].to_dataset()
    shifted = post.copy()
    shifted["T_C"] = post["T_C"] + xr.DataArray([0.0, 1.0], dims="chain")  # chains disagree
    dt["posterior"] = shifted
    verdict = check(dt)
    assert not verdict.passed
    assert any("R-hat" in p for p in verdict.problems)
    assert verdict.rhat_max > GATE.rhat_max


def test_gate_per_fold_in_one_pass_equals_the_gate_per_fold():
    """check_folds (one arviz-stats pass over a fold dimension) gives each fold check()'s verdict."""
    rng = np.random.default_rng(0)
    shape = (3, 4, 500)  # fold, chain, draw
    post = xr.Dataset({"a": (("fold", "chain", "draw"), rng.normal(size=shape)),
                       "b": (("fold", "chain", "draw", "b_dim_0"), rng.normal(size=shape + (2,)))})
    post["a"][1] = post["a"][1] + xr.DataArray([0.0, 0.0, 0.0, 2.0], dims="chain")  # fold 1: a chain apart
    energy = rng.normal(size=shape).cumsum(axis=-1) * 0.05 + rng.normal(size=shape)
    diverging = np.zeros(shape, dtype=bool)
    diverging[2, 0, :3] = True  # fold 2: three divergent transitions
    stats = xr.Dataset({"diverging": (("fold", "chain", "draw"), diverging),
                        "energy": (("fold", "chain", "draw"), energy)})
    together = check_folds(post, stats)
    alone = [check(xr.DataTree.from_dict({"posterior": post.isel(fold=k), "sample_stats": stats.isel(fold=k)}))
             for k in range(3)]
    assert together == alone
    assert [v.passed for v in together] == [True, False, False]
    assert any("R-hat" in p for p in together[1].problems) and together[2].divergences == 3


def test_the_gate_tells_unidentified_parameters_from_an_unconverged_fit():
    """When the chains disagree, the pointwise log-likelihood says why: on a ridge (a + b fixed by
    the data, a and b not) every chain fits each row alike, and the verdict says the parameters are
    not identified; with chains in separate modes of the fit itself it says so instead."""
    from scipy.stats import norm

    rng = np.random.default_rng(1)
    chains, draws, rows = 4, 500, 30
    y = rng.normal(size=rows)
    total = rng.normal(0.0, 0.05, size=(chains, draws))  # a + b: alike in every chain

    def verdict(total: np.ndarray):
        a = total / 2 + np.arange(chains)[:, None]  # each chain at another place on the ridge
        ll = norm.logpdf(y, loc=total[..., None])
        return check(xr.DataTree.from_dict({
            "posterior": xr.Dataset({"a": (("chain", "draw"), a), "b": (("chain", "draw"), total - a)}),
            "log_likelihood": xr.Dataset({"y": (("chain", "draw", "obs"), ll)})}))

    ridge = verdict(total)
    assert not ridge.passed and ridge.rhat_max > 2 and ridge.predictions_converged is True
    assert ridge.loglik_rhat_max <= GATE.rhat_max and ridge.loglik_ess_bulk_min >= GATE.ess_bulk_min
    assert "the parameters are not identified from these data" in str(ridge)
    modes = verdict(total + 0.5 * np.arange(chains)[:, None])  # the chains fit the data differently
    assert not modes.passed and modes.predictions_converged is False and modes.loglik_rhat_max > 1.1
    assert "disagree on the fit to the data itself" in str(modes)
    mixed = check(xr.DataTree.from_dict({"posterior": xr.Dataset({"a": (("chain", "draw"), total)})}))
    assert mixed.passed and mixed.predictions_converged is None and mixed.predictions_note == ""
    assert Verdict.from_json(ridge.to_json()) == ridge  # stored with the fit and read back


def test_gate_thresholds_in_one_place():
    assert (GATE.rhat_max, GATE.ess_bulk_min, GATE.ess_tail_min, GATE.divergences_max, GATE.ebfmi_min) == (
        1.01, 400.0, 400.0, 0, 0.3)


@pytest.mark.parametrize("noise", [Noise("student_t"), Noise("proportional"), Noise("normal", group="series")])
def test_noise_models_sample(small_ds, noise):
    dt = fit(get_law("coulomb_viscous"), small_ds, noise=noise, draws=150, tune=150, chains=1, seed=2)
    post = dt["posterior"]
    for site in noise.sites():
        assert site in post.data_vars
    if noise.group:
        assert post["group_offset"].shape[-1] == 3
    assert np.all(np.isfinite(dt["log_likelihood"]["response"].values))


def test_known_sigma_is_not_sampled(small_ds):
    dt = fit(get_law("coulomb_viscous"), small_ds, noise=Noise(sigma=0.1), draws=100, tune=100, chains=1)
    assert "sigma" not in dt["posterior"].data_vars


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux /proc")
def test_release_compiled_code_frees_memory_mappings(simulator):
    """A fit leaves compiled code mapped; releasing it must bring the mapping count back down."""
    from bayesfric.inference import release_compiled_code

    def mappings():
        return len(Path("/proc/self/maps").read_text().splitlines())

    law = get_law("coulomb_viscous")
    ds = simulator(law, {"velocity": np.linspace(-2, 2, 20)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.05, seed=0)
    release_compiled_code()
    before = mappings()
    fit(law, ds, draws=50, tune=50, chains=2)
    grown = mappings()
    release_compiled_code()
    assert grown - before > 20  # the fit's compiled code is mapped (74 mappings measured, 2026-11-23)
    assert mappings() - before < 0.2 * (grown - before)


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux /proc")
def test_release_clears_jax_caches_only_above_the_mappings_budget(monkeypatch):
    """Between a study's laws JAX's caches (small eager programs every law shares) are kept
    while the process holds fewer mappings than the budget; the law's own programs always go."""
    import bayesfric.inference as inference

    cleared, forgotten = [], []
    monkeypatch.setattr(inference.jax, "clear_caches", lambda: cleared.append(1))
    monkeypatch.setattr(inference, "forget_compiled", lambda: forgotten.append(1))
    assert 0 < inference.memory_mappings() < inference.MAPPINGS_BUDGET
    inference.release_compiled_code(when_mapped_above=inference.MAPPINGS_BUDGET)
    assert cleared == [] and forgotten == [1]
    inference.release_compiled_code(when_mapped_above=1)  # every process has more than one
    assert cleared == [1] and forgotten == [1, 1]
    inference.release_compiled_code()  # the default: always
    assert cleared == [1, 1]


def test_pathfinder_starts_lie_in_the_posterior_bulk(small_ds):
    """Multi-path Pathfinder starts (bayesfric.inference.init) have a higher log density than the
    prior-median starts, and the fit records how its chains started."""
    import jax

    from bayesfric.inference.init import chain_starts
    from bayesfric.model import build_program

    program = build_program(get_law("coulomb_viscous"), small_ds)
    density = program.density()
    log_joint = jax.vmap(density.log_joint)
    median, pathfinder = (chain_starts(program, 3, seed=2, init=init) for init in ("median", "pathfinder"))
    assert pathfinder.shape == median.shape == (3, density.dim) and np.isfinite(pathfinder).all()
    assert np.min(log_joint(pathfinder)) > np.max(log_joint(median))
    with pytest.raises(ValueError, match="unknown init"):
        chain_starts(program, 3, seed=2, init="uniform")
    dt = fit(get_law("coulomb_viscous"), small_ds, draws=100, tune=150, chains=2, init="pathfinder")
    assert json.loads(dt.attrs["sampler_settings"])["init"] == "pathfinder"


def test_a_dense_metric_learns_a_correlated_posterior_and_crosses_it_in_fewer_steps():
    """One NUTS chain (``nuts_chain``) on a 3-d Gaussian with correlations 0.999: the dense
    warm-up's draws match the covariance, and each draw takes far fewer leapfrog steps than
    with the diagonal metric (which cannot undo the correlation: condition number ~3000).
    Measured: 5.1 against 37 steps per draw."""
    import jax

    from bayesfric.inference.adaptation import nuts_chain, sampling_schedule
    from bayesfric.runtime import configure

    configure()  # x64, as every fit runs
    cov = np.full((3, 3), 0.999) + 0.001 * np.eye(3)
    precision = np.linalg.inv(cov)
    schedule = sampling_schedule(500, 1500)

    def run(imm):
        out = jax.jit(lambda z0, m: nuts_chain(jax.random.PRNGKey(3), z0, lambda x: -0.5 * x @ precision @ x,
                                               schedule, m, 0.8, 10))(np.full(3, 0.5), imm)
        return np.asarray(out.position)[500:], float(np.mean(np.asarray(out.n_steps)[500:]))

    dense, dense_steps = run(np.eye(3))
    diag, diag_steps = run(np.ones(3))
    # 1500 correlated draws: the sample covariance within 20 % (effective sizes of several hundred)
    np.testing.assert_allclose(np.cov(dense, rowvar=False), cov, rtol=0.2, atol=0.03)
    assert dense_steps < 0.25 * diag_steps, (dense_steps, diag_steps)


def test_the_auto_metric_goes_dense_on_strong_correlations_only():
    """``auto`` (one ``nuts_chain``): on the 3-d Gaussian with correlations 0.999 the slow
    windows keep their dense estimate (every draw samples with a dense metric, about as few
    steps as ``dense``); on a Gaussian with independent coordinates of scales 1e-3 … 10 they
    keep its diagonal, and the draws are the diagonal metric's, bit for bit (the diagonal of
    the dense estimate is the diagonal estimate)."""
    import jax

    from bayesfric.inference.adaptation import nuts_chain, sampling_schedule
    from bayesfric.runtime import configure

    configure()
    schedule = sampling_schedule(500, 1000)

    def run(precision, imm, auto):
        out = jax.jit(lambda z0, m: nuts_chain(jax.random.PRNGKey(4), z0, lambda x: -0.5 * x @ precision @ x,
                                               schedule, m, 0.8, 10, auto))(np.full(3, 0.5), imm)
        return (np.asarray(out.position)[500:], float(np.mean(np.asarray(out.n_steps)[500:])),
                np.asarray(out.dense_metric)[500:])

    correlated = np.linalg.inv(np.full((3, 3), 0.999) + 0.001 * np.eye(3))
    _, auto_steps, dense_used = run(correlated, np.eye(3), True)
    _, diag_steps, _ = run(correlated, np.ones(3), False)
    assert dense_used.all() and auto_steps < 0.25 * diag_steps, (auto_steps, diag_steps)

    independent = np.diag(1.0 / np.array([1e-3, 1.0, 10.0]) ** 2)
    auto_draws, _, dense_used = run(independent, np.eye(3), True)
    diag_draws, _, _ = run(independent, np.ones(3), False)
    assert not dense_used.any()
    np.testing.assert_array_equal(auto_draws, diag_draws)


def test_the_engine_takes_a_dense_metric_through_fit_and_warm_started_folds(simulator):
    """``NutsEngine.build(metric="dense")``: the fit records it, a warm start begins from the fit's
    covariance, its folds sample; an unknown metric is refused."""
    from bayesfric.compare.refit import RefitEngine
    from bayesfric.model import build_program

    law = get_law("coulomb_viscous")
    ds = simulator(law, {"velocity": np.linspace(-2, 2, 20)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.05, seed=1)
    with pytest.raises(ValueError, match="metric: must be one of"):
        RefitEngine.build(build_program(law, ds), metric="full")
    engine = RefitEngine.build(build_program(law, ds), draws=300, tune=300, chains=2, metric="dense")
    dt = engine.fit(ds)
    assert json.loads(dt.attrs["sampler_settings"])["metric"] == "dense"
    assert engine.settings["metric"] == "dense"
    post = dt["posterior"]
    assert float(post["T_C"].mean()) == pytest.approx(1.0, abs=0.1)
    assert float(post["c_v"].mean()) == pytest.approx(0.5, abs=0.1)
    warm = engine.warm_started(dt, 150)
    masks = np.ones((2, 20), dtype=bool)
    masks[0, 0] = masks[1, 19] = False
    folds = warm.run(masks, seed=1)
    assert np.isfinite(folds.lpd).all() and folds.samples["T_C"].shape[:2] == (2, 2)
    assert engine.compilations == 1  # the fit and the warm-started folds share one compiled sampler


def test_the_auto_metric_records_its_choice_and_falls_back_to_the_diagonal_one(simulator):
    """``NutsEngine`` (default ``auto``) on Coulomb-viscous data at speeds 1-2 rad/s only, where
    T_C and c_v are strongly anti-correlated: every chain goes dense, the fit says so, and warm
    folds start from the fit's covariance. With a gate no fit can pass, a fit that went dense is
    sampled again with the diagonal metric (no dense draw, recorded), at the same target and then
    the raised one, on the same compiled sampler."""
    from bayesfric.compare.refit import RefitEngine
    from bayesfric.inference.diagnostics import Gate
    from bayesfric.model import build_program

    law = get_law("coulomb_viscous")
    ds = simulator(law, {"velocity": np.linspace(1, 2, 30)}, {"T_C": 1.0, "c_v": 0.5}, sigma=0.05, seed=2)
    engine = RefitEngine.build(build_program(law, ds), draws=600, tune=300, chains=2)
    assert engine.metric == "auto"
    dt = engine.fit(ds)
    settings = json.loads(dt.attrs["sampler_settings"])
    assert settings["metric"].startswith("auto: dense in 2 of 2 chains") and "retried" not in settings
    warm = engine.warm_started(dt, 150)
    assert np.asarray(warm.start.inverse_mass).ndim == 2 and np.asarray(warm.start.inverse_mass)[0, 1] != 0
    strict = RefitEngine.build(build_program(law, ds), draws=300, tune=300, chains=2, gate=Gate(ess_bulk_min=1e9))
    fits = strict.run(np.ones((1, 30), dtype=bool))
    assert fits.diagonal.tolist() == [True] and not fits.stats["dense_metric"].any()
    assert not fits.verdicts[0].passed and strict.compilations == 1
    retried = json.loads(strict.fit(ds).attrs["sampler_settings"])
    assert retried["retried"] == ("the dense metric the warm-up chose failed the gate: sampled again with the "
                                  "diagonal one at 0.9, which failed too; then at 0.99")  # no gate is passed
    assert retried["metric"].startswith("auto: dense in 0 of 2")
