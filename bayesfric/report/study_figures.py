"""The figures of a study report, drawn from the study's result tree (its law × metric table,
held-out rows and checks, through :class:`~bayesfric.report.view.TreeView`), the data set and
the full fits (their predictive draws).

Every figure is a bare matplotlib :class:`~matplotlib.figure.Figure` (Agg canvas, no pyplot
state, the user's backend untouched), carries the data's provenance banner
(:func:`bayesfric.report.figures.banner`) and units on its axes, and comes with a caption that
says what to read from it (:class:`bayesfric.report.blocks.FigureRef`).

Why not arviz-plots. arviz-plots 1.3 has ``plot_compare`` and ``plot_pair``, but its matplotlib
backend makes every figure through ``matplotlib.pyplot.subplots`` (``arviz_plots/backend/
matplotlib/core.py``): importing pyplot selects a process-wide backend and registers figures in
pyplot's global manager, which this package must not do to its user. ``plot_compare`` also takes
LOO objects only, while this ranking puts blocked CV and log evidence (other scales, other
reliability rules from the score table) beside LOO. So the compare-style and pair plots are drawn
here with bare matplotlib, in the same layout.

Cost. Figures read stored draws only (no sampling). The pair plots and the predictive bands are
thinned to :data:`MAX_DRAWS` draws; the trajectory panels evaluate nothing (they plot the fits'
stored posterior-predictive draws). Measured with ``benchmarks/bench_figures.py`` (2026-11-23,
2-core machine shared with other jobs, load 5-7): on the shipped robot_joint study (6 laws,
``--quick``) the figures took 23.8 s and the whole report 24.8 s against a median fit of 80.7 s,
0.30× and 0.31× one fit; on pitch_bearing reduced to 3 laws 3.9 s against 131 s (0.03×). The
report is a few tenths of one fit at most, well inside a study's budget of many fits.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure

from bayesfric.limits import CHUNK_NUMBERS
from bayesfric.quantities import QUANTITIES, UnitError, conversion
from bayesfric.report.blocks import FigureRef
from bayesfric.report.figures import banner, plot_sizing_fan, save
from bayesfric.report.pit_figure import pit_caption, plot_loo_pit
from bayesfric.report.ranking_figure import plot_ranking
from bayesfric.report.typeset import unit
from bayesfric.study import scores as sc

if TYPE_CHECKING:
    from collections.abc import Mapping

    import xarray as xr

    from bayesfric.laws.base import Law
    from bayesfric.report.view import TreeView
    from bayesfric.sizing.result import SizingAnswer

__all__ = ["draw", "plot_ranking", "plot_penalty", "plot_bands", "plot_pairs", "plot_trajectories", "MAX_DRAWS"]

#: Posterior draws used by the pair plots and bands (evenly thinned).
MAX_DRAWS = 400
#: Most laws drawn as separate panels of the predictive bands; trajectories shown per study.
MAX_PANELS, MAX_TRAJECTORIES = 6, 6
#: Speeds at which a law with group terms is drawn for a new group (a dashed 90 % band).
NEW_BAND_POINTS = 60


def _colours() -> list[str]:
    return mpl.rcParams["axes.prop_cycle"].by_key()["color"]


def _display(ds, name: str) -> tuple[str, float, float]:
    """(unit, scale, offset) to show ``name`` in the unit of the data file (MN·m, rpm, °C), with
    ``shown = (si − offset) / scale``; SI when the data set does not record its original unit. The
    unit is typeset (:func:`bayesfric.report.typeset.unit`)."""
    attrs = ds[name].attrs
    original, quantity = attrs.get("original_unit"), attrs.get("quantity", name)
    if original and quantity in QUANTITIES:
        try:
            scale, offset = conversion(original, quantity)
            return unit(str(original)), float(scale), float(offset)
        except UnitError:
            pass
    return unit(str(attrs.get("units") or (QUANTITIES[name].unit if name in QUANTITIES else ""))), 1.0, 0.0


def _shown(ds, name: str, values) -> np.ndarray:
    _, scale, offset = _display(ds, name)
    return (np.asarray(values, dtype=float) - offset) / scale


def _order(t: TreeView) -> list[str]:
    """The laws in ranking order on the study's first criterion; in the study's order when it has
    none (``loo = false``, ``evidence = false``, no folds: the report says so)."""
    return sc.ranking_order(t.table, t.laws, t.crits[0] if t.crits else None)


def plot_penalty(t: TreeView, ds: xr.Dataset, path: Path) -> Path:
    """Extrapolation penalty per law and blocked scheme, ± 1 standard error: nats per held-out
    point lost outside the tested envelope relative to inside it (0 = extrapolates as well as it
    interpolates)."""
    table = t.table
    order = _order(t)
    fig = Figure(figsize=(8.5, 0.42 * len(order) + 1.6), layout="constrained")
    ax = fig.subplots()
    y = np.arange(len(order))[::-1]
    step = 0.8 / max(1, len(t.blocked))
    for k, (scheme, colour) in enumerate(zip(t.blocked, _colours(), strict=False)):
        label = scheme  # on the scheme's first point (laws without a penalty have none)
        for yi, name in zip(y, order, strict=True):
            row = sc.value(table, name, "penalty", scheme)
            if row is None:
                continue
            yy = yi + 0.4 - step * (k + 0.5)
            ax.plot([0, row["estimate"]], [yy, yy], color=colour, lw=2)
            ok = bool(row["reliable"])
            se = row["se"] if math.isfinite(row["se"]) else 0.0  # ± 1 se of the paired differences
            ax.errorbar(row["estimate"], yy, xerr=se, fmt="o" if ok else "x", color=colour if ok else "crimson", ms=6,
                        capsize=3, label=label)
            label = None
    ax.axvline(0, color="k", lw=0.8)
    ax.set_yticks(y, order, fontsize=8)
    ax.set_xlabel("extrapolation penalty [nats per held-out point] (lower is better)")
    if ax.get_legend_handles_labels()[1]:
        ax.legend(fontsize=7, loc="best")
    banner(fig, ds)
    return save(fig, path)


def _picked(dt, group: str, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The stored draws (chain and draw flattened) × rows as stored, and the at most MAX_DRAWS
    evenly spaced draws to use."""
    v = dt[group][name].values
    v = v.reshape(v.shape[0] * v.shape[1], -1)
    return v, np.linspace(0, len(v) - 1, min(MAX_DRAWS, len(v))).astype(int)


def _draws(dt, group: str, name: str) -> np.ndarray:
    """At most MAX_DRAWS evenly spaced draws (chain and draw flattened) × rows, picked before the
    cast to float64 (a large fit's groups are float32: no float64 copy of every draw × row)."""
    v, pick = _picked(dt, group, name)
    return np.asarray(v[pick], dtype=float)


def _band(ds, response: str, fit) -> np.ndarray:
    """5, 50 and 95 % of the fit's predictive draws (:func:`_draws`, in display units) per row,
    ``(3, rows)``. Computed for :data:`~bayesfric.limits.CHUNK_NUMBERS` draws × rows at a time:
    each row's quantiles read that row's column only, so the chunks give the one-call numbers
    without its three copies of draws × rows in float64 (1 GB at 10⁵ rows)."""
    v, pick = _picked(fit, "posterior_predictive", "response")
    step = max(1, CHUNK_NUMBERS // len(pick))
    out = np.empty((3, v.shape[1]))
    for start in range(0, v.shape[1], step):
        part = _shown(ds, response, np.asarray(v[pick, start:start + step], dtype=float))
        out[:, start:start + step] = np.quantile(part, [0.05, 0.5, 0.95], axis=0)
    return out


def _new_group_band(ds, response: str, fit, axis: str, x: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """(grid, 5 %, 95 %) in display units of a law with group terms, for a NEW group (run, unit)
    at ``NEW_BAND_POINTS`` values of ``axis`` over the data (:func:`bayesfric.sizing.compute.predict`:
    the group spread integrated over, with noise); None for a law without group terms or one that
    reads more than ``axis``."""
    from bayesfric.laws.variants import law_of_fit
    from bayesfric.sizing.compute import predict
    from bayesfric.sizing.points import SizingError

    law = law_of_fit(fit.attrs)
    if not law.varying or law.trajectory or list(law.operating_inputs) != [axis]:
        return None
    grid = np.linspace(float(np.min(x)), float(np.max(x)), NEW_BAND_POINTS)
    try:
        y = predict(fit, {axis: grid}).y.reshape(-1, grid.size)
    except SizingError:
        return None
    lo, hi = np.quantile(_shown(ds, response, y), [0.05, 0.95], axis=0)
    return _shown(ds, axis, grid), lo, hi


def plot_bands(t: TreeView, ds: xr.Dataset, fits: Mapping[str, xr.DataTree], axis: str, path: Path,
               heldout: np.ndarray | None) -> Path:
    """One panel per law (best first, at most :data:`MAX_PANELS`): data against ``axis``, the
    law's posterior-predictive mean and 90 % band, the trained region shaded, held-out points
    marked. With several inputs the band is drawn per observation (vertical bars)."""
    response = ds.attrs["response"]
    x, y = _shown(ds, axis, ds[axis].values), _shown(ds, response, ds[response].values)
    order = _order(t)[:MAX_PANELS]
    one_input = sum(v.attrs.get("role") == "input" for v in ds.coords.values()) == 1
    cols = min(3, len(order))
    rows = math.ceil(len(order) / cols)
    fig = Figure(figsize=(4.0 * cols, 3.0 * rows + 0.5), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True, sharey=True, squeeze=False)).ravel()
    trained = ~heldout if heldout is not None else np.ones_like(x, dtype=bool)
    s = np.argsort(x, kind="stable")
    for ax, name, colour in zip(axes, order, _colours() * 3, strict=False):
        lo, mid, hi = _band(ds, response, fits[name])
        ax.axvspan(x[trained].min(), x[trained].max(), color="#e6f2e6", lw=0, zorder=0)  # trained region
        ax.plot(x[trained], y[trained], ".", ms=3, color="0.35")
        if heldout is not None and heldout.any():
            ax.plot(x[heldout], y[heldout], "o", ms=4, mfc="none", mec="crimson")
        if one_input:
            ax.fill_between(x[s], lo[s], hi[s], color=colour, alpha=0.25, lw=0)
            ax.plot(x[s], mid[s], "-", color=colour, lw=1.3)
            if (new := _new_group_band(ds, response, fits[name], axis, ds[axis].values)) is not None:
                ax.plot(new[0], new[1], "--", color=colour, lw=1.0, label="a new group, 90 %")
                ax.plot(new[0], new[2], "--", color=colour, lw=1.0)
                ax.legend(fontsize=6, loc="best")
        else:
            ax.vlines(x, lo, hi, color=colour, alpha=0.25, lw=2)
            ax.plot(x, mid, "_", color=colour, ms=6)
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in axes[len(order):]:
        ax.set_visible(False)
    fig.supxlabel(f"{axis} [{_display(ds, axis)[0]}]   (green: trained region; red circles: held out; band: the "
                  "tested runs; dashed, laws with group terms: a NEW group)", fontsize=8)
    fig.supylabel(f"{response} [{_display(ds, response)[0]}]", fontsize=8)
    banner(fig, ds)
    return save(fig, path)


def plot_pairs(fit: xr.DataTree, law: Law, ds: xr.Dataset, path: Path) -> Path | None:
    """Pairwise scatter of a law's scalar coefficients (at most 5, :data:`MAX_DRAWS` draws), with
    units; correlated coefficients show as slanted clouds. None for a one-parameter law."""
    post = fit["posterior"]
    names = [k for k, p in law.params.items() if not p.shape and k in post][:5]
    if len(names) < 2:
        return None
    draws = {k: _draws(fit, "posterior", k)[:, 0] for k in names}
    n = len(names)
    # fixed margins, not the constrained layout: it measured every label of the n × n grid
    # again and again (0.4 of the ~1 s a 5 × 5 grid took); nor trimmed on saving (another 0.3 s)
    fig = Figure(figsize=(1.9 * n + 0.6, 1.9 * n + 0.4))
    fig.subplots_adjust(left=0.6 / (1.9 * n + 0.6) + 0.04, right=0.98, bottom=0.5 / (1.9 * n + 0.4) + 0.03,
                        top=0.94, wspace=0.3, hspace=0.3)
    axes = fig.subplots(n, n, squeeze=False)
    for i, a in enumerate(names):
        for j, b in enumerate(names):
            ax = axes[i, j]
            if j > i:
                ax.set_visible(False)
                continue
            if i == j:
                ax.hist(draws[a], bins=30, color="0.5")
                ax.set_yticks([])
            else:
                ax.plot(draws[b], draws[a], ".", ms=1.5, alpha=0.4, color="tab:blue")
                r = np.corrcoef(draws[b], draws[a])[0, 1]
                ax.text(0.03, 0.92, f"r = {r:+.2f}", transform=ax.transAxes, fontsize=7,
                        color="crimson" if abs(r) > 0.7 else "k")
            ax.tick_params(labelsize=6)
            if i == n - 1:
                ax.set_xlabel(f"{b} [{unit(law.params[b].unit)}]", fontsize=7)
            if j == 0 and i > 0:
                ax.set_ylabel(f"{a} [{unit(law.params[a].unit)}]", fontsize=7)
    banner(fig, ds)
    return save(fig, path, trim=False)


def _path_axis(ds, law) -> str:
    inputs = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    return next((k for k in ("angle", "displacement", "time") if k in inputs and k in law.operating_inputs),
                next(k for k in ("angle", "displacement", "time") if k in inputs))


def plot_trajectories(t: TreeView, ds: xr.Dataset, fits: Mapping[str, xr.DataTree], path: Path) -> Path | None:
    """Measured vs predicted trajectories (hysteresis loops, coast-downs) for the best two laws,
    one panel per trajectory (at most :data:`MAX_TRAJECTORIES`, evenly chosen); held-out
    trajectories say so in their title. None when the data have no trajectories."""
    key = ds.attrs.get("trajectory")
    if not key:
        return None
    order = _order(t)[:2]
    axis = _path_axis(ds, t.law_object(order[0]))
    ids = list(dict.fromkeys(np.asarray(ds[key].values).tolist()))
    ids = [ids[i] for i in np.unique(np.linspace(0, len(ids) - 1, min(MAX_TRAJECTORIES, len(ids))).astype(int))]
    held = t.heldout(t.blocked[0]) if t.blocked else None
    response = ds.attrs["response"]
    cols = min(3, len(ids))
    fig = Figure(figsize=(4.0 * cols, 3.0 * math.ceil(len(ids) / cols) + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(math.ceil(len(ids) / cols), cols, squeeze=False)).ravel()
    bands = {name: _band(ds, response, fits[name]) for name in order}
    values = np.asarray(ds[key].values)
    for ax, tid in zip(axes, ids, strict=False):
        m = values == tid
        x = _shown(ds, axis, ds[axis].values)[m]
        ax.plot(x, _shown(ds, response, ds[response].values)[m], ".", ms=3, color="0.3", label="measured")
        for name, colour in zip(order, _colours(), strict=False):
            lo, mid, hi = (b[m] for b in bands[name])
            ax.fill_between(x, lo, hi, color=colour, alpha=0.2, lw=0) if axis == "time" else None
            ax.plot(x, mid, "-", color=colour, lw=1.1, label=name)
        out = held is not None and bool(held[m].any())
        ax.set_title(f"{key} {tid}" + (" (held out)" if out else ""), fontsize=8, color="crimson" if out else "k")
        ax.tick_params(labelsize=7)
    for ax in axes[len(ids):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    fig.supxlabel(f"{axis} [{_display(ds, axis)[0]}]", fontsize=8)
    fig.supylabel(f"{response} [{_display(ds, response)[0]}]", fontsize=8)
    banner(fig, ds)
    return save(fig, path)


def _band_axes(t: TreeView, ds: xr.Dataset) -> list[tuple[str, np.ndarray | None]]:
    inputs = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    if ds.attrs.get("trajectory"):  # along a path the trajectory panels say more; bands over condition inputs
        inputs = [k for k in inputs if k not in ("angle", "displacement", "time", "velocity")] or inputs
    blocked = t.blocked_axes
    axes = list(dict.fromkeys([a for a in blocked.values() if a in inputs] + inputs))
    held = {a: t.heldout(label) for label, a in blocked.items()}
    return [(a, held.get(a)) for a in axes[:2]]


def draw(t: TreeView, ds: xr.Dataset, fits: Mapping[str, xr.DataTree], folder: Path,
         sizing: SizingAnswer | None = None) -> tuple[list[FigureRef], dict[int, Path]]:
    """Every figure of the report into ``folder/figures``: (references with captions, sizing fans
    by question index). The scores, order, held-out rows and checks come from the result tree
    (``t``); the data set gives the points and the banner; ``fits`` (the full fits, with their
    predictive draws) the bands; ``sizing`` the fans."""
    fdir = folder / "figures"
    refs = []
    if t.crits:
        plot_ranking(t, ds, fdir / "ranking.png")
        refs.append(FigureRef("ranking", "figures/ranking.png",
                              "Each law's score ± 1 standard error per criterion, best first; the dashed line is the "
                              "best ranked law. Read: is the leader separated from the next by more than the error "
                              "bars? Red crosses: results that may not be ranked, shown where they scored (the reason "
                              "is in the table's rank column).", "ranking plot"))
    if t.blocked and t.has_loo:
        plot_penalty(t, ds, fdir / "penalty.png")
        refs.append(FigureRef("extrapolation", "figures/penalty.png",
                              "Nats per held-out point each law loses outside the tested envelope compared with "
                              "inside it, ± 1 standard error. Read: a long bar means the law fits the tested range but "
                              "should not be trusted beyond it.", "extrapolation penalty"))
    for axis, held in _band_axes(t, ds):
        plot_bands(t, ds, fits, axis, fdir / f"bands_{axis}.png", held)
        refs.append(FigureRef("extrapolation", f"figures/bands_{axis}.png",
                              f"Posterior-predictive median and 90 % band of each law over {axis}; green: the region "
                              "the blocked fit trained on, red circles: held-out points (bands are from the full "
                              "fit). Read: where the bands leave the data, the law fails.", f"bands over {axis}"))
    if plot_trajectories(t, ds, fits, fdir / "trajectories.png") is not None:
        refs.append(FigureRef("trajectories", "figures/trajectories.png",
                              "Measured trajectories (dots) against the two best-ranked laws' posterior-predictive "
                              "medians (from the full fit), per condition; conditions held out by the first blocked "
                              "scheme are titled in red. Read: does the law follow the loop or coast-down shape, "
                              "and does it keep doing so at the held-out conditions?", "trajectories"))
    for name in t.laws:
        if plot_pairs(t.fit(name), t.law_object(name), ds, fdir / f"pairs_{name}.png") is not None:
            refs.append(FigureRef(f"parameters:{name}", f"figures/pairs_{name}.png",
                                  "Posterior draws of each pair of coefficients, r = correlation (red when |r| > 0.7)."
                                  " Read: strongly correlated coefficients are not identified separately — quote "
                                  "their combination, not each alone.", f"pair plot {name}"))
    for name in t.laws:  # the laws whose LOO-PIT left its band: which way they are off
        if not t.flag(name, "loo_pit_ok") and plot_loo_pit(t, name, ds, fdir / f"loo_pit_{name}.png") is not None:
            refs.append(FigureRef("data", f"figures/loo_pit_{name}.png", pit_caption(t, name), f"LOO-PIT {name}"))
    fans = {}
    if sizing is not None:
        for i, answer in enumerate(sizing.answers):
            if answer.fan is not None:
                fans[i] = plot_sizing_fan(sizing, answer, fdir / f"sizing_{i + 1}.png", title=str(t.attrs["title"]))
    return refs, fans
