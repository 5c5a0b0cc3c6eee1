"""A parameter's sampler coordinate (:class:`bayesfric.laws.base.SampledAs`) moves the sampler, never
the model: the prior and the log density are the same at every point, only their coordinates differ.

LuGre's F_c is sampled on log g(v_ref), its Stribeck curve at the data's largest speed: on data at
one speed (seed 001's triangle drive) that is what the loops pin, so the ridge of F_c, F_ratio and
v_s, curved where v_s crosses the drive speed, becomes straight.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import numpyro.distributions as dist
import pytest
from numpyro.infer.util import constrain_fn, potential_energy, unconstrain_fn

from bayesfric.datasets import load_builtin, select
from bayesfric.laws import get_law
from bayesfric.laws.steady import steady_state
from bayesfric.laws.transforms import asymmetric
from bayesfric.model import build_program, sampled_as
from bayesfric.priors import rescaled


def test_rescaled_keeps_the_distribution_and_moves_its_coordinate():
    base, c = dist.HalfNormal(2.0), 0.3
    moved = rescaled(base, c)
    values = jnp.array([0.01, 0.5, 3.0])
    np.testing.assert_allclose(moved.log_prob(values), base.log_prob(values))
    to = dist.biject_to(moved.support)
    x = jnp.array([-2.0, 0.0, 1.5])
    np.testing.assert_allclose(to(x), c * jnp.exp(x), rtol=1e-12)
    np.testing.assert_allclose(to.inv(values), jnp.log(values / c), rtol=1e-12)
    np.testing.assert_allclose(to.log_abs_det_jacobian(x, to(x)), x + math.log(c), rtol=1e-12)
    interval = dist.Uniform(0.0, 1.0)
    assert rescaled(interval, c) is interval  # not closed under scaling: sampled as declared


@pytest.fixture(scope="module")
def program():
    ds = select(load_builtin("dahl_duplex"), {"condition": "new"}).isel(obs=slice(0, 24))  # one loop's start
    return build_program(get_law("lugre"), ds)


POINT = {"sigma0": 2.0, "rho1": 0.4, "sigma2": 0.03, "F_c": 0.006, "F_ratio": 0.6, "v_s": 0.009, "gamma": 0.9,
         "sigma": 0.0024}


def _expected_log_prior(program, point):
    """Σ log p(θ) + log|dθ/du| with each site on numpyro's own bijection of its declared prior."""
    total = 0.0
    for name, value in point.items():
        prior = program.resolved[name].to_numpyro()
        to = dist.biject_to(prior.support)
        total += float(prior.log_prob(value) + to.log_abs_det_jacobian(to.inv(value), value))
    return total


def test_lugre_F_c_is_sampled_on_the_stribeck_curve_at_the_drive_speed(program):
    assert set(sampled_as(program.law, program.constants)) == {"F_c"}
    kwargs = program.model_kwargs
    unconstrained = jax.jit(lambda p: unconstrain_fn(program.model, (), kwargs, p))(POINT)
    v_ref = float(np.abs(program.inputs["velocity"]).max())
    g_ref = POINT["F_c"] * (1 + (1 / POINT["F_ratio"] - 1) * math.exp(-((v_ref / POINT["v_s"]) ** 2)))
    assert float(unconstrained["F_c"]) == pytest.approx(math.log(g_ref), rel=1e-12)
    back = jax.jit(lambda u: constrain_fn(program.model, (), kwargs, u))(unconstrained)
    for name, value in POINT.items():
        assert float(back[name]) == pytest.approx(value, rel=1e-12)
    # the same prior density: dF_c/du = F_c on either coordinate (the map is triangular)
    prior_only = kwargs | {"mask": jnp.zeros(program.n_obs, dtype=bool)}
    log_prior = -float(jax.jit(lambda u: potential_energy(program.model, (), prior_only, u))(unconstrained))
    assert log_prior == pytest.approx(_expected_log_prior(program, POINT), rel=1e-10)


def test_a_variant_without_what_it_reads_samples_on_its_own_scale():
    fixed = get_law("lugre").fix(F_ratio=1.0)  # F_s = F_c: the factor is 1, read from the constants
    assert set(sampled_as(fixed, {k: c.value for k, c in fixed.constants.items()})) == {"F_c"}
    steady = steady_state(get_law("lugre"))
    constants = {k: c.value for k, c in steady.constants.items()}
    assert set(sampled_as(steady, constants)) == {"F_c"}
    assert sampled_as(asymmetric(steady, ["v_s"]), constants) == {}  # v_s split by direction: not read
