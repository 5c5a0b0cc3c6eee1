"""Checks of argument values the command line and the Python API share, before any work.

A base module (standard library, :mod:`bayesfric.errors` and :mod:`bayesfric.samplerconfig`
only), so the command line runs them before JAX loads: quantile levels (``--quantiles``,
``quantiles=``) and a seed (``--seed``, ``seed=``). Each problem is a one-line
:class:`~bayesfric.errors.UserError` under the key the caller names.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from bayesfric.errors import UserError

__all__ = ["quantile_levels", "seed_value"]


def quantile_levels(quantiles: Any, key: str = "quantiles") -> list[float]:
    """Quantile levels: at least one, each a number in (0, 1), none twice.

    Examples
    --------
    >>> quantile_levels([0.05, 0.95])
    [0.05, 0.95]
    >>> quantile_levels([0.5, 0.5])
    Traceback (most recent call last):
    ...
    bayesfric.errors.UserError: quantiles: 0.5 is given twice; give each level once
    """
    if isinstance(quantiles, str | bytes) or not isinstance(quantiles, Iterable):
        quantiles = [quantiles]
    values = list(quantiles)
    if not values:
        raise UserError("no quantile level given; give at least one in (0, 1), e.g. [0.05, 0.5, 0.95]", key)
    out: list[float] = []
    for q in values:
        q = q.item() if type(q).__module__ == "numpy" and hasattr(q, "item") else q
        if isinstance(q, bool) or not isinstance(q, int | float) or not 0 < q < 1:  # NaN fails too
            raise UserError(f"each quantile must be a number in (0, 1), got {q!r}", key)
        if float(q) in out:
            raise UserError(f"{float(q):g} is given twice; give each level once", key)
        out.append(float(q))
    return out


def seed_value(seed: Any, key: str = "seed") -> int:
    """A seed: an integer 0 … 2**32 − 1 (the sampler's rule, :data:`bayesfric.samplerconfig.RULES`).

    Examples
    --------
    >>> seed_value(-1, "--seed")
    Traceback (most recent call last):
    ...
    bayesfric.errors.UserError: --seed: must be an integer ≥ 0 and ≤ 4294967295, got integer -1
    """
    from bayesfric.samplerconfig import RULES

    if type(seed).__module__ == "numpy" and hasattr(seed, "item"):
        seed = seed.item()
    if problem := RULES["seed"].problem(seed):
        raise UserError(problem, key)
    return int(seed)
