"""Findings and the top summary block of a study report, as structured data.

A :class:`Finding` is a sentence made of parts, each plain or emphasised (a law's name, a
headline number); the Markdown and HTML renderings decide how emphasis looks, so no Markdown is
written here and parsed back. Every verdict comes from the law × metric table
(:mod:`bayesfric.study.scores`) or a flag of the study's result tree (:mod:`bayesfric.study.tree`,
read through :class:`bayesfric.report.view.TreeView`), never from text. The sizing answer's basis
comes from the sizing result itself (:class:`bayesfric.sizing.result.SizingAnswer`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from bayesfric.compare.asymmetry import asymmetry
from bayesfric.compare.checks import PARETO_K_RELIABLE
from bayesfric.report.typeset import fmt, unit
from bayesfric.study import scores as sc

if TYPE_CHECKING:
    from bayesfric.compare.checks import RankingSensitivity
    from bayesfric.report.view import TreeView
    from bayesfric.sizing.result import SizingAnswer

__all__ = ["Finding", "Summary", "findings", "summary_block", "plain", "counted_winners", "RECOMMEND_WEIGHT",
           "residual_structure", "group_coverage",
           "sensitivity_sentence",
           "NO_CRITERION"]

#: A law is recommended alone when its stacking weight on the deciding criterion is at least
#: this; below it the report recommends the stacking-averaged prediction.
RECOMMEND_WEIGHT = 0.9
#: What the report says when the study computes no score that ranks the laws.
NO_CRITERION = ("The study has no ranking criterion: no PSIS-LOO ([compare] loo = false), no cross-validation "
                "(kfold = 0, no grouped or blocked folds) and no evidence (evidence = false), so the laws are "
                "not ranked; they are listed in the study file's order.")


@dataclass(frozen=True)
class Finding:
    """A sentence of parts ``(text, emphasised)``; ``warning`` marks a decision-changing one."""

    parts: tuple[tuple[str, bool], ...]
    warning: bool = False

    @property
    def text(self) -> str:
        """The sentence without emphasis."""
        return "".join(t for t, _ in self.parts)


def plain(text: str, warning: bool = False) -> Finding:
    """A finding of one plain part."""
    return Finding(((text, False),), warning)


def _f(*parts: str | tuple[str, bool], warning: bool = False) -> Finding:
    return Finding(tuple((p, False) if isinstance(p, str) else p for p in parts), warning)


def _law(name: str) -> tuple[str, bool]:
    return (name, True)


@dataclass
class Summary:
    """The top block: question, one answer per criterion, recommendation, warnings."""

    question: str
    answers: list[Finding] = field(default_factory=list)
    recommendation: Finding | None = None
    warnings: list[Finding] = field(default_factory=list)


def _unranked(table: pd.DataFrame, c: sc.Criterion) -> str:
    above = sc.passed_over(table, c.metric, c.scheme)
    if not above:
        return ""
    why = "; ".join(f"{name}: {sc.value(table, name, c.metric, c.scheme)['reason']}" for name in above)
    return f" ({', '.join(above)} scored higher but {'is' if len(above) == 1 else 'are'} not ranked — {why})"


def _score(table: pd.DataFrame, name: str, c: sc.Criterion) -> str:
    row = sc.value(table, name, c.metric, c.scheme)
    return f"{fmt(row['estimate'], row['se'])} nats"


def counted_winners(crits: list[sc.Criterion], table: pd.DataFrame) -> list[Finding]:
    """Per criterion whose winner would differ if the laws that may not be ranked were counted
    (a fold failed the gate, ...): who would win, by how much, and why it is not ranked."""
    out = []
    for c in crits:
        winner, counted = sc.best(table, c.metric, c.scheme), sc.best(table, c.metric, c.scheme, counted=True)
        if counted is None or counted == winner:
            continue
        row = sc.value(table, counted, c.metric, c.scheme)
        against = (f"; the ranked winner {winner} has {_score(table, winner, c)}" if winner is not None
                   else "; no law is ranked")
        out.append(_f(f"{c.label}: the winner would differ if ", _law(counted), f" were counted — it scored "
                      f"{_score(table, counted, c)}{against}. Not ranked: {row['reason']}.", warning=True))
    return out


def _answer(table: pd.DataFrame, c: sc.Criterion, loo_winner: str | None) -> Finding | None:
    winner = sc.best(table, c.metric, c.scheme)
    if winner is None:
        return _f(f"{c.label}: no law could be ranked (every result unreliable or missing).", warning=True)
    number = _score(table, winner, c)
    if c.kind == "extrapolation":
        same = ("the same law as under LOO" if winner == loo_winner or loo_winner is None
                else f"a different law from LOO ({loo_winner})")
        return _f(f"Best outside the tested envelope (blocked CV '{c.scheme}'): ", _law(winner),
                  f", elpd {number} — {same}{_unranked(table, c)}.")
    if c.kind == "interpolation":
        return _f("Best inside the tested envelope (PSIS-LOO): ", _law(winner),
                  f", elpd {number}{_unranked(table, c)}.")
    if c.kind == "evidence":
        return _f(f"Highest log evidence ({c.scheme}): ", _law(winner), f", log Z {number}{_unranked(table, c)}.")
    return _f(f"Best under {c.scheme}: ", _law(winner), f", elpd {number}{_unranked(table, c)}.")


def _asymmetry(a) -> str:
    """A :class:`~bayesfric.compare.asymmetry.Asymmetry` in words, rounded to its posterior sd."""
    shown = unit(a.unit)
    shown = "" if shown in ("", "–") else f" {shown}"
    return (f"{a.parameter}_pos − {a.parameter}_neg = {fmt(a.mean, a.sd, pm=False)}{shown} "
            f"[{fmt(a.low, a.sd, pm=False)}, {fmt(a.high, a.sd, pm=False)}] ({a.prob:.0%}), "
            f"P(> 0) = {a.p_positive:.2f}")


def findings(t: TreeView) -> list[Finding]:
    """The study's findings: the best law per criterion and the problems that limit them."""
    table, crits = t.table, t.crits
    loo_winner = sc.best(table, "elpd_loo") if t.has_loo else None
    lines = residual_structure(t) + [a for c in crits if (a := _answer(table, c, loo_winner)) is not None]
    lines += group_coverage(t)
    if not crits:
        lines.append(plain(NO_CRITERION, warning=True))
    for name in t.laws:  # direction-dependent coefficients (laws.variants): is the asymmetry supported?
        if t.law_object(name).recipe.get("asymmetric"):
            lines += [_f("Direction asymmetry of ", _law(name), f": {_asymmetry(a)}.") for a in asymmetry(t.fit(name))]
    lines += counted_winners(crits, table) + _warnings(t)
    for label, reason in t.weight_errors:
        lines.append(plain(f"{label} weights not computed: {reason}", warning=True))
    if t.quick is not None:
        quick = dict(t.quick)
        asked, folds = quick.pop("kfold_asked"), quick.pop("kfold_used")
        used = ", ".join(f"{k}={v}" for k, v in quick.items())
        kfold = f"; random K-fold with {folds} folds (the study asks {asked})" if asked else ""
        lines.append(plain(f"QUICK MODE: sampler {used}{kfold} — a pipeline smoke test, not a basis for decisions.",
                           warning=True))
    return lines


def group_coverage(t: TreeView) -> list[Finding]:
    """How the answers for a new group held where a whole group was left out: per law, the share
    of the held-out groups' rows inside the central 90 % (and 50 %) band of its fold's predictive
    (:func:`bayesfric.compare.refit.group_coverage`), a warning where a law's is below 80 %; none in
    a tree made before it was kept."""
    if "group_coverage_90" not in t.diag:
        return []
    shares = [(name, float(t.law(name)["group_coverage_90"]), float(t.law(name)["group_coverage_50"]))
              for name in t.laws]
    shares = [s for s in shares if np.isfinite(s[1])]
    if not shares:
        return []
    text = "; ".join(f"{name} {c90:.0%} (50 % band: {c50:.0%})" for name, c90, c50 in shares)
    return [plain("Answers for a new group, checked by leaving whole groups out: the 90 % predictive band "
                  f"held this share of the left-out groups' rows — {text}. Rows of a group move together, "
                  "so these shares scatter more than a count of independent rows would.",
                  warning=any(c90 < 0.8 for _, c90, _ in shares))]


def _warnings(t: TreeView) -> list[Finding]:
    out = []
    failed = [name for name in t.laws if not t.passed(name)]
    if failed:
        out.append(plain("Fits that FAILED the diagnostics gate (excluded from weights, marked in tables): "
                         f"{', '.join(failed)}.", warning=True))
    disagree = [name for name in t.laws if not t.flag(name, "evidence_agree")]
    if disagree:
        out.append(plain("Evidence estimators disagree beyond their combined error for: "
                         f"{', '.join(disagree)} (left out of the evidence ranking, never averaged).", warning=True))
    for name in t.laws:  # stages a failed fit skipped ([compare] failed_fits, study.units)
        if skipped := t.flag(name, "skipped"):
            out.append(_f(_law(name), ": the full fit failed the diagnostics gate, so "
                          f"{skipped} were not computed (compare.failed_fits = "
                          f"\"{t.attrs['failed_fits']}\"; set \"run\" to compute them anyway).", warning=True))
    pit = [name for name in t.laws if not t.flag(name, "loo_pit_ok")]
    if pit:
        named = ", ".join(name + (f" ({shape})" if (shape := t.flag(name, "loo_pit_direction")) else "")
                          for name in pit)
        out.append(plain(f"LOO-PIT miscalibrated (see the LOO-PIT figures under Data and checks): {named}.",
                         warning=True))
    if t.attrs.get("ranking_changed"):
        out.append(plain("The LOO ranking CHANGES when the priors are scaled (α = 0.5 or 2): the ranking is "
                         "prior-sensitive.", warning=True))
    unreliable_cv = sorted({name for name in t.laws if t.passed(name) and not t.flag(name, "cv_reliable")})
    if unreliable_cv:
        out.append(plain(f"Some cross-validation folds failed the gate for: {', '.join(unreliable_cv)} "
                         "(those scores are not ranked; each keeps its place in the ranking, marked ⚠ with the "
                         "reason).", warning=True))
    return out


def _deciding(crits: list[sc.Criterion]) -> sc.Criterion | None:
    return next((c for c in crits if c.kind in ("extrapolation", "interpolation")), crits[0] if crits else None)


def _weight_key(c: sc.Criterion) -> str:
    return f"stacking {c.scheme}" if c.kind == "extrapolation" else "stacking LOO"


def recommendation(crits: list[sc.Criterion], table: pd.DataFrame) -> Finding:
    """The law to use (or the stacking average), with the reason, from the deciding criterion:
    the first blocked-extrapolation scheme (the study's question), else PSIS-LOO."""
    c = _deciding(crits)
    if c is None:
        return plain("No recommendation: the study has no ranking criterion.", warning=True)
    winner = sc.best(table, c.metric, c.scheme)
    if winner is None:
        return _f("No recommendation: no law passed the checks on the deciding criterion.", warning=True)
    weights = table[(table["metric"] == "weight") & (table["scheme"] == _weight_key(c))]
    weights = weights[weights["estimate"].fillna(0.0) > 0.01]
    top = float(weights["estimate"].max()) if not weights.empty else 1.0
    why = f"highest {c.label}" + (" (prediction outside the tested envelope, the study's question)"
                                  if c.kind == "extrapolation" else " (no extrapolation scheme in this study)")
    if top >= RECOMMEND_WEIGHT or len(weights) < 2:
        return _f("Recommended: ", _law(winner), f" — {why}.")
    mix = ", ".join(f"{r.law} {fmt(r.estimate, digits=2)}"
                    for r in weights.sort_values("estimate", ascending=False).itertuples())
    return _f("Recommended: the ", ("stacking-averaged prediction", True), f" ({_weight_key(c)}: {mix}) — no single "
              f"law carries ≥ {RECOMMEND_WEIGHT:.0%} of the weight; ", _law(winner), f" alone has the {why}.")


def sizing_basis(crits: list[sc.Criterion], result: SizingAnswer | None, rec: Finding) -> Finding:
    """The recommendation with the basis each sizing question uses, read from the sizing result
    (the basis is chosen once there, per question, by the direction it extrapolates in): the
    same weights as the recommendation, or which others and why."""
    c = _deciding(crits)
    if result is None or c is None:
        return rec
    key = _weight_key(c).removeprefix("stacking ")
    parts = []
    for answer in result.answers:
        basis = answer.basis
        if basis is None:
            continue
        shares = sorted(answer.average.weights.items(), key=lambda kv: -kv[1]) if answer.average else []
        used = ", ".join(f"{k} {fmt(v, digits=2)}" for k, v in shares if v >= 0.005)
        same = [s.label for s in basis.schemes] == [key] or (not basis.schemes and key == "LOO")
        why = ("the recommendation's weights" if same else
               f"not the recommendation's weights: the question extrapolates in another direction ({basis.note})")
        parts.append(f"'{answer.question.label}' by {basis.key} ({used}), {why}")
    if not parts:
        return rec
    # group terms: say in the recommendation itself which run or unit the answers are for
    new = list(dict.fromkeys(w for a in result.answers for w in a.warnings if "answers for a NEW" in w))
    text = " Sizing uses, per question: " + "; ".join(parts) + "." + "".join(f" {w}." for w in new)
    return Finding(rec.parts + ((text, False),), rec.warning)


def no_law_extrapolates(blocked: list[str], table: pd.DataFrame) -> Finding | None:
    """The verdict "no law extrapolates" for the first blocked scheme on which every law's
    extrapolation penalty exceeds :data:`bayesfric.sizing.basis.NO_EXTRAPOLATION` nats per
    held-out point (None when some law stays under it on every scheme)."""
    from bayesfric.sizing.basis import NO_EXTRAPOLATION

    for scheme in blocked:
        rows = table[(table["metric"] == "penalty") & (table["scheme"] == scheme)].dropna(subset=["estimate"])
        # every law with a penalty there (a law whose fit failed the gate has none: it predicts nothing)
        if len(rows) and rows["estimate"].min() > NO_EXTRAPOLATION:
            best = rows.loc[rows["estimate"].idxmin()]
            return _f(f"NO LAW EXTRAPOLATES along '{scheme}': every law loses more than {NO_EXTRAPOLATION:g} nats "
                      "per held-out point beyond its training envelope (the least, ", _law(best["law"]),
                      f", {best['estimate']:.3g}). Read every ranking and recommendation below as valid inside the "
                      "tested envelope only; sizing beyond it quotes calibrated numbers only.", warning=True)
    return None


def residual_structure(t: TreeView) -> list[Finding]:
    """One finding per column in which some law's residuals differ between groups, or trend, at
    the same operating point beyond the noise (:mod:`bayesfric.compare.structure`): which laws,
    the largest effect with its test, and what would model it. The summary leads with them."""
    hits: dict[str, list] = {}
    for name in t.laws:
        for c in t.structure(name):
            if c.flagged and c.kind != "curvature":
                hits.setdefault(c.column, []).append((name, c))
    out = []
    for column, found in hits.items():
        name, worst = max(found, key=lambda h: h[1].effect_sd)
        laws = [n for n, _ in found]
        who = "every law" if len(found) == len(t.laws) else f"{len(found)} of {len(t.laws)} laws ({', '.join(laws)})"
        same = [f"'{c}'" for c, f in hits.items() if c != column and [n for n, _ in f] == laws]
        together = (f" Flagged for the same laws as {', '.join(same)}: possibly one effect seen through correlated "
                    "columns." if same else "")
        out.append(_f(f"RESIDUAL STRUCTURE in '{column}' ({who}): {worst.sentence()} (largest under ", _law(name),
                      "). Something the laws do not read moves the response: rankings, bands and sizing below "
                      "assume it does not." + together, warning=True))
    return out


def new_run(t: TreeView):
    """The new-run rule over the study's laws (:mod:`bayesfric.sizing.newrun`), from the tree."""
    from bayesfric.sizing.newrun import law_groups, rule
    return rule([law_groups(name, t.fit(name), t.passed(name), t.structure(name)) for name in t.laws])


def new_run_recommendation(rule, rec: Finding) -> Finding:
    """The recommendation, preceded by what it is for a new run when a group column was flagged:
    the laws that model it, the widened pooled laws, or that no answer for a new run can be given."""
    if not rule.mode:
        return rec
    cols = " and ".join(f"'{c}'" for c in rule.columns)
    if rule.mode == "aware":
        head = (f"For a NEW {cols} (the default question of sizing, predict and score): use ",
                (", ".join(rule.aware), True),
                f" — {'it models' if len(rule.aware) == 1 else 'they model'} {cols}, which the residual-structure "
                "check flagged; the laws blind to it "
                f"({', '.join(rule.blind) or 'none'}) describe the tested levels' average. For the tested ones: ")
    elif rule.mode == "cannot":
        head = (f"CANNOT ANSWER FOR A NEW {cols}: every law that models it ({', '.join(rule.failed)}) failed the "
                "diagnostics gate, and the others are blind to the differences the residual-structure check "
                "found; sizing widens them by the measured spread. For the tested levels: ",)
    else:
        head = (f"No law models {cols}, which the residual-structure check flagged: answers for a new "
                f"{cols} are the pooled laws widened by the measured spread. For the tested levels: ",)
    return Finding(tuple((h, False) if isinstance(h, str) else h for h in head) + rec.parts, True)


def lack_of_fit(t: TreeView) -> list[Finding]:
    """One finding per input along which some law's residuals bend (checks of kind ``curvature``):
    which laws, the largest bend with its test, and what an answer beyond the data says."""
    hits: dict[str, list] = {}
    for name in t.laws:
        for c in t.structure(name):
            if c.flagged and c.kind == "curvature":
                hits.setdefault(c.column, []).append((name, c))
    out = []
    for column, found in hits.items():
        name, worst = max(found, key=lambda h: abs(h[1].effect_sd))
        names = ", ".join(n for n, _ in found)
        who = "every law" if len(found) == len(t.laws) else f"{len(found)} of {len(t.laws)} laws ({names})"
        out.append(_f(f"LACK OF FIT along '{column}' ({who}): {worst.sentence()} (largest under ", _law(name),
                      "). An answer beyond the data along it says first where every law it rests on bends upward.",
                      warning=True))
    return out


def summary_block(t: TreeView, sizing: SizingAnswer | None = None,
                  extra_warnings: list[Finding] | None = None) -> Summary:
    """The top summary: question, one answer per criterion (after the residual-structure findings
    and the verdict that no law extrapolates, when those hold), recommendation (with the basis of
    each sizing question, when ``sizing`` answers some), decision warnings."""
    table, crits = t.table, t.crits
    loo_winner = sc.best(table, "elpd_loo") if t.has_loo else None
    answers = [a for c in crits if (a := _answer(table, c, loo_winner)) is not None]
    if not crits:
        answers.append(plain(NO_CRITERION, warning=True))
    if (verdict := no_law_extrapolates(t.blocked, table)) is not None:
        answers.insert(0, verdict)
    answers[:0] = residual_structure(t) + lack_of_fit(t)
    warnings = counted_winners(crits, table) + _warnings(t) + list(extra_warnings or [])
    blocked_winners = {sc.best(table, "elpd_cv", s) for s in t.blocked}
    if loo_winner and blocked_winners and loo_winner not in blocked_winners:
        warnings.insert(0, _f("The best law inside the tested envelope (", _law(loo_winner), ") is not the best "
                              "outside it: choose by the extrapolation criterion for sizing.", warning=True))
    if t.quick is not None:
        warnings.append(plain("QUICK MODE: short chains and few folds — not a basis for decisions.", warning=True))
    rule = new_run(t)
    rec = sizing_basis(crits, sizing, new_run_recommendation(rule, recommendation(crits, table)))
    if rule.mode:
        answers.insert(0, plain(rule.statement + ".", warning=True))
    return Summary(str(t.attrs["question"]), answers, rec, warnings)


def sensitivity_sentence(sens: RankingSensitivity | None) -> str:
    """The report's sentence on the LOO ranking under power-scaled priors (``""`` when it was not
    computed: fewer than two fits to rank)."""
    if sens is None:
        return ""
    powers = " and ".join(f"{a:g}" for a in sens.ranking if a != 1.0)
    changes = "; ".join(f"α={a}: {' > '.join(r)}" for a, r in sens.ranking.items() if a != 1.0)
    return (f"LOO ranking {' > '.join(sens.ranking[1.0])}; under prior powers α = {powers} it "
            + (f"CHANGES: {changes}" if sens.changed else "is unchanged") + " (PSIS reweighting, no refits)"
            + _high_k_note(sens) + ".")


def _high_k_note(sens: RankingSensitivity) -> str:
    """Which laws' reweighting had Pareto k̂ above the reliability threshold, at which α."""
    unreliable = sens.unreliable()
    if not unreliable:
        return ""
    laws = ", ".join(f"{name} (α = {', '.join(f'{a:g}' for a in alphas)})" for name, alphas in unreliable.items())
    return f"; approximate for {laws}: Pareto k̂ above {PARETO_K_RELIABLE}"
