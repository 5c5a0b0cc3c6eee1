"""Figures of a study: data with each law's posterior predictive, residuals along an axis, and the
sizing fan (predictive bands beyond the tested envelope)."""

from __future__ import annotations

import os
import tempfile
import textwrap
from pathlib import Path

import matplotlib as mpl
import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from bayesfric.quantities import QUANTITIES

__all__ = ["plot_predictive", "plot_sizing_fan", "provenance_label", "banner", "save"]


def provenance_label(ds: xr.Dataset) -> str:
    """The label every figure and table of a dataset carries (reconstructed / measured / simulated)."""
    prov = ds.attrs.get("provenance", "?")
    source = ds.attrs.get("source", "")
    if prov == "reconstructed":
        return f"RECONSTRUCTED data (not measured) — reconstructed from {source}"
    if prov == "simulated":
        return f"SIMULATED data — {source}"
    return f"measured data — {source}"


def banner(fig: Figure, ds: xr.Dataset) -> None:
    """Stamp the data's provenance on a figure: a red "RECONSTRUCTED DATA" banner when the data
    set says it was reconstructed from a paper's figures (``ds.attrs["provenance"]``), a grey
    provenance line otherwise."""
    prov = ds.attrs.get("provenance", "?")
    # As the figure's suptitle: a constrained layout keeps room for it above every panel title.
    if prov == "reconstructed":
        fig.suptitle("RECONSTRUCTED DATA — not measured", x=0.995, ha="right", fontsize=9, fontweight="bold",
                     color="white", bbox={"facecolor": "crimson", "edgecolor": "none", "pad": 3})
    else:
        fig.suptitle("SIMULATED DATA" if prov == "simulated" else "measured data", x=0.995, ha="right",
                     fontsize=8, color="0.3")


def save(fig: Figure, path: Path) -> Path:
    """Write ``fig`` as PNG atomically (temporary file, then rename)."""
    return _save(fig, path)


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=path.parent)
    os.close(fd)
    fig.savefig(tmp, dpi=110, bbox_inches="tight")  # a bare Figure renders with Agg: no pyplot state
    os.replace(tmp, path)
    return path


def plot_predictive(
    ds: xr.Dataset,
    fits: dict[str, xr.DataTree],
    axis: str,
    path: Path,
    *,
    heldout: np.ndarray | None = None,
    title: str = "",
) -> Path:
    """Observed response and each law's posterior-predictive mean and 90 % band along ``axis``.

    Upper panel: data (held-out points of the first blocked scheme marked) and, per law, the
    posterior-predictive mean at each observation. Lower panel: standardised residuals
    (observed − mean) / predictive sd, which shows where along the envelope each law fails.
    """
    x = np.asarray(ds[axis].values, dtype=float)
    unit = QUANTITIES[axis].unit if axis in QUANTITIES else ""
    y = np.asarray(ds[ds.attrs["response"]].values, dtype=float)
    order = np.argsort(x, kind="stable")
    fig = Figure(figsize=(8.5, 7.5))
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    top.plot(x, y, "o", ms=3, color="0.35", alpha=0.6, label="data")
    if heldout is not None and heldout.any():
        top.plot(x[heldout], y[heldout], "o", ms=4, mfc="none", mec="crimson", label="held out (blocked CV)")
    colours = mpl.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (name, dt) in enumerate(fits.items()):
        pp = np.asarray(dt["posterior_predictive"]["response"].values)
        pp = pp.reshape(-1, pp.shape[-1])
        mean, sd = pp.mean(axis=0), pp.std(axis=0)
        lo, hi = np.quantile(pp, [0.05, 0.95], axis=0)
        c = colours[i % len(colours)]
        top.plot(x[order], mean[order], "-", lw=1.2, color=c, label=name)
        top.fill_between(x[order], lo[order], hi[order], color=c, alpha=0.12, lw=0)
        bottom.plot(x, (y - mean) / np.where(sd > 0, sd, 1.0), ".", ms=3, color=c, alpha=0.7)
    bottom.axhline(0, color="k", lw=0.8)
    for level in (-2, 2):
        bottom.axhline(level, color="k", lw=0.5, ls=":")
    response = ds.attrs["response"]
    top.set_ylabel(f"{response} [{ds[response].attrs.get('units', '')}]")
    bottom.set_ylabel("standardised residual")
    bottom.set_xlabel(f"{axis} [{unit}]")
    top.legend(fontsize=7, ncol=2)
    top.set_title((title + "\n" if title else "") + provenance_label(ds), fontsize=8)
    return _save(fig, path)


def plot_sizing_fan(result, answer, path: Path, *, title: str = "") -> Path:
    """The extrapolation fan of a sizing question (:class:`bayesfric.sizing.Answer`).

    Friction magnitude ``|T|`` against the question's operating input (its range, else the input
    it extrapolates most along; other inputs at the question's values): the tested region
    shaded; per law its curve (median of the mean function) and 5–95 % band with observation
    noise, excluded laws dotted for reference; the model average's curve, band and required
    capacity at the question's confidence (dashed); the available capacity (horizontal line) and
    the asked point(s). Units are those the question and data use.
    """
    fan = answer.fan
    question = answer.question
    value = question.at[fan.axis]
    x = value.display(fan.x)
    scale = result.response_scale
    fig = Figure(figsize=(10, 5.5))
    ax = fig.subplots()
    lo, hi = value.display(np.array(fan.tested))
    ax.axvspan(min(lo, hi), max(lo, hi), color="0.9", lw=0, label="tested range")
    colours = mpl.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (name, band) in enumerate(fan.laws.items()):
        c = colours[i % len(colours)]
        if name in fan.excluded:
            ax.plot(x, band["curve"] / scale, ":", lw=1.0, color=c, label=f"{name} (excluded)")
            continue
        weight = next((a.weight for a in answer.laws if a.name == name), 0.0)
        ax.plot(x, band["curve"] / scale, "-", lw=1.1, color=c, label=f"{name} (w = {weight:.2f})")
        ax.fill_between(x, band["lo"] / scale, band["hi"] / scale, color=c, alpha=0.10, lw=0)
    if fan.average is not None:
        ax.fill_between(x, fan.average["lo"] / scale, fan.average["hi"] / scale, facecolor="none",
                        edgecolor="k", hatch="///", lw=0.6, label="model average, 5–95 % with noise")
        ax.plot(x, fan.average["curve"] / scale, "k-", lw=2.0, label="model average, curve")
        ax.plot(x, fan.average["required"] / scale, "k--", lw=1.4,
                label=f"required capacity ({question.confidence:g} quantile)")
    if question.capacity is not None:
        ax.axhline(question.capacity.lo / scale, color="crimson", lw=1.5, label=f"capacity {question.capacity.text}")
    asked = value.display(np.array([value.lo, value.hi]))
    if value.is_range:
        ax.axvspan(asked[0], asked[1], ymax=0.025, color="tab:orange", lw=0, label="asked range")
        for edge in asked:
            ax.axvline(edge, color="tab:orange", lw=1.0, ls=":")
    else:
        ax.axvline(asked[0], color="tab:orange", lw=1.2, ls=":", label="asked point")
    others = ", ".join(f"{k} = {v.text}" for k, v in question.at.items() if k != fan.axis)
    ax.set_xlabel(f"{fan.axis} [{value.unit}]" + (f"   ({others})" if others else ""))
    ax.set_ylabel(f"|{result.response}| [{result.response_unit}]")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    head = f"sizing: {question.label}"
    label = "\n".join(textwrap.wrap(result.provenance, 120))
    ax.set_title((title + "\n" if title else "") + head + "\n" + label, fontsize=8)
    return _save(fig, path)
