"""Answering sizing questions: per law and point the within-model answer, the basis (weights and
measured misses chosen from the question's direction, :mod:`bayesfric.sizing.basis`), the model
average, every answer again with the measured model-form error (:mod:`bayesfric.sizing.calibration`),
and the fan figure's bands. The numbers themselves come from :mod:`bayesfric.sizing.compute`.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping, Sequence

import numpy as np

from bayesfric.inference.diagnostics import verdict_of
from bayesfric.sizing.basis import LOO, Basis, choose_basis
from bayesfric.sizing.calibration import OFFSET, Scheme, discrepancy, widen
from bayesfric.sizing.compute import (
    EXTRAPOLATION_WARN,
    FAN_POINTS,
    LEVELS,
    Answer,
    Draws,
    Fan,
    LawAnswer,
    LawSource,
    Mixture,
    SizingResult,
    law_answer,
    mixture,
    predict,
)
from bayesfric.sizing.compute import levels as quantile_levels
from bayesfric.sizing.distance import point_distance
from bayesfric.sizing.misfit import LocalMisfit, local_misfit
from bayesfric.sizing.newrun import NewRun, law_groups, rule
from bayesfric.sizing.points import SizingQuestion
from bayesfric.sizing.result import SizingAnswer, as_answer
from bayesfric.sizing.shape import Bend, bend

__all__ = ["SIGNIFICANT", "SHARE", "answer_question", "answer", "undetected"]

#: A measured miss within this many standard errors of zero is taken as not shown by the fold.
SIGNIFICANT = 2.0
#: Laws with at least this weight in the average are checked for an undetected form error.
SHARE = 0.2


def _fan_axis(question: SizingQuestion, distance: Mapping[str, np.ndarray],
              tested: Mapping[str, tuple[float, float]]) -> str | None:
    if question.axis:
        return question.axis
    spans = [k for k in question.at if k in tested and tested[k][1] > tested[k][0]]
    if not spans:
        return None
    return max(spans, key=lambda k: float(np.max(distance[k])))


def answered_for(name: str, attrs: Mapping) -> str:
    """Which run or unit a law's answer is for: a new one where the fit has group terms (``vary_by``,
    ``[noise] group``); ``""`` without groups."""
    import json

    recipe = json.loads(attrs.get("law_recipe") or "{}")
    columns = {c: ", ".join(p) for c, p in recipe.get("vary_by", {}).items()}
    noise = json.loads(attrs.get("noise") or "{}").get("group")
    if noise:
        columns.setdefault(noise, "")
        columns[noise] = ", ".join(filter(None, (columns[noise], "a multiplicative offset")))
    return "; ".join(f"{name}: answers for a NEW {c} (its {what} drawn from the spread between the fitted "
                     f"levels of {c!r}), not for a tested one" for c, what in columns.items())


def _warnings(distance: Mapping[str, np.ndarray], sources: Sequence[LawSource], used: Sequence[LawAnswer]) -> list[str]:
    warnings = []
    for k, d in distance.items():
        worst = float(np.max(d))
        if worst > EXTRAPOLATION_WARN:
            warnings.append(f"{k}: up to {worst:.2g} tested ranges beyond the data (more than "
                            f"{EXTRAPOLATION_WARN:g}): the answer rests on extrapolation")
    if len(sources) == 1 and "diagnostics" in sources[0].fit.attrs and not verdict_of(sources[0].fit).passed:
        problems = "; ".join(verdict_of(sources[0].fit).problems)
        warnings.append(f"the fit of {sources[0].name} FAILED the diagnostics gate ({problems}): "
                        "its answer is not reliable")
    warnings += [note for source in sources if (note := answered_for(source.name, source.fit.attrs))]
    used_names = {a.name for a in used}
    for source in sources:
        if source.name in used_names and "diagnostics" in source.fit.attrs:
            if names := verdict_of(source.fit).unidentified:
                warnings.append(f"{source.name}: {', '.join(names)} not identified by the data (its chains did "
                                "not mix along them; its predictions on the tested rows converged): beyond the "
                                "tested envelope its answer rests on them")
    for a in used:
        if a.infinite_noise > 0:
            warnings.append(f"{a.name}: {a.infinite_noise:.1%} of draws have Student-t nu ≤ 2 (infinite noise "
                            "variance), left out of its noise variance term")
    return warnings


def _calibrate(answers: Sequence[LawAnswer], draws: Mapping[str, Draws], sources: Sequence[LawSource],
               basis: Basis, schemes: Sequence[Scheme], grid, data, question: SizingQuestion, qs,
               seed: int, misfits: Mapping[str, LocalMisfit | None]) -> dict[str, Draws]:
    """Each law's answer with its measured model-form error added (``LawAnswer.calibrated``)."""
    out = {}
    for a, src in zip(answers, sources, strict=True):
        out[src.name], a.rel_sd = _widened(src, draws[src.name], basis, schemes, grid, data, seed,
                                           misfits.get(src.name))
        a.calibrated = law_answer(src, out[src.name], question, qs)
    return out


def _widened(src: LawSource, d: Draws, basis: Basis, schemes: Sequence[Scheme], grid, data,
             seed: int, misfit: LocalMisfit | None = None) -> tuple[Draws, np.ndarray]:
    """A law's draws with its measured model-form error added, and the discrepancy's relative sd
    (the blocked folds' miss, floored by the law's misfit at the data nearest each point; that
    misfit, signed, is also the discrepancy's mean: :mod:`bayesfric.sizing.misfit`)."""
    rel, shift = discrepancy(grid, data, src.misses, schemes, basis.schemes, basis.fallback_rate, basis.uncovered)
    if misfit is not None:  # the larger of the two biases (the folds' includes the edge's), the larger sd
        bias = misfit.shift(grid)
        shift = np.where(np.abs(bias) > np.abs(shift), bias, shift)
        rel = np.maximum(rel, np.abs(bias))
    rng = np.random.default_rng([seed, zlib.crc32(("calibrated " + src.name).encode())])
    mu, y, _ = widen(d.mu, d.y, rel, rng, shift)
    return Draws(mu, y, d.noise_var, d.steady), rel


def undetected(sources: Sequence[LawSource], weights: Mapping[str, float], basis: Basis,
               grid: Mapping[str, np.ndarray], data: Mapping[str, np.ndarray]) -> str:
    """Where the data cannot tell a weighted law from the truth: each law with at least
    :data:`SHARE` of the average whose miss on every matched fold is within :data:`SIGNIFICANT`
    standard errors of zero, with the form error that would not have shown (that many standard
    errors of its miss, grown to the farthest point as the band is). ``""`` when none.

    Why: a fold of a few held-out points cannot show a mild form error (the Stribeck + gear
    power-law truth of ``tests/test_sizing_calibration.py`` looks to its fold much like a law
    that is right), and the calibrated band adds only what was measured; the answer says so.
    """
    parts = []
    for src in sources:
        if weights.get(src.name, 0.0) < SHARE or not basis.schemes:
            continue
        limit = 0.0
        for s in basis.schemes:
            miss = src.misses.get(s.label)
            if miss is None or abs(miss.beta) >= SIGNIFICANT * miss.se:
                limit = math.nan
                break
            lo, hi = s.tested(data[s.axis])
            u = (hi - lo) * (np.max(s.distance(grid[s.axis], lo, hi)) + OFFSET)
            limit = max(limit, float(miss.relative(u, rate=SIGNIFICANT * miss.se, width=hi - lo)))
        if math.isfinite(limit):
            parts.append(f"{src.name} (weight {weights[src.name]:.2f}): a form error of up to {limit:.0%} of its "
                         "friction at the farthest point would not have shown")
    if not parts:
        return ""
    return ("the blocked fold(s) CANNOT TELL these laws from the true law beyond the data: their measured miss is "
            f"within {SIGNIFICANT:g} standard errors of zero, and the calibrated band adds only the miss measured; "
            + "; ".join(parts))


def new_run_rule(sources: Sequence[LawSource]) -> NewRun:
    """The new-run rule (:mod:`bayesfric.sizing.newrun`) over the laws' fits and checks."""
    return rule([law_groups(s.name, s.fit, s.excluded is None, s.checks) for s in sources])


def _predicted(sources: Sequence[LawSource], grid, seed: int, new_run: NewRun) -> dict[str, Draws]:
    """Each law's draws at ``grid``; a law blind to a flagged group widened by its spread (new run)."""
    out = {}
    for s in sources:
        d = predict(s.fit, grid, seed)
        if new_run.widened(s.name):
            mu = new_run.widen(s.name, d.mu.reshape((-1, d.mu.shape[-1])), seed).reshape(d.mu.shape)
            d = Draws(mu, d.y + (mu - d.mu), d.noise_var, d.steady)
        out[s.name] = d
    return out


def _bend(distance, average: Mixture | None, used: Sequence[LawAnswer],
          misfits: Mapping[str, LocalMisfit | None]) -> Bend:
    """The bend of the data against the laws the answer rests on (:mod:`bayesfric.sizing.shape`):
    the average's weights, or the one law a single fit answers from."""
    weights = dict(average.weights) if average is not None else ({used[0].name: 1.0} if len(used) == 1 else {})
    tests = {name: (m.lack_of_fit() if (m := misfits.get(name)) is not None else None) for name in weights}
    return bend(distance, weights, tests)


def _averages(used, draws, weights, question, qs, key) -> Mixture | None:
    good = {k: v for k, v in weights.items() if math.isfinite(v) and v > 0 and k in {a.name for a in used}}
    return mixture(used, draws, good, question.confidence, qs, key) if good else None


def answer_question(question: SizingQuestion, sources: Sequence[LawSource], data: Mapping[str, np.ndarray], *,
                    schemes: Sequence[Scheme] = (), seed: int = 0, fan: bool = True,
                    misfits: Mapping[str, LocalMisfit | None] | None = None) -> Answer:
    """Answer one question from the laws' fits, weights and measured misses (see the module).

    ``data`` gives the data's SI values of every input of the question (the tested envelope);
    ``schemes`` the study's blocked extrapolation schemes; ``misfits`` each law's residuals at
    the data (:mod:`bayesfric.sizing.misfit`; none given: the folds' miss alone). With one
    source and no scheme (one fit), the law's answer is the only one: no average, no weights,
    no calibrated numbers.
    """
    misfits = misfits or {}
    qs = quantile_levels(question.confidence)
    grid = question.grid()
    tested = {k: (float(np.min(v)), float(np.max(v))) for k, v in data.items() if k in grid}
    distance = {k: point_distance(grid[k], data[k]) for k in grid if k in data}  # per direction
    new_run = new_run_rule(sources)
    draws = _predicted(sources, grid, seed, new_run)
    answers = [law_answer(s, draws[s.name], question, qs) for s in sources]
    used = [a for a in answers if a.excluded is None]
    warnings = _warnings(distance, sources, used)
    single = len(sources) == 1 and not schemes
    basis = None if single else choose_basis(
        grid, data, schemes, [a.name for a in used], {s.name: dict(s.weights) for s in sources},
        {s.name: dict(s.misses) for s in sources}, {s.name: dict(s.penalties) for s in sources}, new_run)
    weights = {used[0].name: 1.0} if single and used else (basis.weights if basis else {})
    average = _averages(used, draws, weights, question, qs, basis.key if basis else "single fit")
    calibrated: dict[str, Draws] = {}
    if average is not None and basis is not None and basis.calibrated:
        calibrated = _calibrate(answers, draws, sources, basis, schemes, grid, data, question, qs, seed, misfits)
        average.calibrated = mixture([a.calibrated for a in used], calibrated, average.weights, question.confidence,
                                     qs, basis.key)
    flag = undetected(sources, average.weights, basis, grid, data) if average is not None and basis else ""
    if flag:
        warnings.append(flag)
    bent = _bend(distance, average, used, misfits)
    if bent.direction == "downward":
        warnings.append(bent.statement)
    for a in answers:
        a.weight = average.weights.get(a.name, 0.0) if average is not None else 0.0
        a.weight_raw = weights.get(a.name, math.nan)
    no_average = "" if average is not None else (
        "every law is excluded" if not used else f"no law sizing may use has a positive weight ({basis.key})")
    loo = {s.name: s.weights.get(LOO, math.nan) for s in sources if s.excluded is None}
    average_loo = _averages(used, draws, loo, question, qs, f"stacking {LOO}") if len(used) > 1 else None
    if average is not None:
        governing = int(np.argmax((average.calibrated or average).required))
    elif used:
        governing = int(np.argmax(np.max([a.required for a in used], axis=0)))
    else:
        governing = 0
    out = Answer(question, grid, tested, distance, answers, average, average_loo, no_average, governing,
                 qs, warnings, basis=basis, undetected=flag, draws=draws, calibrated_draws=calibrated,
                 bend=bent.statement if bent.upward else "", bend_upward=bent.upward)
    if fan:
        out.fan = _fan(out, sources, data, seed, schemes=schemes, misfits=misfits)
    return out


def _fan(out: Answer, sources: Sequence[LawSource], data: Mapping[str, np.ndarray], seed: int,
         measured: tuple[np.ndarray, np.ndarray] | None = None, schemes: Sequence[Scheme] = (),
         misfits: Mapping[str, LocalMisfit | None] | None = None) -> Fan | None:
    question = out.question
    axis = _fan_axis(question, out.distance, out.tested)
    if axis is None:
        return None
    lo, hi = out.tested[axis]
    x = np.linspace(min(lo, question.at[axis].lo), max(hi, question.at[axis].hi), FAN_POINTS)
    grid = {k: (x if k == axis else np.full(FAN_POINTS, v.lo)) for k, v in question.at.items()}
    qs = quantile_levels(question.confidence)
    draws = _predicted(sources, grid, seed, new_run_rule(sources))
    bands = {}
    for s in sources:
        y = np.abs(draws[s.name].y).reshape(-1, FAN_POINTS)
        mu = np.abs(draws[s.name].mu).reshape(-1, FAN_POINTS)
        bands[s.name] = {"curve": np.median(mu, axis=0), "lo": np.quantile(y, LEVELS[0], axis=0),
                         "hi": np.quantile(y, LEVELS[-1], axis=0)}
    average = None
    if out.average is not None:
        stub = [law_answer(s, draws[s.name], question, qs, exceedance=False)
                for s in sources if s.name in out.average.weights]
        mix = mixture(stub, draws, out.average.weights, question.confidence, qs, out.average.basis)
        average = {"curve": mix.mean_fn.q(0.5), "lo": mix.noisy.q(LEVELS[0]), "hi": mix.noisy.q(LEVELS[-1]),
                   "required": mix.required}
        if out.average.calibrated is not None:
            picked = [s for s in sources if s.name in out.average.weights]
            cal = {s.name: _widened(s, draws[s.name], out.basis, schemes, grid, data, seed,
                                    (misfits or {}).get(s.name))[0] for s in picked}
            stub = [law_answer(s, cal[s.name], question, qs, exceedance=False) for s in picked]
            cmix = mixture(stub, cal, out.average.weights, question.confidence, qs, out.average.basis)
            average |= {"cal_lo": cmix.mean_fn.q(LEVELS[0]), "cal_hi": cmix.mean_fn.q(LEVELS[-1]),
                        "cal_required": cmix.required}
    return Fan(axis, x, (lo, hi), bands, [s.name for s in sources if s.excluded is not None], average,
               measured=measured)


def answer(questions: Sequence[SizingQuestion], sources: Sequence[LawSource], data: Mapping[str, np.ndarray], *,
           response: str, response_unit: str, response_scale: float, provenance: str, source: str,
           schemes: Sequence[Scheme] = (), measured: np.ndarray | None = None, seed: int = 0,
           fan: bool = True) -> SizingAnswer:
    """Answer every question (see :func:`answer_question`); ``fan``: also the fan figures' bands
    (with the ``measured`` response, SI, drawn against the fan's axis when given). Returns the
    one object every rendering reads (:class:`~bayesfric.sizing.result.SizingAnswer`)."""
    answers = []
    misfits = {} if measured is None or (len(sources) == 1 and not schemes) else {
        s.name: local_misfit(s.fit, data, measured, seed) for s in sources if s.excluded is None}
    for q in questions:
        out = answer_question(q, sources, data, schemes=schemes, seed=seed, fan=False, misfits=misfits)
        if fan:
            axis = _fan_axis(q, out.distance, out.tested)
            points = (np.asarray(data[axis]), np.abs(np.asarray(measured))) if axis and measured is not None else None
            out.fan = _fan(out, sources, data, seed, points, schemes, misfits)
        answers.append(out)
    return as_answer(SizingResult(answers, response, response_unit, response_scale, provenance, source))
