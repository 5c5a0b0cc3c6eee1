"""A blocked fold scored for a NEW group: how well each law predicts, beyond the tested envelope,
a run (series, unit) it has never seen.

A blocked fold trains on every run's rows inside the envelope and scores the rows beyond it;
a law with group terms scores them with each run's own fitted level, which answers "this
tested run, faster", not "the next run". Here the same fold's draws score each run's held-out
rows **as a new run's**: every level of the study's group column is replaced, per posterior
draw, by a fresh draw from the fold's group distribution (a varying parameter's
``T(T⁻¹(p) + p_sd · z)``; a ``[noise] group`` offset ``group_sd · z``), and each run's
held-out rows are scored **jointly**, ``log mean_s Π_{i ∈ run} p(y_i | θ_s, new level_s)`` (the
rows of one run share its level). A law without group terms is scored jointly per run as well
(its draws are the same for every run). No refit: one evaluation of the law over the fold's
draws.

What it can tell: one joint density per run. The stacking weights over those densities
(Bayesian bootstrap, :func:`bayesfric.compare.weights.new_group_weights`: each run's density
reweighted by Dirichlet draws, so a law must predict most runs better to take the weight) are
computed from :data:`MIN_GROUPS` runs on. With two runs the scheme cannot tell laws apart (two
values hold one degree of freedom about their spread), and sizing falls back to the stated rule
of :mod:`bayesfric.sizing.basis`; with three, the weights separate laws only where one predicts
every run far better, and spread otherwise. Leave-one-group-out follows the same rule
(:attr:`bayesfric.compare.refit.CVResult.too_few`): with two groups each fold trains on one.

A trend's levels (campaigns along a service coordinate) are forecast, not exchangeable: a law
whose varying parameter follows a trend keeps its fitted levels here (named).
"""

from __future__ import annotations

from collections.abc import Mapping

import jax
import numpy as np

from bayesfric.exported import program_options

__all__ = ["MIN_GROUPS", "new_group_lpd", "new_level_samples", "label"]

#: Fewest runs from which a blocked fold scored for a new run (and leave-one-group-out) weighs
#: the laws.
MIN_GROUPS = 3


def label(column: str, scheme: str) -> str:
    """The weighting label of ``scheme``'s fold scored for a new level of ``column``.

    >>> label("run", "velocity > 1.5 rad/s")
    'new run, velocity > 1.5 rad/s'
    """
    return f"new {column}, {scheme}"


def new_level_samples(program, samples: Mapping[str, np.ndarray], column: str,
                      rng: np.random.Generator) -> dict[str, np.ndarray]:
    """``samples`` (flat draws ``(S, ...)``, constrained, deterministic sites included) with every
    level of ``column`` replaced by a new level's draw: the varying parameters' level sites and
    values, and a ``[noise] group`` offset on that column (see the module)."""
    from bayesfric.hierarchy import _bijection, site_names

    out = {k: np.array(v, dtype=float, copy=True) for k, v in samples.items()}
    law = program.law
    if column in program.groupings:
        names = site_names(law, program.groupings)
        for p, (sd_site, level_site, values_site) in names.items():
            if law.varying[p] != column or p in law.trending:
                continue
            t = _bijection(program.resolved[p])
            z = rng.normal(size=out[values_site].shape)
            u = np.asarray(t.inv(out[p]))[:, None] + out[sd_site][:, None] * z
            out[values_site] = np.asarray(t(u), dtype=float)
            out[level_site] = z if level_site.endswith("_z") else u
    if program.noise.group == column and "group_offset" in out:
        z = rng.normal(size=out["group_offset"].shape)
        out["group_offset"] = out["group_sd"][:, None] * z
        out["group_z"] = z
    return out


def new_group_lpd(program, samples: Mapping[str, np.ndarray], heldout: np.ndarray, groups: np.ndarray,
                  column: str, seed: int = 0) -> np.ndarray:
    """Each run's held-out rows scored jointly as a new run's: one value per run with held-out
    rows, in the order of their level index (see the module).

    Parameters
    ----------
    program : bayesfric.model.Program
        The law's program on the full data (the fold's).
    samples : mapping
        One fold's constrained draws ``(chain, draw, ...)``.
    heldout : ndarray of bool, shape (n_obs,)
        The fold's held-out rows.
    groups : ndarray of int, shape (n_obs,)
        Each row's level of ``column`` (the study's grouped column).
    column : str
        The group column.
    seed : int
        Seed of the new levels' draws.
    """
    from bayesfric.limits import CHUNK_NUMBERS

    s = int(np.prod(next(iter(samples.values())).shape[:2]))
    flat = {k: np.asarray(v).reshape((s,) + np.shape(v)[2:]) for k, v in samples.items()}
    flat = new_level_samples(program, flat, column, np.random.default_rng([int(seed), 7]))
    density = program.density()
    pointwise = jax.jit(jax.vmap(density.pointwise), compiler_options=program_options(program.n_obs, optimised=False))
    size = max(1, CHUNK_NUMBERS // max(1, program.n_obs))
    lpd = np.concatenate([np.asarray(pointwise({k: v[a:a + size] for k, v in flat.items()}))
                          for a in range(0, s, size)])
    out = []
    for g in np.unique(groups[heldout]):
        rows = heldout & (groups == g)
        sums = lpd[:, rows].sum(axis=1)
        out.append(float(jax.scipy.special.logsumexp(sums) - np.log(s)))
    return np.asarray(out, dtype=float)

