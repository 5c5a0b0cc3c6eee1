"""The noise model's Student-t sampler (bayesfric.studentt): exact draws, numpyro's density."""

import jax
import jax.numpy as jnp
import numpy as np
import numpyro.distributions as dist
import pytest
from scipy import stats

from bayesfric.studentt import StudentT, standard_gamma

#: One compilation per output shape (alpha is an argument, not a traced-in constant).
gamma = jax.jit(standard_gamma, static_argnums=2)


@pytest.mark.parametrize("alpha", [0.3, 0.95, 1.0, 2.5, 40.0])
def test_gamma_draws_follow_the_gamma_law(alpha):
    """KS against scipy's Gamma(alpha) over 20 independent keys: the p-values are uniform (a
    biased sampler drives them to 0), and the pooled mean sits within 4 standard errors."""
    draws = [np.asarray(gamma(jax.random.PRNGKey(s), jnp.float64(alpha), (20000,))) for s in range(20)]
    pvalues = [stats.kstest(x, stats.gamma(alpha).cdf).pvalue for x in draws]
    assert stats.kstest(pvalues, "uniform").pvalue > 1e-3
    pooled = np.concatenate(draws)
    assert abs(pooled.mean() - alpha) < 4 * np.sqrt(alpha / pooled.size)


def test_gamma_takes_per_element_shapes_and_is_reproducible():
    alpha = jnp.array([[0.5, 3.0], [10.0, 100.0]])
    a = standard_gamma(jax.random.PRNGKey(3), alpha)
    b = standard_gamma(jax.random.PRNGKey(3), alpha)
    assert a.shape == alpha.shape and bool(jnp.all(a > 0))
    np.testing.assert_array_equal(a, b)
    many = gamma(jax.random.PRNGKey(4), alpha, (5000, 2, 2))
    np.testing.assert_allclose(np.asarray(many).mean(axis=0), alpha, rtol=0.1)


@pytest.mark.parametrize("nu", [1.5, 4.0, 30.0])
def test_student_t_draws_match_numpyros_law(nu):
    """Draws under vmap (as Predictive draws them) follow t(nu, loc, scale)."""
    keys = jax.random.split(jax.random.PRNGKey(7), 400)
    draw = jax.jit(jax.vmap(lambda k: StudentT(nu, 1.0, 2.0).sample(k, (100,))))
    x = np.asarray(draw(keys)).ravel()
    assert stats.kstest(x, stats.t(nu, 1.0, 2.0).cdf).pvalue > 1e-3


def test_density_is_numpyros_bit_for_bit():
    y = jnp.linspace(-5.0, 5.0, 11)
    ours, theirs = StudentT(3.0, 0.5, 1.5), dist.StudentT(3.0, 0.5, 1.5)
    np.testing.assert_array_equal(ours.log_prob(y), theirs.log_prob(y))
    assert ours.batch_shape == theirs.batch_shape
