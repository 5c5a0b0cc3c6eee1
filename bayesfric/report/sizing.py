"""Renderings of a :class:`bayesfric.sizing.result.SizingAnswer`: ``sizing.csv`` records, the sizing
section of ``summary.md`` and ``report.html``, and the text ``bayesfric size`` prints.

Nothing here computes a sizing number: every value comes from the result; this module only
picks rows, converts SI to the units the question and data use, and formats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bayesfric.report.findings import Finding, plain
from bayesfric.report.tables import format_table
from bayesfric.report.typeset import fmt, unit
from bayesfric.sizing import EXTRAPOLATION_WARN, LEVELS, RANGE_POINTS, Answer
from bayesfric.sizing.result import SizingAnswer
from bayesfric.sizing.steady import steady_line
from bayesfric.sizing.tidy import ONE_FIT, first_warnings, p_text

__all__ = ["Section", "sections", "records", "text_report", "headlines", "RANGE_ROWS"]

#: Points of a range shown in the along-the-range table (sizing.csv has every point).
RANGE_ROWS = 6

_MEAN_FN = "mean function (parameter uncertainty only)"
_NOISY = "with observation noise (what the drive meets)"


@dataclass
class Section:
    """One question, ready to render: a heading, lines of text, warnings and tables."""

    title: str
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    tables: list[tuple[str, list[str], list[list[str]]]] = field(default_factory=list)  # caption, header, rows
    figure: str | None = None  # the fan figure: file name (Markdown) or base64 PNG (HTML), when one was drawn
    caption: str = ""  # the figure's caption, where it is not the sizing fan's


def _g(x: float, digits: int = 4) -> str:
    """A number with ``digits`` significant digits (:func:`bayesfric.report.typeset.fmt`: no
    ``5.505e-10``; powers of ten written out)."""
    return fmt(float(x), digits=digits) if isinstance(x, float | int | np.floating) and math.isfinite(x) else "–"


def _qty(text: str) -> str:
    """A value with its unit as the user wrote it (``"85 kN*m"``), the unit typeset (85 kN·m)."""
    number, _, rest = str(text).partition(" ")
    return f"{number} {unit(rest)}" if rest else unit(number)


def _w(x: float) -> str:
    """A weight: two decimals, ``0`` for none."""
    if not (isinstance(x, float | int) and math.isfinite(x)):
        return "–"
    return "0" if abs(x) < 0.005 else f"{x:.2f}"


def _pct(level: float) -> str:
    return f"{level * 100:g} %"


def _energy_unit(joules: float) -> tuple[str, float]:
    for name, scale in (("MJ", 1e6), ("kJ", 1e3)):
        if abs(joules) >= scale:
            return name, scale
    return "J", 1.0


def _point_text(answer: Answer, j: int) -> str:
    return ", ".join(f"{k} = {_g(float(v.display(answer.grid[k][j])))} {unit(v.unit)}"
                     for k, v in answer.question.at.items())


def _distance_text(answer: Answer, j: int) -> str:
    parts = []
    for k, v in answer.question.at.items():
        if k not in answer.distance:
            continue
        lo, hi = (float(x) for x in v.display(np.array(answer.tested[k])))
        d = float(answer.distance[k][j])
        where = "inside" if d == 0 else ("above" if answer.grid[k][j] > answer.tested[k][1] else "below")
        parts.append(f"{k} {_g(d, 3)} ({where} the tested {_g(min(lo, hi))}–{_g(max(lo, hi))} {unit(v.unit)})")
    return "; ".join(parts)


def _cal_cells(a, j: int, scale: float, capacity) -> list[str]:
    """Calibrated friction-curve 5/50/95 %, required capacity and P(exceed) of a law or average."""
    cal = a.calibrated
    if cal is None:
        return ["–"] * (4 + (capacity is not None))
    cells = [_g(float(cal.mean_fn.q(q)[j]) / scale) for q in LEVELS] + [_g(float(cal.required[j]) / scale)]
    if capacity is not None:
        cells.append(p_text(float(cal.p_exceed[j]), float(cal.p_se[j]), float(cal.p_bound[j])))
    return cells


def _law_table(result: SizingAnswer, answer: Answer, j: int) -> tuple[str, list[str], list[list[str]]]:
    scale, shown, c = result.response_scale, unit(result.response_unit), answer.question.confidence
    single = answer.basis is None
    capacity = answer.question.capacity
    within = not (answer.basis is not None and answer.basis.no_extrapolation)
    calibrated = answer.basis is not None and answer.basis.calibrated
    header = ["law"] + ([] if single else ["weight (basis)", "used", "weight (LOO)"])
    if within:
        header += [*(f"mean fn {_pct(q)}" for q in LEVELS), *(f"with noise {_pct(q)}" for q in LEVELS),
                   f"required @ {c:g}"] + ([f"P(|{result.response}| > {_qty(capacity.text)})"] if capacity else [])
    if calibrated:
        header += [*(f"calibrated curve {_pct(q)}" for q in LEVELS), f"calibrated required @ {c:g}"]
        header += [f"calibrated P(> {_qty(capacity.text)})"] if capacity else []

    def row(name, a, weights=(math.nan, math.nan, math.nan)):
        cells = [name] + ([] if single else [_w(w) for w in weights])
        if within:
            cells += [_g(float(a.mean_fn.q(q)[j]) / scale) for q in LEVELS]
            cells += [_g(float(a.noisy.q(q)[j]) / scale) for q in LEVELS]
            cells.append(_g(float(a.required[j]) / scale))
            if capacity is not None:
                cells.append(p_text(float(a.p_exceed[j]), float(a.p_se[j]), float(a.p_bound[j])))
        return cells + (_cal_cells(a, j, scale, capacity) if calibrated else [])

    mark = {a.name: " (steady state)" for a in answer.laws if a.steady}  # a stateful law's steady state
    rows = [row(a.name + mark.get(a.name, ""), a, (a.weight_raw, a.weight, a.weight_loo)) for a in answer.used]
    rows += [row(f"{a.name}{mark.get(a.name, '')} (EXCLUDED)", a, (a.weight_raw, math.nan, a.weight_loo))
             for a in answer.laws if a.excluded is not None]
    for mix, name in ((answer.average, "MODEL AVERAGE"), (answer.average_loo, "average by LOO weights")):
        if mix is not None and not single:
            rows.append(row(name, mix, (math.nan, 1.0 if name == "MODEL AVERAGE" else math.nan, math.nan)))
    caption = (f"|{result.response}| [{shown}] at {_point_text(answer, j)}: quantiles of the {_MEAN_FN} and "
               f"{_NOISY}; required capacity = the {c:g} quantile with noise")
    if calibrated:
        caption += ("; calibrated = with the model-form error the blocked folds measured (the friction curve's "
                    "band, and the required capacity and P(exceed) with noise and that error)")
    return caption, header, rows


def _split_table(result: SizingAnswer, answer: Answer, j: int) -> tuple[str, list[str], list[list[str]]] | None:
    mix = answer.average
    if mix is None or answer.basis is None:  # one fit: no average to split
        return None
    scale, shown = result.response_scale, unit(result.response_unit)
    total = float(mix.var_total[j])
    rows = []
    for name, var in (("parameter (within-law)", mix.var_param), ("observation noise", mix.var_noise),
                      ("between-law disagreement", mix.var_between)):
        v = float(var[j])
        rows.append([name, _g(v / scale**2), _g(math.sqrt(v) / scale if v >= 0 else math.nan),
                     f"{v / total:.1%}" if total > 0 and math.isfinite(total) else "–"])
    rows.append(["total", _g(total / scale**2), _g(math.sqrt(total) / scale if total >= 0 else math.nan), "100 %"])
    caption = (f"variance split of the model average at {_point_text(answer, j)} (law of total variance, weights "
               f"as used)")
    return caption, ["component", f"variance [({shown})²]", f"sd [{shown}]", "share"], rows


def _energy_table(result: SizingAnswer, answer: Answer, j: int) -> tuple[str, list[str], list[list[str]]] | None:
    rotation = answer.question.energy_rotation
    if rotation is None:
        return None
    c = answer.question.confidence
    spreads = [(a.name, a.mean_fn, a.noisy) for a in answer.used]
    if answer.average is not None and answer.basis is not None:
        spreads.append(("MODEL AVERAGE", answer.average.mean_fn, answer.average.noisy))
    spreads += [(f"{a.name} (EXCLUDED)", a.mean_fn, a.noisy) for a in answer.laws if a.excluded is not None]
    top = max((float(answer.energy(n, c)[j]) for _, _, n in spreads), default=1.0)
    e_unit, scale = _energy_unit(top)
    header = ["law", *(f"mean fn {_pct(q)}" for q in LEVELS), *(f"with noise {_pct(q)}" for q in LEVELS),
              f"required @ {c:g}"]
    rows = [[name, *(_g(float(answer.energy(m, q)[j]) / scale) for q in LEVELS),
             *(_g(float(answer.energy(n, q)[j]) / scale) for q in LEVELS), _g(float(answer.energy(n, c)[j]) / scale)]
            for name, m, n in spreads]
    caption = (f"friction energy of one {_qty(rotation.text)} rotation [{e_unit}] at {_point_text(answer, j)}: "
               f"E = |{result.response}| · θ per draw (torque assumed independent of the angle; with noise, the "
               "scatter is taken to last the whole rotation)")
    return caption, header, rows


def _range_table(result: SizingAnswer, answer: Answer) -> tuple[str, list[str], list[list[str]]] | None:
    axis = answer.question.axis
    mix = answer.average
    if axis is None or mix is None:
        return None
    value = answer.question.at[axis]
    scale, c = result.response_scale, answer.question.confidence
    picks = sorted(set(np.linspace(0, answer.n_points - 1, RANGE_ROWS).round().astype(int)) | {answer.governing})
    cal = mix.calibrated
    header = [f"{axis} [{unit(value.unit)}]", "extrapolation distance", "median with noise", f"required @ {c:g}"]
    capacity = answer.question.capacity
    if capacity is not None:
        header.append(f"P(|{result.response}| > {_qty(capacity.text)})")
    if cal is not None:
        header += ["calibrated curve 5–95 %", f"calibrated required @ {c:g}"]
        header += [f"calibrated P(> {_qty(capacity.text)})"] if capacity is not None else []
    rows = []
    for j in picks:
        med, req = float(mix.noisy.q(0.5)[j]), float(mix.required[j])
        cells = [_g(float(value.display(answer.grid[axis][j]))), _g(float(answer.distance[axis][j]), 3),
                 _g(med / scale), _g(req / scale)]
        if capacity is not None:
            cells.append(p_text(float(mix.p_exceed[j]), float(mix.p_se[j]), float(mix.p_bound[j])))
        if cal is not None:
            cells += [f"{_g(float(cal.mean_fn.q(0.05)[j]) / scale)}–{_g(float(cal.mean_fn.q(0.95)[j]) / scale)}",
                      _g(float(cal.required[j]) / scale)]
            if capacity is not None:
                cells.append(p_text(float(cal.p_exceed[j]), float(cal.p_se[j]), float(cal.p_bound[j])))
        rows.append(cells)
    caption = (f"model average along {axis} {_qty(value.text)} [{unit(result.response_unit)}] ({RANGE_POINTS} "
               "points sized; every point in sizing.csv)")
    return caption, header, rows


def sections(result: SizingAnswer, figures: dict[int, str] | None = None) -> list[Section]:
    """One :class:`Section` per question (``figures``: question index -> fan figure file name)."""
    out = []
    for i, answer in enumerate(result.answers):
        q = answer.question
        j = answer.governing
        sec = Section(f"Sizing {i + 1}: {q.label}", figure=(figures or {}).get(i))
        extra = f"; available capacity {_qty(q.capacity.text)}" if q.capacity is not None else ""
        sec.lines.append(f"Asked: {q.describe()}; confidence {q.confidence:g}{extra}.")
        if q.axis and answer.used:
            sec.lines.append(f"The range of {q.axis} is sized at {answer.n_points} points; the tables give the "
                             f"governing point {_point_text(answer, j)} (largest required capacity).")
        sec.lines.append(f"Extrapolation distance (tested ranges beyond the data; warning above "
                         f"{EXTRAPOLATION_WARN:g}): {_distance_text(answer, j)}.")
        if q.axis and answer.n_points > 1:
            worst = {k: float(np.max(d)) for k, d in answer.distance.items()}
            sec.lines.append("Largest over the range: " + "; ".join(f"{k} {_g(d, 3)}" for k, d in worst.items()) + ".")
        sec.warnings += first_warnings(answer)
        if steady := steady_line(answer.laws):
            sec.lines.append(steady)
        if answer.basis is None:
            sec.lines.append(ONE_FIT)
        elif answer.average is not None:
            sec.lines.append(f"Model average ({answer.basis.note}), renormalised over the laws sizing uses ('used'); "
                             "LOO stacking weights shown beside and as a second average.")
        else:
            sec.warnings.append(f"no model average: {answer.no_average}")
        excluded = [f"{a.name} ({a.excluded})" for a in answer.laws if a.excluded is not None]
        if excluded:
            sec.lines.append("Excluded from sizing, never averaged (rows marked EXCLUDED, for reference only): "
                             + "; ".join(excluded) + ".")
        notes = [f"{a.name}: {a.weight_note}" for a in answer.used if a.weight_note]
        if notes:
            sec.lines.append("Left out of the weighting (weight 0): " + "; ".join(notes) + ".")
        sec.warnings += answer.warnings
        sec.tables.append(_law_table(result, answer, j))
        for table in (_split_table(result, answer, j), _energy_table(result, answer, j), _range_table(result, answer)):
            if table is not None:
                sec.tables.append(table)
        out.append(sec)
    return out


def headlines(result: SizingAnswer) -> list[Finding]:
    """One finding per question: the calibrated required capacity at its governing point
    (emphasised), the within-model one beside it, and what to distrust first."""
    lines = []
    for answer in result.answers:
        q, j = answer.question, answer.governing
        shown, scale = unit(result.response_unit), result.response_scale
        first = first_warnings(answer)
        if answer.average is None:
            lines.append(plain(f"Sizing '{q.label}': no model average ({answer.no_average}).", warning=True))
            continue
        mix = answer.average.calibrated or answer.average
        what = "calibrated for model-form error" if answer.average.calibrated is not None else "within-model"
        if answer.bend_upward:
            what += ", NOT for the upward bend the data show"
        steady = " at steady state (constant speed)" if steady_line(answer.used, answer.average.weights) else ""
        tail = f"{steady} at confidence {q.confidence:g} ({what}, model average, {_point_text(answer, j)}"
        if answer.average.calibrated is not None and not (answer.basis and answer.basis.no_extrapolation):
            tail += f"; within-model {_g(float(answer.average.required[j]) / scale)} {shown}"
        if q.capacity is not None:
            p = p_text(float(mix.p_exceed[j]), float(mix.p_se[j]), float(mix.p_bound[j]))
            tail += f"; P(> {_qty(q.capacity.text)}) {p}"
        tail += ")"
        if q.energy_rotation is not None:
            energy = float(answer.energy(mix.noisy, q.confidence)[j])
            e_unit, e_scale = _energy_unit(energy)
            tail += f"; friction energy of one {_qty(q.energy_rotation.text)} rotation {_g(energy / e_scale)} {e_unit}"
        if first:
            tail += " — " + "; ".join(first)
        if answer.warnings:
            tail += f" — {len(answer.warnings)} warning(s), see Sizing"
        lines.append(Finding(((f"Sizing '{q.label}': required |{result.response}| ", False),
                              (f"{_g(float(mix.required[j]) / scale)} {shown}", True), (tail + ".", False)),
                             warning=bool(first)))
    return lines


def text_report(result: SizingAnswer) -> str:
    """What ``bayesfric size`` prints."""
    lines = [f"sizing from {result.source}", result.provenance,
             "magnitudes |T|: friction opposes motion, so the drive must overcome |T| in either direction", ""]
    for sec in sections(result):
        lines += [sec.title, "=" * min(len(sec.title), 100)]
        lines += sec.lines + [f"WARNING: {w}" for w in sec.warnings] + [""]
        for caption, header, rows in sec.tables:
            lines += [caption, format_table(header, rows), ""]
    return "\n".join(lines)


def _record(ds, base: dict, r: int, c: int, levels, single: bool, rotation: float) -> dict:
    """One row of ``sizing.csv``: row ``r`` (a law or an average) at point ``c`` of the Dataset."""
    quantiles = [float(x) for x in ds["quantile"].values]

    def at(name: str, level: float | None = None) -> float:
        v = ds[name].values
        return float(v[r, c] if level is None else v[r, c, quantiles.index(level)])

    rec = dict(base, role=str(ds["role"].values[r]), law=str(ds["name"].values[r, c]),
               included=bool(ds["included"].values[r, c]), excluded_reason=str(ds["excluded_reason"].values[r]),
               steady_state=str(ds["steady_state"].values[r, c]))
    if not single:
        rec.update(weight_basis=at("weight_basis"), weight_used=at("weight_used"), weight_stacking_loo=at("weight_loo"))
    rec.update({f"mean_fn_q{level * 100:g}": at("mean_fn", level) for level in levels})
    rec.update({f"noisy_q{level * 100:g}": at("noisy", level) for level in levels})
    for name in ("required", "p_exceed", "p_exceed_se", "p_exceed_bound", "var_param", "var_noise", "var_between"):
        rec[name] = at(name)
    rec.update({f"calibrated_q{level * 100:g}": at("calibrated_mean_fn", level) for level in LEVELS})
    for name in ("calibrated_required", "calibrated_p_exceed", "calibrated_p_exceed_se", "model_form_rel_sd"):
        rec[name] = at(name)
    if math.isfinite(rotation):
        rec["energy_rotation_rad"] = rotation
        rec.update({f"energy_mean_fn_q{level * 100:g}_J": at("mean_fn", level) * rotation for level in levels})
        rec.update({f"energy_noisy_q{level * 100:g}_J": at("noisy", level) * rotation for level in levels})
    rec["warnings"] = str(ds["warnings"].values[c])
    return rec


def records(result: SizingAnswer) -> list[dict]:
    """``sizing.csv``: one row per question, point and law (plus the averages), SI units: a
    rendering of ``result.dataset`` (:mod:`bayesfric.sizing.tidy`), the question's units aside.

    ``calibrated_q5/q50/q95`` are the friction curve's quantiles with the measured model-form
    error, ``calibrated_required`` and ``calibrated_p_exceed`` the required capacity and
    exceedance probability with noise and that error (NaN where nothing was measured: one fit,
    no blocked fold). ``steady_state``: what a stateful law's answer is (:data:`bayesfric.sizing.STEADY_NOTE`;
    "" for a steady law). One fit (``bayesfric size FIT.nc``) has no weight columns and no averages.
    """
    ds, out = result.dataset, []
    for i, answer in enumerate(result.answers):
        q = answer.question
        for j, c in enumerate(np.flatnonzero(ds["question"].values == i + 1)):
            base: dict = {"question": i + 1, "label": q.label, "point": j + 1, "confidence": q.confidence}
            for k, v in q.at.items():
                base[k] = float(ds[k].values[c])
                base[f"{k} [{v.unit}]"] = float(v.display(ds[k].values[c]))
                base[f"distance[{k}]"] = float(ds[f"distance_{k}"].values[c])
            base["unit"] = ds.attrs["unit"]
            base["capacity"] = float(ds["capacity"].values[c])
            base["governing"] = bool(ds["governing"].values[c])
            base["basis"] = str(ds["basis"].values[c])
            out += [_record(ds, base, r, c, answer.energy_levels, bool(ds["single_fit"].values[c]),
                            float(ds["energy_rotation"].values[c]))
                    for r in range(ds.sizes["law"]) if ds["name"].values[r, c] != ""]
    return out
