"""Warm starts of fold refits from a full fit: initial points and inverse mass matrix
(:meth:`bayesfric.inference.engine.NutsEngine.warm_started`)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.inference.adaptation import DENSE_ABOVE, PSEUDO_COUNT, SHRINK_TO
from bayesfric.model import Program

__all__ = ["warm_start_from"]


def warm_start_from(program: Program, fit: xr.DataTree, chains: int, seed: int, metric: str = "diag"):
    """Initial points and inverse mass matrix for the fold chains, from a full fit.

    Picks ``chains`` posterior draws (chain ``c % n_chains``, a random draw of it), maps them
    to the unconstrained space the sampler works in, and takes the per-coordinate variance of
    all unconstrained draws as the diagonal inverse mass matrix (floored at 1e-16 of the largest
    so a coordinate whose draws did not move keeps a positive scale, but relative, so a
    coordinate the data pin down hard keeps its own scale), or for a dense metric their
    covariance, regularised towards a thousandth of its own diagonal as the warm-up's own
    estimates are (:mod:`bayesfric.inference.adaptation`: weight n / (n + 5) on the sample
    covariance). For the ``auto`` metric, that covariance where its correlations are strong
    (:func:`strongly_correlated`), else the diagonal metric's variances as a diagonal matrix.
    """
    density = program.density(seed)
    post = fit["posterior"]
    missing = [n for n in density.sites if n not in post.data_vars]
    if missing:
        raise UserError(f"warm start: the fit lacks the sampled site(s) {missing}; is it a fit of "
                         f"{program.law.name!r} with the same noise model?")
    n_chain, n_draw = post.sizes["chain"], post.sizes["draw"]
    flat = {n: np.asarray(post[n].values).reshape((n_chain * n_draw,) + post[n].shape[2:]) for n in density.sites}
    unconstrained = density.to_unconstrained(flat)
    rng = np.random.default_rng(seed)
    picks = np.array([(c % n_chain) * n_draw + rng.integers(n_draw) for c in range(chains)])
    if metric in ("dense", "auto"):
        draws = np.asarray(unconstrained)
        n = draws.shape[0]
        cov = np.atleast_2d(np.cov(draws, rowvar=False))
        scale = np.diag(cov)
        target = SHRINK_TO * np.diag(np.maximum(scale, 1e-16 * scale.max() + 1e-300))
        imm = (n / (n + PSEUDO_COUNT)) * cov + (PSEUDO_COUNT / (n + PSEUDO_COUNT)) * target
        if metric == "auto" and not strongly_correlated(imm):
            var = np.var(draws, axis=0)  # the diagonal metric's start, as a diagonal matrix
            imm = np.diag(np.maximum(var, 1e-16 * np.max(var) + 1e-300))
        return unconstrained[picks], imm
    var = jnp.var(unconstrained, axis=0)
    imm = jnp.maximum(var, 1e-16 * jnp.max(var) + 1e-300)
    return unconstrained[picks], imm


def strongly_correlated(covariance: np.ndarray) -> bool:
    """Whether the ``auto`` metric uses ``covariance`` dense: the condition number of its
    correlation matrix is above :data:`~bayesfric.inference.adaptation.DENSE_ABOVE`."""
    scale = np.sqrt(np.diag(covariance))
    eigenvalues = np.linalg.eigvalsh(covariance / np.outer(scale, scale))
    return bool(eigenvalues[0] > 0 and eigenvalues[-1] / eigenvalues[0] > DENSE_ABOVE)
