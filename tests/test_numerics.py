"""Powers through exp and log (bayesfric.numerics): values and gradients against closed forms."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bayesfric.numerics import positive_power, power_ratio

BASES = np.array([1e-6, 0.013, 0.5, 1.0, 2.7, 40.0, 3.3e4])
EXPONENTS = np.array([-1.379, 0.15, 0.5, 1.0, 4.0 / 3.0, 2.5])


@pytest.mark.parametrize("p", EXPONENTS)
@pytest.mark.parametrize("as_array", [False, True], ids=["python number", "array (exp/log)"])
def test_positive_power_equals_pow_for_positive_bases(p, as_array):
    # a Python number that is a multiple of 1/2 takes the sqrt-and-multiply path, an array exp/log
    exponent = jnp.asarray(p) if as_array else float(p)
    np.testing.assert_allclose(np.asarray(positive_power(jnp.asarray(BASES), exponent)), BASES**p, rtol=1e-13)


def test_static_exponents_zero_and_one_cost_nothing():
    a = jnp.asarray(BASES)
    assert np.all(np.asarray(positive_power(a, 0)) == 1.0)
    assert np.array_equal(np.asarray(positive_power(a, 1.0)), BASES)
    assert "exp" not in str(jax.make_jaxpr(lambda x: positive_power(x, 1.5))(a))  # sqrt(a) ** 3
    assert "exp" in str(jax.make_jaxpr(lambda x: positive_power(x, 1.28))(a))


def test_positive_power_is_zero_with_finite_gradients_at_and_below_zero():
    a = jnp.array([0.0, -1.0, -1e-300])
    assert np.all(np.asarray(positive_power(a, 0.7)) == 0.0)
    for p in (0.5, 1.5):
        grad_a, grad_p = jax.vmap(jax.grad(positive_power, argnums=(0, 1)), in_axes=(0, None))(a, p)
        assert np.all(np.asarray(grad_a) == 0.0) and np.all(np.asarray(grad_p) == 0.0)


@pytest.mark.parametrize("a, p", [(0.013, 0.6), (2.7, 1.379), (40.0, -0.5), (3.0, 1.5)])
def test_positive_power_gradients_are_the_closed_forms(a, p):
    grad_a, grad_p = jax.grad(positive_power, argnums=(0, 1))(a, p)
    assert float(grad_a) == pytest.approx(p * a ** (p - 1.0), rel=1e-12)  # d/da a^p = p a^(p-1)
    assert float(grad_p) == pytest.approx(a**p * np.log(a), rel=1e-12)  # d/dp a^p = a^p ln a
    grad_a_static = jax.grad(lambda x: positive_power(x, p))(a)  # p a Python number: static path
    assert float(grad_a_static) == pytest.approx(p * a ** (p - 1.0), rel=1e-12)


def test_power_ratio_equals_the_power_of_the_ratio():
    speeds = np.array([0.0, 1e-4, 0.02, 0.5, 4.0])
    got = np.asarray(power_ratio(jnp.asarray(speeds), 0.05, 0.8))
    np.testing.assert_allclose(got, np.where(speeds > 0, (speeds / 0.05) ** 0.8, 0.0), rtol=1e-13)
    grad_scale = jax.grad(lambda s: power_ratio(0.5, s, 0.8))(0.05)
    assert float(grad_scale) == pytest.approx(-0.8 / 0.05 * (0.5 / 0.05) ** 0.8, rel=1e-12)
