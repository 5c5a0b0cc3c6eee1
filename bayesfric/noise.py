"""AR(1) residuals along ordered trajectories: exact likelihood, masks integrated out exactly.

Model
-----
Within each trajectory (rows in data order, a new trajectory wherever the data set's
``trajectory`` group changes value), the residuals ``e_t = y_t − mu_t`` follow a stationary
AR(1) process in the *sample index* (ρ is per sample step, so it assumes roughly even sampling):

    e_first ~ N(0, σ²/(1 − ρ²)),        e_t | e_{t−1} ~ N(ρ e_{t−1}, σ²),

σ the innovation standard deviation, |ρ| < 1. Trajectories are independent of each other.

Pointwise log-likelihood: the *conditional* one
-----------------------------------------------
The observation site carries one term per point, ``log p(y_t | y_{<t}, θ)`` (the first point of a
trajectory: its marginal). The terms sum to the exact joint log-likelihood of the trajectory.

Masks (cross-validation folds): a point with mask 0 is *integrated out exactly*. For the next
observed point t, its last observed predecessor s = t − k in the same trajectory gives

    e_t | e_s ~ N(ρ^k e_s, σ² (1 − ρ^(2k)) / (1 − ρ²)),

and with no observed predecessor in its trajectory e_t takes the stationary marginal. So a fold's
training likelihood is the exact marginal likelihood of the points it keeps.

Which predictive each score then reads (documented in ``docs/laws.md``, *Correlated residuals*):

* PSIS-LOO removes one term ``p(y_t | y_{<t}, θ)`` from the joint; it scores the one-step-ahead
  conditional predictive ``p(y_t | y_{<t})`` with a posterior that still sees every other term
  (including those conditioned on y_t) -- an approximation of leave-one-out, as for any
  factorised-but-dependent likelihood.
* K-fold, grouped and blocked refits train on the fold's points with the held-out ones
  integrated out, and score each held-out point by ``log mean_s p(y_t | y_{t−1}, θ_s)``: the
  one-step-ahead predictive given the *observed* previous value (held out or not); the first
  point of a trajectory is scored by its marginal. A held-out whole trajectory is therefore
  scored point by point, not by its joint predictive density.

Predictive draws of a program (posterior and prior predictive, hence LOO-PIT and the
posterior-predictive checks) are the same one-step-ahead conditionals given the observed data,
``y_t ~ N(mu_t + ρ^k e_s, ...)``, not freshly simulated trajectories: they check the predictive
the likelihood scores. :meth:`AR1Residuals.sample` without ``past`` simulates trajectories.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpyro.distributions as dist
from jax import lax
from numpyro.distributions import constraints

from bayesfric.numerics import positive_power

__all__ = ["AR1Residuals", "ar1_conditionals", "ar1_log_prob"]

_LOG_2PI = math.log(2 * math.pi)


def ar1_conditionals(resid, sigma, rho, start, observed=None):
    """Conditional mean and variance of each residual given the last observed one before it.

    Parameters
    ----------
    resid : array, shape (n,)
        Residuals ``y − mu`` in data order.
    sigma, rho : float
        Innovation standard deviation (> 0) and lag-one correlation (|ρ| < 1).
    start : array of bool, shape (n,)
        True at the first row of each trajectory.
    observed : array of bool or 0/1, shape (n,), optional
        Rows that are observed (the likelihood mask); default all.

    Returns
    -------
    tuple of arrays
        ``(mean, var)`` of ``e_t`` given the last observed ``e_s`` (s < t, same trajectory),
        the stationary ``(0, σ²/(1 − ρ²))`` where there is none.
    """
    resid = jnp.asarray(resid, dtype=float)
    n = resid.shape[-1]
    idx = jnp.arange(n)
    obs = jnp.ones(n, dtype=bool) if observed is None else jnp.asarray(observed).astype(bool)
    obs = jnp.broadcast_to(obs, (n,))
    first = lax.cummax(jnp.where(jnp.asarray(start, dtype=bool), idx, 0))  # trajectory's first row
    last_obs = lax.cummax(jnp.where(obs, idx, -1))
    prev = jnp.concatenate([jnp.array([-1]), last_obs[:-1]])  # last observed row strictly before t
    has_prev = prev >= first
    k = jnp.where(has_prev, idx - prev, 1).astype(resid.dtype)
    # ρ^k for negative ρ and integer k: |ρ|^k times the sign's parity
    parity = jnp.where(jnp.mod(k, 2) == 1, jnp.sign(rho), 1.0)
    rho_k = parity * positive_power(jnp.abs(rho), k)
    marginal = sigma**2 / (1.0 - rho**2)
    mean = jnp.where(has_prev, rho_k * resid[jnp.maximum(prev, 0)], 0.0)
    var = jnp.where(has_prev, marginal * (1.0 - rho_k**2), marginal)
    return mean, var


def ar1_log_prob(resid, sigma, rho, start, observed=None):
    """Pointwise conditional log density ``log p(e_t | e_{observed < t})`` (see module doc).

    Unobserved rows get the value their conditional would have, but the caller masks them; the
    observed rows' terms sum to the exact marginal log-likelihood of the observed residuals.
    """
    mean, var = ar1_conditionals(resid, sigma, rho, start, observed)
    return -0.5 * (_LOG_2PI + jnp.log(var) + (resid - mean) ** 2 / var)


class AR1Residuals(dist.Distribution):
    """Observation distribution ``y = mu + e`` with AR(1) residuals along trajectories.

    Its batch shape is the number of observations; ``log_prob`` returns the conditional terms
    (one per point), so numpyro's pointwise log-likelihood is the conditional one. ``observed``
    is the likelihood mask the program applies, passed here so that masked points are
    integrated out rather than conditioned on.

    ``past`` (the observed response, optional) makes :meth:`sample` draw the *one-step-ahead*
    predictive ``y_t ~ p(y_t | y_<t observed)`` -- the predictive the pointwise log-likelihood
    scores, and so what posterior-predictive checks and LOO-PIT compare with; without it
    :meth:`sample` draws whole new stationary trajectories.
    """

    arg_constraints = {"loc": constraints.real, "sigma": constraints.positive}
    support = constraints.real

    def __init__(self, loc, sigma, rho, start, observed=None, past=None, *, validate_args=None):
        self.loc = jnp.asarray(loc, dtype=float)
        self.sigma, self.rho = sigma, rho
        self.start = jnp.asarray(start, dtype=bool)
        self.observed = observed
        self.past = past
        super().__init__(batch_shape=jnp.shape(self.loc), validate_args=validate_args)

    def log_prob(self, value):
        return ar1_log_prob(value - self.loc, self.sigma, self.rho, self.start, self.observed)

    def sample(self, key, sample_shape=()):
        """One-step-ahead draws given ``past``, else whole stationary AR(1) trajectories."""
        eps = jax.random.normal(key, tuple(sample_shape) + self.batch_shape)
        if self.past is not None:
            mean, var = ar1_conditionals(jnp.asarray(self.past) - self.loc, self.sigma, self.rho,
                                         self.start, self.observed)
            return self.loc + mean + jnp.sqrt(var) * eps
        stationary = self.sigma / jnp.sqrt(1.0 - self.rho**2)
        decay = jnp.where(self.start, 0.0, self.rho) * jnp.ones_like(eps)
        shock = jnp.where(self.start, stationary, self.sigma) * eps

        def compose(first, second):  # affine maps e -> a e + b, applied first then second
            a1, b1 = first
            a2, b2 = second
            return a2 * a1, a2 * b1 + b2

        _, e = lax.associative_scan(compose, (decay, shock), axis=-1)
        return self.loc + e
