"""The one log density of a program, in numpyro's unconstrained space, on flat vectors.

Every consumer of a program's posterior density reads it from here: the emcee backend, the
compile-once NUTS refit engine, both log-evidence estimators (bridge sampling, Laplace-t
importance sampling) and the tempered-SMC reference. Nothing else builds a density of its own.

``x`` is a flat vector of the unconstrained latent sites (numpyro's transforms: log for positive
parameters, logit for bounded ones ...), ordered as :func:`jax.flatten_util.ravel_pytree` orders
the site dictionary. :meth:`Density.log_joint` is ``log p(y, θ(x)) + log |dθ/dx|`` -- minus
numpyro's potential energy -- with an optional 0/1 likelihood ``mask`` and optional data
arrays passed as arguments, so compiled callers can change the fold or the data set without
recompiling.

>>> density = program.density()                                  # doctest: +SKIP
>>> density.log_joint(density.x0), density.log_likelihood(density.x0).shape   # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property, partial
from typing import Any, Protocol

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree
from numpyro import handlers
from numpyro.infer import init_to_median
from numpyro.infer.util import constrain_fn, log_likelihood, potential_energy, unconstrain_fn

from bayesfric.exported import program_jit

__all__ = ["Density", "ProgramLike", "build_density", "median_starts", "pending_median_starts", "start_seeds",
           "N_STARTS", "OBS_SITE"]

#: The observation site of every program (over dimension ``obs``).
OBS_SITE = "response"
#: Prior-median starts computed together by :attr:`Density.starts` (the NUTS chains' default).
N_STARTS = 4


class ProgramLike(Protocol):
    """What a density reads of its program: the numpyro model, its arguments and the number of
    observations. :class:`bayesfric.model.Program` is one; the type is declared here, below
    :mod:`bayesfric.model`, which builds each program's density (no import back)."""

    def model(self, inputs: Any, group_index: Any = None, response: Any = None, mask: Any = None,
              seen: Any = None) -> None: ...

    @property
    def model_kwargs(self) -> dict[str, Any]: ...

    @property
    def n_obs(self) -> int: ...


@dataclass(frozen=True)
class Density:
    """Unconstrained log density, pointwise log-likelihood and site maps of one program.

    Attributes
    ----------
    program : ProgramLike
        The program (a :class:`bayesfric.model.Program`: law, priors, noise, data).
    sites : list of str
        Latent sample sites, in the order of the flat vector.
    dim : int
        Length of the flat vector.
    unravel : callable
        Flat vector -> dict of unconstrained site values.
    seed : int
        Seed of the prior draws behind :attr:`x0`.
    """

    program: ProgramLike
    sites: list[str]
    dim: int
    unravel: Callable[[jax.Array], dict[str, jax.Array]]
    seed: int = 0

    @cached_property
    def starts(self) -> jax.Array:
        """:data:`N_STARTS` prior-median starting points ``(N_STARTS, dim)`` (numpyro's
        ``init_to_median(num_samples=15)``, one seed each: :func:`start_seeds`).

        The same compiled program (and the same points) as the NUTS engine's default four
        chain starts, so the optimisers of the evidence estimators and of emcee compile nothing
        of their own for it. Computed on first use.
        """
        return median_starts(self.program, start_seeds(self.seed, N_STARTS))

    @property
    def x0(self) -> jax.Array:
        """The first of :attr:`starts`."""
        return self.starts[0]

    def _kwargs(self, data: Mapping[str, Any] | None, mask: Any = None) -> dict[str, Any]:
        kwargs = dict(self.program.model_kwargs if data is None else data)
        return kwargs | {"mask": mask}

    def log_joint(self, x: jax.Array, mask: Any = None, data: Mapping[str, Any] | None = None) -> jax.Array:
        """``log p(y_mask, θ(x)) + log|J|`` (minus numpyro's potential energy).

        ``mask`` (bool, ``(n_obs,)``) keeps only those observations in the likelihood; ``data``
        replaces the program's arrays (``inputs``, ``group_index``, ``response``) by arguments.
        """
        return -potential_energy(self.program.model, (), self._kwargs(data, mask), self.unravel(x))

    @cached_property
    def log_joint_batch(self) -> Callable[[jax.Array], jax.Array]:
        """Compiled :meth:`log_joint` over a batch ``(n, dim)`` of flat vectors (traces kept on disk)."""
        return program_jit(self.program, "log_joint_batch", jax.vmap(self.log_joint), optimised=True)

    @cached_property
    def neg_value_and_grad(self) -> Callable[[jax.Array], tuple[jax.Array, jax.Array]]:
        """Compiled ``x -> (-log_joint(x), -∇log_joint(x))``, for optimisers."""
        return program_jit(self.program, "neg_value_and_grad", jax.value_and_grad(lambda x: -self.log_joint(x)),
                           optimised=True)

    def log_prior(self, x: jax.Array) -> jax.Array:
        """``log p(θ(x)) + log|J|``: the log joint with every observation masked out."""
        return self.log_joint(x, mask=jnp.zeros(self.program.n_obs, dtype=bool))

    def constrain(self, x: jax.Array, data: Mapping[str, Any] | None = None) -> dict[str, jax.Array]:
        """Constrained values of every sampled and deterministic site at ``x``."""
        return constrain_fn(self.program.model, (), self._kwargs(data), self.unravel(x),
                            return_deterministic=True)

    def log_likelihood(self, x: jax.Array, data: Mapping[str, Any] | None = None) -> jax.Array:
        """Pointwise ``log p(y_i | θ(x))``, shape ``(n_obs,)``."""
        return self.pointwise(self.constrain(x, data), data)

    def pointwise(self, constrained: Mapping[str, jax.Array], data: Mapping[str, Any] | None = None) -> jax.Array:
        """Pointwise log-likelihood at constrained site values (one draw, no batch axis)."""
        kwargs = dict(self.program.model_kwargs if data is None else data)
        batched = {k: jnp.asarray(v)[None] for k, v in constrained.items()}
        return log_likelihood(self.program.model, batched, **kwargs)[OBS_SITE][0]

    def to_unconstrained(self, constrained: Mapping[str, Any]) -> jax.Array:
        """Constrained draws, shaped ``(n, ...)`` per site, to flat unconstrained vectors ``(n, dim)``."""
        model, kwargs = self.program.model, self.program.model_kwargs
        draws = {k: jnp.asarray(constrained[k]) for k in self.sites}
        # one compiled program: run eagerly, the transforms dispatch (and the first time in a
        # process compile) op by op -- 27 s for a warm start of stribeck on the loaded 2-core box
        to_flat = jax.vmap(lambda p: ravel_pytree(unconstrain_fn(model, (), kwargs, p))[0])
        return program_jit(self.program, "to_unconstrained", to_flat, optimised=True)(draws)


def _median_start(program: ProgramLike, key: jax.Array) -> dict[str, jax.Array]:
    """Unconstrained latent sites at a prior median (numpyro's ``init_to_median(num_samples=15)``)."""
    model, kwargs = program.model, program.model_kwargs
    substituted = handlers.substitute(handlers.seed(model, key), substitute_fn=init_to_median(num_samples=15))
    trace = handlers.trace(substituted).get_trace(**kwargs)
    latent = {name: site["value"] for name, site in trace.items()
              if site["type"] == "sample" and not site["is_observed"]}
    return unconstrain_fn(model, (), kwargs, latent)


def start_seeds(seed: int, n: int) -> list[int]:
    """Seeds of ``n`` prior-median starting points of a run with seed ``seed``."""
    return [seed * 7919 + c for c in range(n)]


def _median_starts_jit(program: ProgramLike) -> Callable:
    def flat_starts(keys):
        return jax.vmap(lambda key: ravel_pytree(_median_start(program, key))[0])(keys)

    return program_jit(program, "median_starts", flat_starts, optimised=True)


def _seed_keys(seeds: list[int]) -> jax.Array:
    return jnp.stack([jax.random.PRNGKey(s) for s in seeds])


def median_starts(program: ProgramLike, seeds: list[int]) -> jax.Array:
    """Flat prior-median starting points ``(len(seeds), dim)``, one per seed, in ONE compiled call.

    Executing the model eagerly instead dispatches (and, the first time in a process, compiles)
    each of its few hundred operations one by one.
    """
    return _median_starts_jit(program)(_seed_keys(seeds))


def pending_median_starts(program: ProgramLike, seeds: list[int]) -> Callable[[], jax.Array]:
    """:func:`median_starts`, compiling in the background (:mod:`bayesfric.exported`) from now on;
    call the returned function for the value (it waits for the compilation)."""
    keys = _seed_keys(seeds)
    starts = _median_starts_jit(program)
    starts.ahead(keys)
    return lambda: starts(keys)


def build_density(program: ProgramLike, seed: int = 0) -> Density:
    """The density of ``program``; its latent sites are found by an abstract trace (no compilation)."""
    shapes = jax.eval_shape(partial(_median_start, program), jax.random.PRNGKey(seed))
    flat, unravel = ravel_pytree(jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes))
    return Density(program=program, sites=sorted(shapes), dim=int(flat.size), unravel=unravel, seed=seed)
