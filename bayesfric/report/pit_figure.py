"""The LOO-PIT figure of a law the checks flagged as miscalibrated: what its predictive
distribution gets wrong, drawn from the LOO-PIT values and band the checks unit stored
(:func:`bayesfric.compare.loo_pit_check`), with the direction read by
:func:`bayesfric.compare.pit_shape` in its title.

Two panels: the PIT histogram against the uniform density a calibrated law gives (U-shaped: the
intervals are too narrow; a hump: too wide; a slope: biased), and the PIT ECDF minus the uniform
CDF inside the simultaneous band the check tested against (arviz-stats' ``plot_loo_pit``
layout). Nothing is sampled or simulated here.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from bayesfric.report.figures import banner, save

if TYPE_CHECKING:
    import xarray as xr

    from bayesfric.report.view import TreeView

__all__ = ["plot_loo_pit", "pit_caption", "BINS"]

#: Bins of the PIT histogram.
BINS = 20


def plot_loo_pit(t: TreeView, name: str, ds: xr.Dataset, path: Path) -> Path | None:
    """The LOO-PIT figure of law ``name`` from the tree's ``/checks`` (None when its checks stored
    fewer than two PIT values); ``ds`` gives the provenance banner."""
    pit, band, shape = t.pit(name)
    if pit.size < 2:
        return None
    pit = np.clip(pit, 0.0, 1.0)
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    left, right = fig.subplots(1, 2)
    n = pit.size
    p = 1.0 / BINS  # a calibrated law's bin probability: density 1 ± 2 binomial sd
    spread = 2.0 * np.sqrt(n * p * (1 - p)) / (n * p)
    left.axhspan(1 - spread, 1 + spread, color="0.88", lw=0, label="calibrated ± 2 sd")
    left.hist(pit, bins=BINS, range=(0, 1), density=True, color="tab:blue", alpha=0.8, label="LOO-PIT")
    left.axhline(1.0, color="k", lw=1)
    left.set_xlabel("LOO-PIT value", fontsize=10)
    left.set_ylabel("density", fontsize=10)
    left.legend(fontsize=8, loc="upper center")
    grid = np.linspace(0.0, 1.0, 1001)  # the difference falls between jumps: evaluated, not stepped
    ecdf = np.searchsorted(np.sort(pit), grid, side="right") / n
    if band is not None:
        points, lower, upper = band
        right.fill_between(points, lower - points, upper - points, color="0.88", lw=0,
                           label=f"{t.flag(name, 'ci_prob'):.0%} simultaneous band")
    right.plot(grid, ecdf - grid, color="tab:blue", lw=1.4, label="ECDF − uniform")
    right.axhline(0.0, color="k", lw=1)
    right.set_xlabel("LOO-PIT value", fontsize=10)
    right.set_ylabel("ECDF − uniform CDF", fontsize=10)
    right.legend(fontsize=8, loc="best")
    for ax in (left, right):
        ax.set_xlim(0, 1)
        ax.tick_params(labelsize=9)
    label = shape.label if shape is not None else "miscalibrated"
    left.set_title(f"{name}: {label}", fontsize=11, loc="left")
    banner(fig, ds)
    return save(fig, path)


def pit_caption(t: TreeView, name: str) -> str:
    """What the LOO-PIT figure of law ``name`` shows and how to read it, with the direction in words."""
    shape = t.pit(name)[2]
    said = shape.text() if shape is not None else "the PIT values were not stored"
    n = int(t.attrs.get("n_obs", 0))
    sample = (f"{shape.n} observations, a random subsample of the {n} rows" if shape is not None and 0 < shape.n < n
              else f"{shape.n if shape is not None else '?'} observations")
    return (f"LOO-PIT of {name} ({sample}): {said}. Left: histogram "
            "against the flat density of a calibrated law (grey: ± 2 sd of a bin); right: the ECDF minus the uniform "
            "CDF against the simultaneous band the check tested. Read: a U-shaped histogram (ECDF difference above "
            "zero on the left, below on the right) means intervals too narrow, a hump (below, then above) too wide, "
            "a difference of one sign throughout biased predictions; trust this law's intervals (and any sizing "
            "from them) only after the noise model or the law is fixed.")
