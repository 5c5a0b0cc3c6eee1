"""Figure helpers shared by the report (provenance label and banner, atomic PNG writing) and the
sizing fan (predictive bands beyond the tested envelope); a study's other figures are in
:mod:`bayesfric.report.study_figures`."""

from __future__ import annotations

import os
import tempfile
import textwrap
from pathlib import Path

import matplotlib as mpl
import numpy as np
import xarray as xr
from matplotlib.figure import Figure
from matplotlib.text import Text

from bayesfric.datasets.provenance import provenance_label, provenance_text
from bayesfric.report.typeset import unit as unit_text

#: The provenance labels are :mod:`bayesfric.datasets.provenance`'s, re-exported for the report.
__all__ = ["plot_sizing_fan", "provenance_label", "provenance_text", "banner", "save"]


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


def save(fig: Figure, path: Path, *, trim: bool = True) -> Path:
    """Write ``fig`` as PNG atomically (temporary file, then rename), every text drawn literally
    (a study label with ``$`` in it is not parsed as mathtext, which would fail on ``$x^$``).

    ``trim`` cuts the figure to what is drawn (matplotlib's tight bounding box, which lays out
    every text once more: 0.3-0.7 s of the ~1 s a 5 × 5 pair grid took); a figure whose margins
    are fixed for its labels passes False.
    """
    return _save(fig, path, trim)


def _save(fig, path: Path, trim: bool = True) -> Path:
    for text in fig.findobj(Text):  # labels are user text: a '$' is a dollar, never mathtext to parse
        text.set_parse_math(False)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=path.parent)
    os.close(fd)
    # a bare Figure renders with Agg: no pyplot state
    fig.savefig(tmp, dpi=110, **({"bbox_inches": "tight"} if trim else {}))
    os.replace(tmp, path)
    return path


def plot_sizing_fan(result, answer, path: Path, *, title: str = "") -> Path:
    """The extrapolation fan of a sizing question (:class:`bayesfric.sizing.Answer`).

    Friction magnitude ``|T|`` against the question's operating input (its range, else the input
    it extrapolates most along; other inputs at the question's values): the tested region
    shaded; per law its curve (median of the mean function) and 5–95 % band with observation
    noise, excluded laws dotted for reference; the model average's curve, band and required
    capacity at the question's confidence (dashed), and where blocked folds measured the laws'
    model-form error the average's calibrated 5–95 % band of the curve (grey) and calibrated
    required capacity (dash-dot); laws with zero weight faded; the measured data (grey dots,
    every condition); the available capacity (horizontal line) and the asked point(s). Units are
    those the question and data use.
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
    if fan.measured is not None:  # the data along this axis (other inputs at every tested value)
        ax.plot(value.display(fan.measured[0]), fan.measured[1] / scale, ".", ms=2.5, color="0.45", alpha=0.6,
                zorder=1, label="measured (all conditions)")
    colours = [mpl.colormaps["tab10"](i % 10) for i in range(len(fan.laws))]
    for c, (name, band) in zip(colours, fan.laws.items(), strict=True):
        if name in fan.excluded:
            ax.plot(x, band["curve"] / scale, ":", lw=1.0, color=c, label=f"{name} (excluded)")
            continue
        weight = next((a.weight for a in answer.laws if a.name == name), 0.0)
        faded = answer.basis is not None and not weight > 0.005  # zero weight: shown, faded
        ax.plot(x, band["curve"] / scale, "-", lw=0.8 if faded else 1.3, color=c, alpha=0.35 if faded else 1.0,
                label=f"{name} (w = {weight:.2f})" if answer.basis is not None else name)
        if not faded:  # a zero-weight law: its curve only, faded
            ax.fill_between(x, band["lo"] / scale, band["hi"] / scale, color=c, alpha=0.12, lw=0)
    if fan.average is not None and answer.basis is not None:
        ax.fill_between(x, fan.average["lo"] / scale, fan.average["hi"] / scale, facecolor="none",
                        edgecolor="k", hatch="///", lw=0.6, label="model average, 5–95 % with noise (within-model)")
        ax.plot(x, fan.average["curve"] / scale, "k-", lw=2.0, label="model average, curve")
        ax.plot(x, fan.average["required"] / scale, "k--", lw=1.4,
                label=f"required capacity ({question.confidence:g} quantile, within-model)")
    if fan.average is not None and "cal_lo" in fan.average:
        ax.fill_between(x, fan.average["cal_lo"] / scale, fan.average["cal_hi"] / scale, color="k", alpha=0.15,
                        lw=0, label="model average, calibrated 5–95 % of the curve (model-form error)")
        ax.plot(x, fan.average["cal_required"] / scale, "k-.", lw=1.4,
                label=f"calibrated required capacity ({question.confidence:g})")
    if question.capacity is not None:
        number, _, given = question.capacity.text.partition(" ")
        ax.axhline(question.capacity.lo / scale, color="crimson", lw=1.5, label=f"capacity {number} {unit_text(given)}")
    asked = value.display(np.array([value.lo, value.hi]))
    if value.is_range:
        ax.axvspan(asked[0], asked[1], ymax=0.025, color="tab:orange", lw=0, label="asked range")
        for edge in asked:
            ax.axvline(edge, color="tab:orange", lw=1.0, ls=":")
    else:
        ax.axvline(asked[0], color="tab:orange", lw=1.2, ls=":", label="asked point")
    others = ", ".join(f"{k} = {v.text}" for k, v in question.at.items() if k != fan.axis)
    ax.set_xlabel(f"{fan.axis} [{unit_text(value.unit)}]" + (f"   ({others})" if others else ""))
    ax.set_ylabel(f"|{result.response}| [{unit_text(result.response_unit)}]")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    head = f"sizing: {question.label}"
    label = "\n".join(textwrap.wrap(result.provenance, 120))
    ax.set_title((title + "\n" if title else "") + head + "\n" + label, fontsize=8)
    return _save(fig, path)
