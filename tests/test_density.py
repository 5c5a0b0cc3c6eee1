"""One log density per program: every consumer reads the same numbers at the same point."""

import dataclasses

import jax
import numpy as np
import pytest
from numpyro.infer.util import potential_energy

from bayesfric.compare.refit import RefitEngine
from bayesfric.inference import fit
from bayesfric.laws import get_law
from bayesfric.model import Noise, build_program


@pytest.fixture(scope="module")
def case(simulator):
    law = get_law("stribeck")
    v = np.concatenate([-np.geomspace(0.01, 2, 12)[::-1], np.geomspace(0.01, 2, 12)])
    series = np.arange(v.size) % 3
    ds = simulator(law, {"velocity": v}, {"T_C": 2.0, "dT_s": 1.0, "v_s": 0.1, "delta": 0.8}, sigma=0.1, seed=2,
                   groups={"series": series})
    program = build_program(law, ds, noise=Noise(kind="student_t", group="series"))
    return law, ds, program


@pytest.fixture(scope="module")
def simulator():
    from bayesfric.datasets.synthetic import simulate

    return simulate


def test_the_density_is_numpyros_potential_and_splits_into_prior_and_likelihood(case):
    _, _, program = case
    density = program.density()
    x = density.x0 + 0.1 * np.random.default_rng(0).standard_normal(density.dim)
    kwargs = program.model_kwargs
    assert float(density.log_joint(x)) == pytest.approx(
        -float(potential_energy(program.model, (), kwargs, density.unravel(x))), rel=1e-12)
    pointwise = density.log_likelihood(x)
    assert pointwise.shape == (program.n_obs,)
    assert float(density.log_joint(x)) == pytest.approx(float(density.log_prior(x) + pointwise.sum()), rel=1e-10)
    half = np.arange(program.n_obs) < program.n_obs // 2
    assert float(density.log_joint(x, half)) == pytest.approx(float(density.log_prior(x) + pointwise[half].sum()),
                                                              rel=1e-10)
    assert program.density() is density  # built once
    shifted = dataclasses.replace(program, response=program.response + 1.0)  # a copy never reuses the old data
    assert shifted.density() is not density
    assert float(shifted.density().log_likelihood(x).sum()) != pytest.approx(float(pointwise.sum()))


def test_every_consumer_reads_the_one_density(case):
    """The fit's stored log-likelihood, emcee's log probability and the refit engine agree with it."""
    law, ds, program = case
    density = program.density()
    dt = fit(law, ds, sampler="emcee", noise=program.noise, draws=40, tune=40, thin=4, seed=0)
    post = dt["posterior"]
    draw = {k: post[k].values[0, -1] for k in density.sites}
    x = density.to_unconstrained({k: np.asarray(v)[None] for k, v in draw.items()})[0]
    # the DataTree's pointwise log-likelihood (what LOO, K-fold scoring and checks read)
    stored = dt["log_likelihood"]["response"].values[0, -1]
    np.testing.assert_allclose(np.asarray(density.log_likelihood(x)), stored, rtol=1e-9)
    # emcee's log probability of that draw (its sample_stats.lp)
    assert float(density.log_joint(x)) == pytest.approx(float(dt["sample_stats"]["lp"].values[0, -1]), rel=1e-9)
    # the refit engine samples this very density object
    engine = RefitEngine.build(program, draws=50, tune=50, chains=1)
    assert engine.kernel.density is density
    assert np.isfinite(float(jax.jit(density.log_joint)(engine.kernel.positions(engine.start)[0])))
