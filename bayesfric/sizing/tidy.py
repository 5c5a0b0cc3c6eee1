"""Every sizing answer as one tidy :class:`xarray.Dataset`: one row per law and average, one
column per point of every question, the quantiles along ``quantile``, and the draws they came
from kept along ``sample`` (so a quantile at any level is computed exactly as the kept ones were).

Built once from the computed answers (:func:`bayesfric.sizing.answer.answer`); the
:class:`~bayesfric.sizing.result.SizingAnswer` wraps it, and ``sizing.csv`` and the report
render it. Layout (SI units throughout):

``law`` (row)
    every law, then ``average`` (the model average by the question's basis weights) and
    ``average_loo`` (by LOO stacking weights); ``role`` says which. A row a question has no
    answer for (no average, a single fit) has ``name == ""`` and NaN numbers at its points.
    ``p_exceed_text`` (and ``calibrated_``) says P(exceed) as the report does (:func:`p_text`).
``point``
    every point of every question, numbered across questions; ``question`` (1-based),
    ``question_point`` (1-based within it), ``label``, ``confidence``, ``capacity``,
    ``energy_rotation`` (NaN: not asked), ``governing``, ``basis`` and ``basis_note`` (which
    weights, and why; a single fit's :data:`ONE_FIT`), ``single_fit``, ``no_average`` (why there
    is none; ``""``), ``warnings`` (what to distrust first, then every warning of the answer),
    each asked input's value and ``distance_<input>`` (tested ranges beyond the data; NaN
    where the question does not ask it).
``quantile``
    the levels every question asked (5 / 50 / 95 % and each confidence): ``mean_fn`` and
    ``noisy`` (and their ``calibrated_`` forms); NaN at a level a question did not ask.
``component`` and ``sample``
    each law's draws of ``|T|`` at every point, ``draws_mean_fn`` and ``draws_noisy`` (and
    ``calibrated_``), NaN beyond the law's ``n_draws``; ``mix_weight`` (and
    ``calibrated_mix_weight``) gives each row's weight on each law's draws.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import xarray as xr

from bayesfric.quantities import QUANTITIES
from bayesfric.sizing.compute import Answer, SizingResult
from bayesfric.sizing.steady import steady_line

__all__ = ["AVERAGE", "AVERAGE_LOO", "ONE_FIT", "ROLES", "QUANTILE_VARS", "DRAW_VARS", "p_text", "first_warnings",
           "build_dataset"]

AVERAGE, AVERAGE_LOO = "average", "average_loo"
#: What a single fit's answer is not (no average, no weights, no calibration).
ONE_FIT = ("One fit: no model average, no weights; no blocked fold measured this law's model-form error, so no "
           "calibrated numbers: its intervals carry parameter and noise uncertainty only.")
#: Row kind of each average row (laws are "law").
ROLES = {AVERAGE: "average", AVERAGE_LOO: "average LOO"}
#: Variables along ``quantile``.
QUANTILE_VARS = ("mean_fn", "noisy", "calibrated_mean_fn", "calibrated_noisy")
#: Variables holding the draws (and their weights): left out of the data frame.
DRAW_VARS = ("draws_mean_fn", "draws_noisy", "calibrated_draws_mean_fn", "calibrated_draws_noisy", "mix_weight",
             "calibrated_mix_weight", "n_draws")
_ROW_FLOATS = ("weight_basis", "weight_used", "weight_loo", "required", "p_exceed", "p_exceed_se", "p_exceed_bound",
               "ess", "var_param", "var_noise", "var_between", "calibrated_required", "calibrated_p_exceed",
               "calibrated_p_exceed_se", "calibrated_p_exceed_bound", "model_form_rel_sd")


def p_text(p: float, se: float, bound: float) -> str:
    """``P(|T| > capacity)`` as a reader is told it: ``"0.0123 ± 0.0031"``; where no draw (or every
    draw) exceeds, the one-sided 95 % bound ``"< 0.00075 (no draw exceeds)"``; ``"–"`` without a
    capacity.

    Examples
    --------
    >>> p_text(0.0, 0.0, 3 / 4000), p_text(0.25, 0.01, float("nan"))
    ('< 0.00075 (no draw exceeds)', '0.25 ± 0.01')
    """
    if not math.isfinite(p):
        return "–"
    if math.isfinite(bound):
        return f"< {bound:.2g} (no draw exceeds)" if p == 0 else f"> {1 - bound:.4g} (every draw exceeds)"
    return f"{p:.3g} ± {se:.2g}"


def first_warnings(answer: Answer) -> list[str]:
    """What the data cannot support, said before any number: the answer for a new run (which laws
    it comes from where the data show the runs differ, :mod:`bayesfric.sizing.newrun`); data that
    bend upward against every weighted law (:mod:`bayesfric.sizing.shape`); no law
    extrapolates here; a direction no blocked fold tests; a model-form error nothing measured."""
    basis = answer.basis
    out = []
    if basis is not None and basis.new_run:
        out.append(basis.new_run)
    if getattr(answer, "bend", ""):
        out.append(answer.bend)
    if basis is not None and basis.no_extrapolation:
        out.append(f"NO LAW EXTRAPOLATES HERE: {basis.no_extrapolation}; only calibrated numbers are quoted")
    if basis is not None and basis.uncovered:
        out.append(basis.note.split("; ")[0])
    if basis is not None and not basis.calibrated and any(float(np.max(d)) > 0 for d in answer.distance.values()):
        out.append("no blocked fold measured any law's miss beyond the envelope: the model-form error of this "
                   "extrapolated answer is UNMEASURED and its intervals are not calibrated")
    return out


class _Arrays:
    """The arrays of the Dataset while they are filled (rows × points, and so on)."""

    def __init__(self, laws: list[str], n: int, levels: list[float], samples: int):
        rows = len(laws) + 2
        self.laws, self.levels = laws, levels
        self.rows = laws + [AVERAGE, AVERAGE_LOO]
        self.f = {k: np.full((rows, n), np.nan) for k in _ROW_FLOATS}
        self.q = {k: np.full((rows, n, len(levels)), np.nan) for k in QUANTILE_VARS}
        self.name = np.full((rows, n), "", dtype=object)
        self.steady = np.full((rows, n), "", dtype=object)
        self.included = np.zeros((rows, n), dtype=bool)
        self.mix = {k: np.zeros((rows, len(laws), n)) for k in ("mix_weight", "calibrated_mix_weight")}
        self.draws = {k: np.full((len(laws), samples, n), np.nan) for k in DRAW_VARS[:4]}
        self.n_draws = np.zeros(len(laws), dtype=int)

    def spread(self, prefix: str, r: int, cols: slice, a) -> None:
        """Quantiles, required capacity and P(exceed) of a law's or a mixture's answer."""
        for kind in ("mean_fn", "noisy"):
            for level, values in getattr(a, kind).quantiles.items():
                self.q[prefix + kind][r, cols, self.levels.index(level)] = values
        self.f[prefix + "required"][r, cols] = a.required
        self.f[prefix + "p_exceed"][r, cols] = a.p_exceed
        self.f[prefix + "p_exceed_se"][r, cols], self.f[prefix + "p_exceed_bound"][r, cols] = a.p_se, a.p_bound
        if not prefix:
            self.f["var_param"][r, cols], self.f["var_noise"][r, cols] = a.var_param, a.var_noise

    def texts(self) -> dict[str, np.ndarray]:
        """``p_exceed_text`` and ``calibrated_p_exceed_text``: P(exceed) as a reader is told it."""
        out = {}
        for prefix in ("", "calibrated_"):
            p, se, bound = (self.f[prefix + k] for k in ("p_exceed", "p_exceed_se", "p_exceed_bound"))
            out[prefix + "p_exceed_text"] = np.vectorize(p_text, otypes=[object])(p, se, bound) if p.size else \
                np.full(p.shape, "", dtype=object)
        return out

    def draws_of(self, prefix: str, k: int, cols: slice, d) -> None:
        mu, y = np.abs(d.mu).reshape(-1, d.mu.shape[-1]), np.abs(d.y).reshape(-1, d.y.shape[-1])
        self.draws[prefix + "draws_mean_fn"][k, :len(mu), cols] = mu
        self.draws[prefix + "draws_noisy"][k, :len(y), cols] = y
        self.n_draws[k] = len(mu)


def _fill_law(arr: _Arrays, answer: Answer, cols: slice, a) -> None:
    r = arr.rows.index(a.name)
    arr.name[r, cols], arr.steady[r, cols], arr.included[r, cols] = a.name, a.steady, a.excluded is None
    arr.f["weight_basis"][r, cols], arr.f["weight_used"][r, cols] = a.weight_raw, a.weight
    arr.f["weight_loo"][r, cols], arr.f["ess"][r, cols] = a.weight_loo, a.ess
    arr.spread("", r, cols, a)
    arr.mix["mix_weight"][r, r, cols] = 1.0
    if a.name in answer.draws:
        arr.draws_of("", r, cols, answer.draws[a.name])
    if a.calibrated is not None:
        arr.spread("calibrated_", r, cols, a.calibrated)
        arr.mix["calibrated_mix_weight"][r, r, cols] = 1.0
        if a.rel_sd is not None:
            arr.f["model_form_rel_sd"][r, cols] = a.rel_sd
    if a.name in answer.calibrated_draws:
        arr.draws_of("calibrated_", r, cols, answer.calibrated_draws[a.name])


def _fill_average(arr: _Arrays, answer: Answer, cols: slice, mix, row: str) -> None:
    r = arr.rows.index(row)
    arr.name[r, cols], arr.included[r, cols] = mix.basis, True
    arr.steady[r, cols] = steady_line(answer.laws, mix.weights, False)
    arr.spread("", r, cols, mix)
    arr.f["var_between"][r, cols] = mix.var_between
    for law, w in mix.weights.items():
        arr.mix["mix_weight"][r, arr.laws.index(law), cols] = w
    if mix.calibrated is not None:
        arr.spread("calibrated_", r, cols, mix.calibrated)
        for law, w in mix.calibrated.weights.items():
            arr.mix["calibrated_mix_weight"][r, arr.laws.index(law), cols] = w


def _point_coords(answers: Sequence[Answer]) -> dict[str, tuple]:
    """The coordinates along ``point``: which question, where, and what was asked there."""
    inputs = list(dict.fromkeys(k for a in answers for k in a.question.at))
    text = ("label", "basis", "basis_note", "no_average", "warnings")
    per: dict[str, list] = {k: [] for k in ("question", "question_point", "label", "confidence", "capacity",
                                            "energy_rotation", "governing", "basis", "basis_note", "single_fit",
                                            "no_average", "warnings")}
    values: dict[str, list] = {k: [] for k in inputs}
    distance: dict[str, list] = {k: [] for k in inputs}
    for i, a in enumerate(answers):
        q, n = a.question, a.n_points
        per["question"] += [i + 1] * n
        per["question_point"] += list(range(1, n + 1))
        per["label"] += [q.label] * n
        per["confidence"] += [q.confidence] * n
        per["capacity"] += [q.capacity.lo if q.capacity is not None else math.nan] * n
        per["energy_rotation"] += [q.energy_rotation.lo if q.energy_rotation is not None else math.nan] * n
        per["governing"] += [j == a.governing for j in range(n)]
        per["basis"] += [a.basis.key if a.basis is not None else "single fit"] * n
        per["basis_note"] += [a.basis.note if a.basis is not None else ONE_FIT] * n
        per["single_fit"] += [a.basis is None] * n
        per["no_average"] += [a.no_average] * n
        per["warnings"] += ["; ".join(first_warnings(a) + a.warnings)] * n
        for k in inputs:
            values[k] += list(np.asarray(a.grid[k], dtype=float)) if k in a.grid else [math.nan] * n
            distance[k] += list(np.asarray(a.distance[k], dtype=float)) if k in a.distance else [math.nan] * n
    coords = {k: ("point", np.asarray(v, dtype=object if k in text else None))
              for k, v in per.items()}
    coords |= {k: ("point", np.asarray(v, dtype=float)) for k, v in values.items()}
    coords |= {f"distance_{k}": ("point", np.asarray(v, dtype=float)) for k, v in distance.items()}
    return coords


def _attrs(result: SizingResult) -> dict[str, str | float]:
    answers = result.answers
    laws = [a for ans in answers for a in ans.laws]
    new = dict.fromkeys(w for ans in answers for w in ans.warnings if "answers for a NEW" in w)
    return {
        "response": result.response, "unit": QUANTITIES[result.response].unit,
        "response_unit": result.response_unit, "response_scale": result.response_scale,
        "provenance": result.provenance, "source": result.source,
        "magnitudes": "magnitudes |T|: friction opposes motion, so the drive must overcome |T| in either direction",
        "answers_for": "; ".join(new) if new else "the tested process: the fit(s) have no group terms",
        "steady_state": steady_line(laws, None, False),
        "approximate": "Monte Carlo from the kept posterior draws: quantiles are those of the draws (a model "
                       "average's invert the weighted empirical CDF of every law's draws), P(|T| > capacity) "
                       "carries its Monte Carlo error p_exceed_se (p_exceed_bound where no draw, or every "
                       "draw, exceeds)",
        "within_model": "mean_fn: the law's mean function, parameter uncertainty only; noisy: with the fit's "
                        "observation noise; required: the confidence quantile of noisy",
        "calibrated": "calibrated_*: with the model-form error the blocked folds measured added (NaN where none "
                      "was measured: one fit, no blocked fold)",
    }


def build_dataset(result: SizingResult) -> xr.Dataset:
    """The tidy Dataset of ``result`` (see the module), with its draws kept."""
    answers = result.answers
    laws = list(dict.fromkeys(a.name for ans in answers for a in ans.laws))
    sizes = [ans.n_points for ans in answers]
    starts = np.cumsum([0, *sizes])
    levels = sorted(set().union(*(ans.energy_levels for ans in answers))) if answers else []
    samples = max((d.n_draws for ans in answers for d in ans.draws.values()), default=0)
    arr = _Arrays(laws, int(starts[-1]), levels, samples)
    for i, ans in enumerate(answers):
        cols = slice(int(starts[i]), int(starts[i + 1]))
        for a in ans.laws:
            _fill_law(arr, ans, cols, a)
        for mix, row in ((ans.average, AVERAGE), (ans.average_loo, AVERAGE_LOO)):
            if mix is not None and ans.basis is not None:
                _fill_average(arr, ans, cols, mix, row)
    rl, lp, cs = ("law", "point"), ("law", "component", "point"), ("component", "sample", "point")
    data = {k: (rl, v) for k, v in arr.f.items()}
    data |= {k: (("law", "point", "quantile"), v) for k, v in arr.q.items()}
    data |= {"name": (rl, arr.name), "steady_state": (rl, arr.steady), "included": (rl, arr.included)}
    data |= {k: (rl, v) for k, v in arr.texts().items()}
    data |= {k: (lp, v) for k, v in arr.mix.items()} | {k: (cs, v) for k, v in arr.draws.items()}
    data["n_draws"] = ("component", arr.n_draws)
    excluded = {a.name: a.excluded or "" for ans in answers for a in ans.laws}
    notes = {a.name: a.weight_note for ans in answers for a in ans.laws}
    coords = {"law": arr.rows, "role": ("law", ["law"] * len(laws) + [ROLES[AVERAGE], ROLES[AVERAGE_LOO]]),
              "excluded_reason": ("law", np.asarray([excluded[k] for k in laws] + ["", ""], dtype=object)),
              "weight_note": ("law", np.asarray([notes[k] for k in laws] + ["", ""], dtype=object)),
              "point": np.arange(int(starts[-1])), "quantile": np.asarray(levels, dtype=float),
              "component": laws, "sample": np.arange(samples)} | _point_coords(answers)
    return xr.Dataset(data, coords=coords, attrs=_attrs(result))
