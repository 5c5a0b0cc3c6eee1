"""Which way a law's predictive distribution is off, read from its LOO-PIT values.

The LOO-PIT value of an observation is ``u_i = P(ỹ_i ≤ y_i | y_-i)``; for a calibrated
predictive distribution the ``u_i`` are uniform on [0, 1] (Gneiting et al. 2007, "Probabilistic
forecasts, calibration and sharpness", JRSS B 69; Säilynoja et al. 2022 for the simultaneous
ECDF band that :func:`bayesfric.compare.loo_pit_check` tests against). The band says *whether*
the values leave uniformity; :func:`pit_shape` says *how*. Each value is mapped to its normal
score ``z_i = Φ⁻¹(u_i)``: calibrated, the scores are standard normal; a predictive
distribution ``s`` times too narrow spreads them ``s`` times wider whatever its shift, a shifted
one moves them without spreading them. Two numbers are read:

* ``scale = IQR(z) / 1.349``, the robust spread of the scores: about how many times more widely
  the observations scatter around the predictions than the predictive distribution says (1
  when calibrated; the interquartile range ignores the clipped extremes);
* ``mean(u)``, the PIT mean: 1/2 when calibrated.

Rules, each with a practical and a statistical threshold (both must be passed; ``n`` PIT values,
standard errors under calibration: ``1.166 / sqrt(n)`` for ``scale``, the IQR estimator's, and
``sqrt(1/12 / n)`` for the mean):

* **too narrow** (U-shaped PIT: observations pile into both tails, the predictive intervals
  understate the scatter): ``scale ≥ 1 +`` :data:`SCALE_MARGIN` and more than :data:`Z`
  standard errors above 1;
* **too wide** (hump-shaped PIT: observations crowd the middle, the intervals overstate the
  scatter): ``scale ≤ 1 / (1 +`` :data:`SCALE_MARGIN` ``)`` and more than :data:`Z` standard
  errors below 1;
* **biased** (PIT mean away from 1/2): ``|mean − 1/2| ≥`` :data:`BIAS_MARGIN` and more than
  :data:`Z` standard errors; a mean above 1/2 means the observations lie above the predictions
  (predictions systematically **low**), below 1/2 systematically **high**.

Width and bias are read separately, so a shifted but well-scaled prediction does not read as
"too narrow" (a shift empties one PIT tail and fills the other), and a prediction both shifted
and too narrow gets both words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

__all__ = ["PitShape", "pit_shape", "SCALE_MARGIN", "BIAS_MARGIN", "Z"]

#: Relative excess of the scores' spread over 1 that calls the intervals too narrow (and its
#: reciprocal too wide): 1.15 = the observations scatter 15 % more widely than predicted.
SCALE_MARGIN = 0.15
#: How far the PIT mean must sit from 1/2 to call the predictions biased.
BIAS_MARGIN = 0.05
#: Standard errors (under calibration) a number must also clear, so small samples stay quiet.
Z = 2.0
#: Standard error of the IQR-based scale of n standard normal scores, times sqrt(n).
_SCALE_SE = 1.166
_CLIP = 1e-6  # PIT values of exactly 0 or 1 (no predictive draw beyond the observation)


@dataclass(frozen=True)
class PitShape:
    """The direction(s) in which a set of LOO-PIT values departs from uniform.

    ``scale``: robust spread of the normal scores (observed over predicted scatter, 1 when
    calibrated); ``mean``: the PIT mean; ``lower``/``upper``: shares of PIT values below 1/4 and
    above 3/4; ``narrow``/``wide``: the intervals' width verdict; ``bias``: ``"low"`` (predictions
    below the observations), ``"high"`` or ``""``.
    """

    n: int
    scale: float
    mean: float
    lower: float
    upper: float
    narrow: bool
    wide: bool
    bias: str

    @property
    def outside(self) -> float:
        """Share of observations outside the central 50 % predictive interval (1/2 expected)."""
        return self.lower + self.upper

    @property
    def directions(self) -> list[str]:
        """Short labels: ``too narrow``, ``too wide``, ``biased (predictions too low|high)``."""
        out = ["too narrow"] * self.narrow + ["too wide"] * self.wide
        return out + ([f"biased (predictions too {self.bias})"] if self.bias else [])

    @property
    def label(self) -> str:
        """The directions joined (``"too narrow, biased (predictions too low)"``), or
        ``"no single direction"``."""
        return ", ".join(self.directions) or "no single direction"

    def text(self) -> str:
        """One sentence in words with the numbers behind it."""
        parts = []
        if self.narrow:
            parts.append(f"predictive intervals too narrow: the observations scatter {self.scale:.1f}× as widely "
                         f"as predicted ({self.outside:.0%} outside the central 50 % interval, 50 % expected; "
                         "U-shaped PIT)")
        if self.wide:
            parts.append(f"predictive intervals too wide: the observations scatter only {self.scale:.2f}× as "
                         f"widely as predicted ({self.outside:.0%} outside the central 50 % interval, 50 % "
                         "expected; hump-shaped PIT)")
        if self.bias:
            where = "above" if self.bias == "low" else "below"
            parts.append(f"predictions systematically too {self.bias}: the observations lie {where} them "
                         f"(mean PIT {self.mean:.2f}, 0.50 expected)")
        if not parts:
            return (f"no single direction: scatter {self.scale:.2f}× the predicted, mean PIT {self.mean:.2f} "
                    "(0.50 expected); the ECDF leaves its band locally")
        return "; ".join(parts)


def pit_shape(pit: np.ndarray) -> PitShape:
    """Classify LOO-PIT values (see the module's rules and thresholds).

    Parameters
    ----------
    pit : numpy.ndarray
        LOO-PIT values in [0, 1] (non-finite values are dropped).

    Returns
    -------
    PitShape
        Shares, mean and the verdicts; no verdict at all for fewer than two values.
    """
    u = np.asarray(pit, dtype=float).ravel()
    u = u[np.isfinite(u)]
    n = int(u.size)
    if n < 2:
        return PitShape(n, math.nan, math.nan, math.nan, math.nan, False, False, "")
    z = norm.ppf(np.clip(u, _CLIP, 1.0 - _CLIP))
    q25, q75 = np.quantile(z, [0.25, 0.75])
    scale, mean = float((q75 - q25) / (2.0 * norm.ppf(0.75))), float(np.mean(u))
    scale_se, mean_se = _SCALE_SE / math.sqrt(n), math.sqrt(1.0 / 12.0 / n)
    narrow = scale - 1.0 >= max(SCALE_MARGIN, Z * scale_se)
    wide = 1.0 - scale >= max(1.0 - 1.0 / (1.0 + SCALE_MARGIN), Z * scale_se)
    shift = mean - 0.5
    bias = ("low" if shift > 0 else "high") if abs(shift) >= max(BIAS_MARGIN, Z * mean_se) else ""
    return PitShape(n, scale, mean, float(np.mean(u < 0.25)), float(np.mean(u > 0.75)), narrow, wide, bias)
