"""The report's time-to-exceed answers: a fan over service time and a table per question.

Reads the study's ``/service`` node (:func:`bayesfric.sizing.exceed.answer_study`): per question
``q<i>`` each law with a trend and their average. Rendered as :class:`~bayesfric.report.sizing.Section`
objects inside the report's sizing part, with their own caption.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from bayesfric.report.figures import banner, save
from bayesfric.report.findings import Finding, _f
from bayesfric.report.sizing import Section
from bayesfric.report.typeset import fmt

__all__ = ["CAPTION", "draw", "sections", "headlines", "text"]

CAPTION = ("|friction| at the operating point against service time. Dots with bars: each tested campaign as "
           "fitted (median, 5–95 %); shaded: the forecast of the typical campaign (50 % and 90 % bands; a random "
           "walk's paths), dotted: where a single new campaign may lie (90 %); red line: the capacity; lower "
           "panel: P(capacity exceeded by then). Read: where the band meets the capacity line, and how wide it "
           "is there — that spread is the uncertainty in the time left.")


def _questions(node: xr.DataTree) -> list[tuple[str, xr.DataTree]]:
    return sorted(((k, v) for k, v in node.children.items() if k.startswith("q")), key=lambda kv: int(kv[0][1:]))


def _time(x: float, unit: str) -> str:
    if not math.isfinite(x):
        return "beyond the horizon"
    return f"{fmt(float(x), digits=3)} {unit}".strip()


def _plot(q: xr.DataTree, data: xr.Dataset, path: Path) -> Path:
    """One question's fan over service time (the average where there is one, else the first law)."""
    name = "average" if "average" in q.children else next(iter(q.children))
    res = q[name].to_dataset()
    unit, cap = str(q.attrs.get("unit", "")), float(res.attrs["capacity"])
    fig = Figure(figsize=(7.5, 6.0))
    top, low = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    t = res["service"].values
    fan, new = res["fan"], res["fan_new"]
    top.fill_between(t, fan.sel(quantile=0.05), fan.sel(quantile=0.95), alpha=0.25, color="C0", label="typical, 90 %")
    top.fill_between(t, fan.sel(quantile=0.25), fan.sel(quantile=0.75), alpha=0.35, color="C0", label="typical, 50 %")
    top.plot(t, fan.sel(quantile=0.5), color="C0")
    for level in (0.05, 0.95):
        top.plot(t, new.sel(quantile=level), ":", color="C0", label="a new campaign, 90 %" if level == 0.05 else None)
    c, cq = res["campaign"].values, res["campaign_q"]
    mid = cq.sel(quantile=0.5).values
    top.errorbar(c, mid, yerr=[mid - cq.sel(quantile=0.05).values, cq.sel(quantile=0.95).values - mid], fmt="o",
                 color="k", ms=4, label="tested campaigns (fitted)")
    top.axhline(cap, color="C3", lw=1.5, label=f"capacity {q.attrs.get('capacity', '')}")
    response = str(res.attrs.get("response", "friction"))
    top.set_ylabel(f"|{response}| ({ {'torque': 'N·m', 'force': 'N'}.get(response, 'SI') })")
    top.set_title(f"{q.attrs.get('label', '')}: {name}", fontsize=10)
    top.legend(fontsize=7, loc="upper left")
    low.plot(t, res["p_exceed"].values, color="C3")
    low.set_ylim(0, 1)
    low.set_ylabel("P(exceeded)")
    low.set_xlabel(f"service time ({unit})" if unit else "service coordinate")
    banner(fig, data)
    return save(fig, path)


def draw(node: xr.DataTree | None, data: xr.Dataset, folder: Path) -> dict[int, Path]:
    """Each question's fan into ``folder/figures/service_<i>.png``; question index -> file."""
    if node is None:
        return {}
    return {int(k[1:]): _plot(q, data, Path(folder) / "figures" / f"service_{int(k[1:]) + 1}.png")
            for k, q in _questions(node)}


def _row(name: str, res: xr.Dataset, unit: str) -> list[str]:
    q = res["crossing_q"]
    weight = res.attrs.get("weight")
    within = res["crossing_within_q"] if "crossing_within_q" in res else q
    return [name, "" if weight is None else f"{float(weight):.2f}", *(_time(float(q.sel(quantile=p)), unit)
                                                                      for p in (0.05, 0.5, 0.95)),
            f"{_time(float(within.sel(quantile=0.05)), unit)} – {_time(float(within.sel(quantile=0.95)), unit)}",
            f"{float(res['allowance'].values[-1]):.1%}" if "allowance" in res else "",
            f"{float(res.attrs['p_within_horizon']):.2f}", str(res.attrs.get("form", ""))]


def sections(node: xr.DataTree | None, figures: dict[int, str] | None = None, offset: int = 0) -> list[Section]:
    """One :class:`Section` per time-to-exceed question (``figures``: index -> the fan's reference)."""
    out = []
    for k, q in _questions(node) if node is not None else []:
        i, unit = int(k[1:]), str(q.attrs.get("unit", ""))
        sec = Section(f"Sizing {offset + i + 1}: {q.attrs['label']} — time to exceed", figure=(figures or {}).get(i),
                      caption=CAPTION)
        if lead := _statement(q):
            sec.lines.append(lead)
            if not _calibrated(q):
                sec.warnings.append("the interval of the time to exceed is not calibrated for the campaigns' upward "
                                    "bend: the crossing may come earlier (first line)")
        sec.lines.append(f"Asked: when does |friction| at {q.attrs['point']} first exceed {q.attrs['capacity']}, "
                         f"forecast up to {q.attrs['horizon']}?")
        sec.lines.append("Answer for the typical campaign: the fitted trend (a random walk: its simulated paths) at "
                         "the operating point, per posterior draw; its first crossing of the capacity. A single new "
                         "campaign scatters about it (dotted band). The trend is extrapolated past the last tested "
                         "campaign; its forecasts were scored by leave-future-out over campaigns "
                         "(benchmarks/bench_trend_forecast.py: coverage when the trend's form is and is not a "
                         "candidate).")
        if q.attrs.get("no_trend"):
            sec.lines.append("Laws without a trend cannot forecast service time and are left out: "
                             f"{q.attrs['no_trend']}.")
        if "average" in q.children:
            sec.lines.append(f"Average weighted by {q.attrs['weighting']} (the laws' forecasts of campaigns they "
                             f"had not seen): {q.attrs['weights']}.")
        else:
            sec.warnings.append("no weighted average: no law with a trend has a weight")
        rows = [_row(name, q[name].to_dataset(), unit) for name in q.children]
        sec.tables.append(("Time to exceed, per law and averaged (5 %, median, 95 % of the posterior with the "
                           "model-form allowance; within-model: the trend's own 90 % interval; allowance: the "
                           "relative sd added at the horizon; P(within) = the share of draws that exceed before "
                           "the horizon)",
                           ["law", "weight", "5 %", "median", "95 %", "within-model 90 %", "allowance",
                            "P(within horizon)", "trend"], rows))
        sec.lines += [f"Model-form allowance of {n}: {q[n].attrs['allowance']}." for n in q.children
                      if n != "average" and q[n].attrs.get("allowance")]
        sec.lines += [f"Campaign levels of {n} against its trend at the point: {q[n].attrs['bend']} "
                      f"({q[n].attrs.get('bend_test', '')})." for n in q.children
                      if n != "average" and q[n].attrs.get("bend")]
        steady = {str(q[n].attrs.get("steady", "")) for n in q.children} - {""}
        if steady:
            sec.lines.append("Stateful laws answer from their " + "; ".join(sorted(steady)) + ".")
        out.append(sec)
    return out



def _statement(q: xr.DataTree) -> str:
    """What a question's answer leads with: the question's own statement (a model average's, over
    the laws carrying weight), else the one law's where there is no average."""
    if "statement" in q.attrs or "average" in q.children:
        return str(q.attrs.get("statement", ""))
    first = next(iter(q.children), None)
    return "" if first is None else str(q[first].attrs.get("statement", ""))


def _calibrated(q: xr.DataTree) -> bool:
    """False where the answer is marked not calibrated for the campaigns' bend."""
    if "shape_calibrated" in q.attrs or "average" in q.children:
        return bool(int(q.attrs.get("shape_calibrated", 1)))
    first = next(iter(q.children), None)
    return first is None or bool(int(q[first].attrs.get("shape_calibrated", 1)))


def headlines(node: xr.DataTree | None) -> list[Finding]:
    """One finding per time-to-exceed question: the averaged (else the first law's) median time and
    90 % interval, emphasised, and the law and trend form it rests on."""
    out = []
    for _, q in _questions(node) if node is not None else []:
        name = "average" if "average" in q.children else next(iter(q.children), None)
        if name is None:
            continue
        res, unit = q[name].to_dataset(), str(q.attrs.get("unit", ""))
        lo, mid, hi = (float(res["crossing_q"].sel(quantile=p)) for p in (0.05, 0.5, 0.95))
        laws = [n for n in q.children if n != "average"]
        top = max(laws, key=lambda n: float(q[n].attrs.get("weight", 0.0)))
        basis = (f"model average, led by {top} ({q[top].attrs.get('form')} trend, weight "
                 f"{float(q[top].attrs.get('weight', 0.0)):.2f})" if name == "average" else f"{name} alone")
        lead = _statement(q)
        out.append(_f(f"Time to exceed '{q.attrs['label']}' ({q.attrs['capacity']} at {q.attrs['point']}): ",
                      *([(lead, True), " "] if lead else []),
                      (f"median {_time(mid, unit)}, 90 % interval {_time(lo, unit)} – {_time(hi, unit)}", True),
                      f" for the typical campaign, with the model-form allowance the leave-future-out folds "
                      f"measured{'' if _calibrated(q) else ' (not calibrated for that bend)'}; P(within "
                      f"{q.attrs['horizon']}) {float(res.attrs['p_within_horizon']):.2f} ({basis}).",
                      warning=not _calibrated(q)))
    return out


def text(result: xr.Dataset) -> str:
    """One fit's time-to-exceed answer as ``bayesfric size --horizon`` prints it.

    Examples
    --------
    >>> print(text(result))                                                   # doctest: +SKIP
    time to exceed 1.8 N*m at {'velocity': 146.6}: coastdown_oring_closed_form_trend_hours (linear trend) ...
    """
    unit = str(result.attrs.get("unit", ""))
    lo, mid, hi = (float(result["crossing_q"].sel(quantile=p)) for p in (0.05, 0.5, 0.95))
    marked = not int(result.attrs.get("shape_calibrated", 1))
    lines = [f"{'WARNING' if marked else 'note'}: {result.attrs['statement']}"] if result.attrs.get("statement") else []
    lines += [f"time to exceed {float(result.attrs['capacity']):g} (SI) at {result.attrs['at']} (SI): "
             f"{result.attrs['law']} ({result.attrs['form']} trend)",
             f"answer for: {result.attrs['curve']}",
             f"median {_time(mid, unit)}; 90 % interval {_time(lo, unit)} – {_time(hi, unit)}; "
             f"P(exceeded by {_time(float(result.attrs['horizon']), unit)}) "
             f"{float(result.attrs['p_within_horizon']):.2f}"]
    if result.attrs.get("allowance"):
        lines.append(f"model-form allowance: {result.attrs['allowance']}")
    if result.attrs.get("bend"):
        lines.append(f"campaign levels against the trend at the point: {result.attrs['bend']} "
                     f"({result.attrs.get('bend_test', '')})"
                     + ("; the interval is NOT calibrated for that shape" if marked else ""))
    if result.attrs.get("steady"):
        lines.append(f"note: {result.attrs['steady']}")
    service = result["service"].values
    marks = np.linspace(0, service.size - 1, 6).astype(int)
    lines.append("service time  P(exceeded)  median |friction| (typical)")
    lines += [f"{_time(float(service[k]), unit):>12}  {float(result['p_exceed'][k]):11.2f}  "
              f"{float(result['fan'].sel(quantile=0.5)[k]):.4g}" for k in marks]
    return "\n".join(lines)
