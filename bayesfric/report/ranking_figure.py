"""The ranking figure: each law's score ± 1 standard error per criterion, in ranking order.

Laid out to be read at page width and on a phone (a 390 px screen shows a figure about 360 px
wide): one column of panels, :data:`WIDTH` inches wide with :data:`FONT`-point text, so the
text is about 10 px high when the image is scaled down to a phone's width (and 17 px at its
natural 600 px on a page); one panel per criterion, the log-evidence estimators sharing one
panel (they estimate the same number); long law names wrapped at an underscore so they do not
run into the panel. Unreliable results (not ranked: a fold or the fit failed the gate, the
evidence estimators disagree) are red crosses at their place; the dashed line is the ranked
winner's score.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from bayesfric.report.figures import banner, save
from bayesfric.study import scores as sc

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr

    from bayesfric.report.view import TreeView

__all__ = ["plot_ranking", "wrap_name", "WIDTH", "FONT"]

#: Figure width in inches (550 px at the report's 110 dpi).
WIDTH = 5.0
#: Text size in points.
FONT = 13
#: Law names longer than this are wrapped at an underscore.
NAME_CHARS = 18
_MARKERS = ("o", "D", "s", "^")


def wrap_name(name: str, width: int = NAME_CHARS) -> str:
    """``name`` on two lines, split at the underscore nearest its middle, when longer than
    ``width`` characters (``prestressed_roller_bearing`` → ``prestressed_\\nroller_bearing``)."""
    if len(name) <= width or "_" not in name:
        return name
    cuts = [i for i, ch in enumerate(name) if ch == "_"]
    cut = min(cuts, key=lambda i: abs(i + 1 - len(name) / 2))
    return name[:cut + 1] + "\n" + name[cut + 1:]


def _panels(crits: list[sc.Criterion]) -> list[list[sc.Criterion]]:
    """Criteria grouped into panels: every log-evidence estimator in one panel, the rest alone."""
    panels = [[c] for c in crits if c.metric != "log_evidence"]
    evidence = [c for c in crits if c.metric == "log_evidence"]
    return panels + ([evidence] if evidence else [])


def _title(group: list[sc.Criterion]) -> str:
    if group[0].metric == "log_evidence":
        return "log evidence (" + ", ".join(f"{m} {c.scheme}" for m, c in zip("●◆■▲", group, strict=False)) + ")"
    return "\n".join(textwrap.wrap(group[0].label, 44))


def _panel(ax, table: pd.DataFrame, order: list[str], group: list[sc.Criterion], y: np.ndarray) -> None:
    step = 0.22 if len(group) > 1 else 0.0
    for k, c in enumerate(group):
        offset = step * (k - (len(group) - 1) / 2)
        for yi, name in zip(y, order, strict=True):
            row = sc.value(table, name, c.metric, c.scheme)
            if row is None:
                continue
            se = row["se"] if math.isfinite(row["se"]) else 0.0
            ok = bool(row["reliable"])
            ax.errorbar(row["estimate"], yi - offset, xerr=se, fmt=_MARKERS[k % 4] if ok else "x",
                        color="k" if ok else "crimson", ms=6 if ok else 8, capsize=3, mew=1.5)
        winner = sc.best(table, c.metric, c.scheme)
        if winner is not None and k == 0:
            ax.axvline(float(sc.value(table, winner, c.metric, c.scheme)["estimate"]), color="0.4", ls="--", lw=1)
    ax.set_title(_title(group), fontsize=FONT, loc="left")
    ax.set_xlabel("log evidence [nats]" if group[0].metric == "log_evidence" else "elpd [nats]", fontsize=FONT)
    ax.tick_params(labelsize=FONT - 1)
    ax.grid(axis="x", lw=0.3)
    ax.set_ylim(-0.6, len(order) - 0.4)


def plot_ranking(t: TreeView, ds: xr.Dataset, path: Path) -> Path:
    """One panel per criterion (blocked elpd, LOO elpd, other CV, log evidence), stacked: each
    law's estimate ± 1 se in ranking order, the ranked winner's value as a dashed line, results
    that may not be ranked as red crosses (the layout of arviz compare plots, one panel per
    scale, in one column so that it reads on a phone)."""
    crits = t.crits
    order = sc.ranking_order(t.table, t.laws, crits[0] if crits else None)
    panels = _panels(crits) or [[]]
    labels = [wrap_name(n) for n in order]
    lines = sum(label.count("\n") + 1 for label in labels)
    height = [0.17 * lines + 0.12 * len(order) + 0.9 + 0.2 * _title(g).count("\n") if g else 1.0 for g in panels]
    fig = Figure(figsize=(WIDTH, sum(height) + 0.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(panels), 1, squeeze=False, height_ratios=height)).ravel()
    y = np.arange(len(order))[::-1]
    for ax, group in zip(axes, panels, strict=True):
        if group:
            _panel(ax, t.table, order, group, y)
        ax.set_yticks(y, labels, fontsize=FONT - 1)
    banner(fig, ds)
    return save(fig, path)
