"""Sampler checks shared by study files and the ``fit`` command that need more than the settings
(each setting, the retry target among them, is checked by
:class:`~bayesfric.inference.config.SamplerConfig`): the emcee walkers a program needs, the draws
bridge sampling needs. Re-exported by :mod:`bayesfric.study.config`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpyro import handlers

if TYPE_CHECKING:
    from bayesfric.model import Program

__all__ = ["EVIDENCE_MIN_DRAWS", "free_parameter_count", "walkers_problem"]

#: Bridge sampling splits every chain in halves of at least 20 draws.
EVIDENCE_MIN_DRAWS = 40


def free_parameter_count(program: Program) -> int:
    """Number of free (sampled, unobserved) scalar parameters of a program."""
    trace = handlers.trace(handlers.seed(program.model, 0)).get_trace(**program.model_kwargs)
    return sum(int(np.size(s["value"])) for s in trace.values() if s["type"] == "sample" and not s["is_observed"])


def walkers_problem(program: Program, walkers: int | None) -> str | None:
    """Why ``walkers`` emcee walkers cannot sample ``program`` (None if they can, or if unset)."""
    if walkers is None:
        return None
    ndim = free_parameter_count(program)
    if walkers < 2 * ndim:
        return (f"emcee needs at least 2 × {ndim} = {2 * ndim} walkers for the {ndim} free parameters "
                f"of law {program.law.name!r}, got {walkers}")
    return None
