"""Is a direction asymmetry supported? The posterior of ``p_pos − p_neg`` for every parameter a law
variant made direction-dependent (:mod:`bayesfric.laws.variants`, ``asymmetric = [...]``).

The difference is computed draw by draw from the fit's posterior, so its interval carries the
posterior correlation of the two sides. Whether the asymmetric variant predicts better than the
symmetric law is the study's ranking (evidence, LOO) of the two entries; this module gives the
size and sign of the asymmetry itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.laws.variants import law_of_fit

__all__ = ["Asymmetry", "asymmetry"]


@dataclass(frozen=True)
class Asymmetry:
    """Posterior summary of ``<parameter>_pos − <parameter>_neg`` (SI units of the parameter)."""

    law: str
    parameter: str
    unit: str
    mean: float
    sd: float
    low: float  # equal-tailed interval of probability ``prob``
    high: float
    prob: float
    p_positive: float  # posterior probability that the positive side is larger
    draws: int

    def excludes_zero(self) -> bool:
        """True if the interval lies on one side of zero."""
        return self.low > 0 or self.high < 0

    def text(self) -> str:
        """One line, e.g. ``T_C_pos − T_C_neg = 0.41 N*m [0.30, 0.52] (90 %), P(> 0) = 1.00``."""
        return (f"{self.parameter}_pos − {self.parameter}_neg = {self.mean:.4g} {self.unit} "
                f"[{self.low:.4g}, {self.high:.4g}] ({self.prob:.0%}), P(> 0) = {self.p_positive:.2f}")


def asymmetry(fit: xr.DataTree, prob: float = 0.9) -> list[Asymmetry]:
    """One :class:`Asymmetry` per direction-dependent parameter of the fit's law (none if symmetric).

    Parameters
    ----------
    fit : xarray.DataTree
        A fit (:func:`bayesfric.inference.fit`) whose attrs record the law variant.
    prob : float
        Probability mass of the equal-tailed interval.
    """
    if not 0 < prob < 1:
        raise UserError(f"must be in (0, 1), got {prob}", "prob")
    law = law_of_fit(fit.attrs)
    post = fit["posterior"].to_dataset()
    out = []
    for name in law.recipe.get("asymmetric", ()):
        diff = np.asarray(post[f"{name}_pos"] - post[f"{name}_neg"], dtype=float).ravel()
        low, high = np.quantile(diff, [(1 - prob) / 2, (1 + prob) / 2])
        out.append(Asymmetry(law=law.name, parameter=name, unit=law.params[f"{name}_pos"].unit,
                             mean=float(diff.mean()), sd=float(diff.std(ddof=1)), low=float(low), high=float(high),
                             prob=prob, p_positive=float(np.mean(diff > 0)), draws=diff.size))
    return out
