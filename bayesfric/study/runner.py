"""Run a study: fit every candidate law, compare them every way the study asks, write the reports.

Output goes to ``<out_root>/<study>/`` atomically: everything is written into a marked hidden
work folder ``<out_root>/.<study>.<token>`` that replaces the old report folder only when the
whole study succeeded, so a failed or interrupted run never leaves a half-written report. Every
check of the study, its paths and its data runs before anything is written; an existing
``<out_root>/<study>`` is replaced only if bayesfric created it for this study; work folders of
killed runs are removed by the next run of the study (:mod:`bayesfric.fsutil`).

Besides the reports, every run stores ``weights.json`` (:mod:`bayesfric.sizing.store`): the
weights, the diagnostics and evidence verdicts and the weighting exclusions of every law, so
``bayesfric size`` can answer sizing questions from ``fits/*.nc`` later without refitting. A study
with ``[[sizing]]`` questions also gets them answered here: ``sizing.csv``, a fan figure per
question and a sizing section in ``summary.md`` and ``report.html``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from bayesfric import compare, fsutil, sizing
from bayesfric.datasets import DataError, load_dataset, resolve, select
from bayesfric.inference import SAMPLERS, release_compiled_code, save_fit
from bayesfric.laws.variants import for_data
from bayesfric.model import build_program
from bayesfric.priors import PriorError
from bayesfric.quantities import QUANTITIES
from bayesfric.study.claims import ClaimError, check_claim, evaluate_claims
from bayesfric.study.config import Study, StudyError, load_study, sampler_settings, walkers_problem
from bayesfric.study.outcome import Estimate, LawOutcome, StudyOutcome
from bayesfric.study.scores import score_table

__all__ = ["run_study", "validate_against_data", "sizing_questions", "load_study_data"]

#: ``--quick`` caps per sampler (a setting is lowered to its cap, never raised) and the cap on
#: K-fold folds: a smoke test of the whole pipeline, not for decisions (reports say so).
QUICK = {"nuts": {"draws": 300, "tune": 300, "chains": 2}, "emcee": {"draws": 1000, "tune": 1000, "thin": 10}}
QUICK_KFOLD = 4
#: Result keys of a law outcome that a CV scheme label must not shadow.
_RESERVED_LABELS = ("loo", "bridge", "SMC")


def validate_against_data(study: Study, ds) -> None:
    """Data-dependent checks of a study, before anything is written.

    Every key that names data must exist in it; every law must read inputs the data has and
    predict its response; every law's program must build (priors scaled by inputs the data
    has); random K-fold needs at most as many folds as points (or trajectories); emcee needs
    at least 2 walkers per free parameter.

    Raises
    ------
    StudyError
        One line naming the study file and the key.
    """
    where = str(study.path)
    coords = {k for k, v in ds.coords.items()}
    inputs = {k for k, v in ds.coords.items() if v.attrs.get("role") == "input"}
    if study.noise.group and study.noise.group not in coords:
        raise StudyError(f"{where}: [noise] group: {study.noise.group!r} is not a group of the data "
                         f"({', '.join(sorted(coords))})")
    if study.noise.kind == "ar1" and not ds.attrs.get("trajectory"):
        raise StudyError(f"{where}: [noise] kind: 'ar1' needs ordered trajectories, but the data "
                         "names no trajectory group")
    if study.grouped and study.grouped not in coords:
        raise StudyError(f"{where}: [compare] grouped: {study.grouped!r} is not a coordinate of the data "
                         f"({', '.join(sorted(coords))})")
    for i, b in enumerate(study.blocked):
        if b.axis not in inputs:
            raise StudyError(f"{where}: compare.blocked[{i}].axis: {b.axis!r} is not an input of the data "
                             f"(inputs: {', '.join(sorted(inputs))})")
    if study.kfold:
        try:
            compare.kfold_masks(ds, study.kfold)
        except ValueError as exc:
            raise StudyError(f"{where}: [compare] kfold: {exc}") from None
    for i, spec in enumerate(study.laws):
        try:  # the law as it runs on this data: its motion kind, without optional inputs it lacks
            law = for_data(spec.build(), ds)
        except DataError as exc:
            raise StudyError(f"{where}: laws[{i}] ({spec.name}): {exc}") from None
        missing = [f"{q} ({QUANTITIES[q].meaning})" for q in law.operating_inputs if q not in inputs]
        if missing:
            raise StudyError(f"{where}: laws[{i}] ({spec.name}) reads {'; '.join(missing)}, which the data lacks "
                             f"(its inputs: {', '.join(sorted(inputs)) or 'none'})")
        if law.response != ds.attrs["response"]:
            raise StudyError(f"{where}: laws[{i}] ({spec.name}) predicts {law.response}, the data has "
                             f"{ds.attrs['response']}")
        try:
            program = build_program(law, ds, priors=spec.priors, noise=study.noise, constants=spec.constants)
        except (PriorError, DataError) as exc:
            raise StudyError(f"{where}: laws[{i}] ({spec.name}): {exc}") from None
        if study.sampler["name"] == "emcee" and (problem := walkers_problem(program, study.sampler["walkers"])):
            raise StudyError(f"{where}: [sampler] walkers: {problem}")
    sizing_questions(study, ds)


def sizing_questions(study: Study, ds, questions: list[sizing.SizingQuestion] | None = None,
                     cli: bool = False) -> list[sizing.SizingQuestion]:
    """The study's ``[[sizing]]`` questions (or ``questions``) checked against the data and the laws.

    Every input named must be an input of the data, every input a candidate law reads must be
    given, a capacity must be of the data's response quantity, and no candidate law may be a
    trajectory law. Returns the questions with their capacity parsed.

    Raises
    ------
    StudyError
        One line naming the study file and the key (``sizing[i].at.velocity``), or with ``cli``
        the option (``--at velocity``) of a question given on the command line.
    """
    where = str(study.path)
    questions = study.sizing if questions is None else questions
    if not questions:
        return []
    inputs = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    laws = [for_data(spec.build(), ds) for spec in study.laws]  # inputs as the laws read this data
    for i, law in enumerate(laws):
        if law.trajectory:
            raise StudyError(f"{where}: laws[{i}] ({law.name}): a trajectory (stateful) law cannot be sized at an "
                             "operating point; remove it or the [[sizing]] questions")
    required = list(dict.fromkeys(q for law in laws for q in law.operating_inputs))
    checked = []
    for i, question in enumerate(questions):
        try:
            checked.append(sizing.check_question(question, inputs, required, ds.attrs["response"],
                                                 keys=sizing.CLI_KEYS if cli else None))
        except sizing.SizingError as exc:
            raise StudyError(str(exc) if cli else f"{where}: sizing[{i}].{exc}") from None
    return checked


def load_study_data(study: Study):
    """The study's data set with its row selection; problems name the study file and key."""
    try:
        ds = load_dataset(resolve(study.dataset))
    except DataError as exc:
        raise StudyError(f"{study.path}: [data] dataset: {exc}") from None
    try:
        return select(ds, study.select)
    except DataError as exc:
        raise StudyError(f"{study.path}: [data] select: {exc}") from None


def _fold_schemes(study: Study, ds, seed: int, kfold: int) -> list[tuple[str, object, str]]:
    """(label, Folds, kind) for every CV scheme the study asks for; kind: kfold, grouped or blocked.

    ``kfold`` is the number of random folds to use (the study's, or fewer under ``--quick``).
    A scheme the data cannot support (one group level, a cut with no point on one side) is a
    :class:`StudyError` naming its key (raised before anything is written).
    """
    where = str(study.path)
    schemes = []
    if kfold:
        schemes.append((f"{kfold}-fold", compare.kfold_masks(ds, kfold, seed=seed), "kfold"))
    if study.grouped:
        try:
            folds = compare.grouped_masks(ds, study.grouped)
        except (DataError, ValueError) as exc:
            raise StudyError(f"{where}: [compare] grouped: {exc}") from None
        schemes.append((f"leave-one-{study.grouped}-out", folds, "grouped"))
    for i, b in enumerate(study.blocked):
        try:
            folds = compare.blocked_masks(ds, b.axis, threshold=b.threshold, quantile=b.quantile,
                                          direction=b.direction, future=b.future)
        except (DataError, ValueError) as exc:
            raise StudyError(f"{where}: compare.blocked[{i}]: {exc}") from None
        schemes.append((b.label or folds.scheme, folds, "blocked"))
    labels = [label for label, _, _ in schemes]
    first = len(schemes) - len(study.blocked)
    for i in range(first, len(schemes)):
        if labels[i] in labels[:i] or labels[i] in _RESERVED_LABELS:
            raise StudyError(f"{where}: compare.blocked[{i - first}].label: {labels[i]!r} names another result "
                             "already; give each blocked fold its own label")
    return schemes


def _run_law(study: Study, spec, ds, folder: Path, schemes, settings: dict, seed: int, quick: bool) -> LawOutcome:
    start = time.perf_counter()
    clock = [start]

    def lap(stage: str) -> None:  # per-stage wall time, printed and stored with the outcome
        now = time.perf_counter()
        out.timings[stage] = now - clock[0]
        clock[0] = now

    program = build_program(spec.build(), ds, priors=spec.priors, noise=study.noise, constants=spec.constants)
    law = program.law  # as it runs on this data (motion kind, units), named by the entry's label
    if study.sampler.get("name", "nuts") == "nuts":
        # One compiled engine per law: the full fit is its all-true mask, and the same compiled
        # sampler refits every fold -- cold (the full warm-up from the prior median) for folds
        # that remove a whole region or series, warm-started from the full fit's draws and mass
        # matrix (a 250-step warm-up) for folds that drop a few points (PSIS-LOO's high-k
        # points, random K-fold), when the full fit passed the gate.
        engine = compare.RefitEngine(program, seed=seed, **settings)
        dt = engine.fit(ds)
    else:
        dt = SAMPLERS[study.sampler["name"]](program, ds, seed=seed, **settings)
        # folds of an emcee study are refitted with NUTS, at the NUTS defaults' length
        engine = compare.RefitEngine(program, draws=1000, tune=500, chains=4, seed=seed)
    fit_file = save_fit(dt, folder / "fits" / f"{law.name}.nc")
    verdict = compare.verdict_of(dt)
    out = LawOutcome(law=law, fit=dt, fit_file=fit_file, verdict=verdict)
    lap("fit")
    if not verdict.passed:
        out.flags.append("diagnostics FAILED: " + "; ".join(verdict.problems))
    cold_engine = engine
    warm_tune = min(250, engine.tune)  # a warm start needs ≥ 120 warm-up steps within the engine's
    near_engine = engine.warm_started(dt, warm_tune) if verdict.passed and warm_tune >= 120 else engine
    loo = None
    if study.loo:
        loo = compare.psis_loo(dt, program=program, engine=near_engine, seed=seed)
        out.results["loo"] = loo
        out.loo, out.loo_pointwise = Estimate(loo.elpd, loo.se), loo.elpd_i
        out.p_loo, out.pareto_k_max, out.n_high_k = loo.p_loo, float(np.max(loo.pareto_k)), loo.n_high_k
        out.high_k_handling = f"PSIS-LOO: {loo.n_high_k} points with Pareto k > {loo.k_threshold:.2f} ({loo.handling})"
        if not loo.reliable:
            why = "the full fit failed the gate" if not loo.fit_passed else loo.handling
            out.flags.append(f"LOO unreliable ({why})")
        lap("loo")
    for label, folds, kind in schemes:
        engine = near_engine if kind == "kfold" else cold_engine
        cv = compare.cross_validate(engine, folds, seed=seed)
        out.results[label] = cv
        out.cv[label] = Estimate(cv.elpd, cv.se)
        out.cv_pointwise[label] = cv.elpd_i
        out.cv_reliable[label] = cv.reliable
        if not cv.reliable:
            out.flags.append(f"{label}: folds {cv.failed_folds} failed the gate")
        if kind == "blocked" and loo is not None:
            out.penalty[label] = compare.extrapolation_penalty(loo, cv).per_point
        lap(f"cv {label}")
    if study.evidence:
        # Two estimators that share only the density: bridge sampling on the fit's draws and
        # importance sampling from a Laplace-t proposal (bench_evidence.py: together ≤ 0.63× the
        # fit on the shipped laws). Tempered SMC (3-13× the fit) runs only when the study asks.
        bridge = compare.bridge_log_evidence(program, dt, seed=seed)
        importance = compare.laplace_is_log_evidence(program, seed=seed)
        out.evidence = {"bridge": Estimate(bridge.log_z, bridge.error),
                        "importance": Estimate(importance.log_z, importance.error)}
        agreement = compare.compare_estimators(bridge, importance)
        out.evidence_disagreement = agreement.difference
        out.evidence_agree = agreement.agree
        if not agreement.agree:
            why = (f"importance weights heavy-tailed (Pareto k = {importance.diagnostics['pareto_k']:.2f})"
                   if not importance.diagnostics.get("reliable", True) else
                   f"> {agreement.threshold:.2f} nat")
            out.flags.append(f"evidence estimators disagree by {abs(agreement.difference):.2f} nat ({why}); "
                             "not ranked by evidence")
        lap("evidence")
        if study.smc:
            smc = compare.smc_log_evidence(program, seed=seed, particles=study.smc_particles, runs=study.smc_runs)
            out.evidence["SMC"] = Estimate(smc.log_z, smc.error)
            lap("SMC reference")
    out.prior_implausible = compare.prior_predictive_check(program, seed=seed).implausible
    pit = compare.loo_pit_check(dt, seed=seed)
    out.loo_pit_pvalue, out.loo_pit_ok = pit.ks_pvalue, bool(pit.within_band)
    if not pit.within_band:
        out.flags.append(f"LOO-PIT outside the {pit.ci_prob:.0%} band (KS p = {pit.ks_pvalue:.3f}): miscalibrated")
    sens = compare.prior_sensitivity(dt)
    flagged = [f"{i} ({d})" for i, d in zip(sens.index, sens["diagnosis"], strict=True) if d != "-"]
    out.prior_sensitivity = ("psense flags " + ", ".join(flagged) if flagged
                             else "no parameter flagged by power-scaling (psense)")
    lap("checks")
    out.seconds = time.perf_counter() - start
    print(f"    {law.name}: " + ", ".join(f"{k} {v:.0f} s" for k, v in out.timings.items()), flush=True)
    return out


def _assign_weights(out: StudyOutcome) -> None:
    """Stacking and pseudo-BMA+ weights from LOO, stacking from the first blocked scheme, and the
    prior sensitivity of the LOO ranking. Failed fits are excluded unless the study says otherwise."""
    fits = {w.name: w.fit for w in out.laws}
    bases = []
    if out.study.loo:
        bases += [("stacking LOO", "loo", "stacking"), ("pseudo-BMA+ LOO", "loo", "pseudo-BMA+")]
    if out.blocked:
        bases.append((f"stacking {out.blocked[0]}", out.blocked[0], "stacking"))
    for label, key, method in bases:
        results = {w.name: w.results[key] for w in out.laws if key in w.results}
        try:
            weights = compare.model_weights(results, method=method, include_failed=out.study.include_failed,
                                            fits=fits)
        except ValueError as exc:  # e.g. every fit excluded
            out.extra.setdefault("weight_errors", []).append((label, str(exc)))
            continue
        for w in out.laws:
            w.weights[label] = weights.weights.get(w.name, 0.0 if w.name in weights.excluded else float("nan"))
            if w.name in weights.excluded:
                w.weight_exclusions[label] = weights.excluded[w.name]
    if out.study.loo and len(fits) > 1:
        reliable = {w.name: w.fit for w in out.laws if w.reliable or out.study.include_failed}
        if len(reliable) > 1:
            sens = compare.ranking_sensitivity(reliable)
            order = " > ".join(sens.ranking[1.0])
            out.ranking_changed = bool(sens.changed)
            out.ranking_sensitivity = (
                f"LOO ranking {order}; under prior powers α = 0.5 and 2 it "
                + ("CHANGES: " + "; ".join(f"α={a}: {' > '.join(r)}" for a, r in sens.ranking.items() if a != 1.0)
                   if sens.changed else "is unchanged") + " (PSIS reweighting, no refits).")


def _run_settings(study: Study, quick: bool) -> tuple[dict, int]:
    """Backend settings and number of K-fold folds of this run: the study's (validated), or
    under ``--quick`` lowered to the :data:`QUICK` caps and at most :data:`QUICK_KFOLD` folds."""
    settings = sampler_settings(study.sampler)
    if not quick:
        return settings, study.kfold
    caps = QUICK[study.sampler["name"]]
    return settings | {k: min(settings[k], cap) for k, cap in caps.items() if k in settings}, \
        min(study.kfold, QUICK_KFOLD)


def _check_claims(study: Study, labels: list[str]) -> None:
    """The ``[[claims]]`` checked against the study's laws, schemes and evidence estimators."""
    estimators = (["bridge", "importance"] + (["SMC"] if study.smc else [])) if study.evidence else []
    for i, claim in enumerate(study.claims):
        try:
            check_claim(claim, [spec.name for spec in study.laws], labels, estimators)
        except ClaimError as exc:
            raise StudyError(f"{study.path}: claims[{i}].{exc}") from None


def _prepare(path: str | Path, out_root: str | Path, quick: bool):
    """Every check of a run, before anything is written: study, report folder, data, folds."""
    study = load_study(path)
    fsutil.check_output_folder(out_root)  # a root problem is not the study's: reported as the path's
    try:
        final = fsutil.report_folder(out_root, study.name)
    except fsutil.PathError as exc:
        raise StudyError(f"{study.path}: [study] name: {exc}") from None
    ds = load_study_data(study)
    validate_against_data(study, ds)
    settings, kfold = _run_settings(study, quick)
    schemes = _fold_schemes(study, ds, study.sampler["seed"], kfold)
    _check_claims(study, [label for label, _, _ in schemes])
    return study, final, ds, settings, kfold, schemes, sizing_questions(study, ds)


def run_study(path: str | Path, out_root: str | Path = "reports", quick: bool = False) -> Path:
    """Run the study file at ``path`` and write ``<out_root>/<study name>/``.

    Parameters
    ----------
    path : str or Path
        Study TOML file.
    out_root : str or Path
        Reports root folder (created if missing).
    quick : bool
        Smoke test: fewer draws and folds (:data:`QUICK`, :data:`QUICK_KFOLD`), applied after
        the study's own settings were validated; the report says so.

    Returns
    -------
    Path
        The report folder.

    Raises
    ------
    StudyError, DataError
        One line, on bad input, before anything is written.
    """
    start = time.perf_counter()
    study, final, ds, settings, kfold, schemes, questions = _prepare(path, out_root, quick)
    seed = study.sampler["seed"]
    root = final.parent
    for stale in fsutil.clean_stale_work(root, study.name):
        print(f"[{study.name}] removed the work folder of an interrupted run: {stale}", flush=True)
    work = fsutil.create_work_folder(root, study.name)
    try:
        outcomes = []
        for spec in study.laws:
            print(f"[{study.name}] fitting {spec.name} ...", flush=True)
            outcomes.append(_run_law(study, spec, ds, work, schemes, settings, seed, quick))
            release_compiled_code()  # one law's compiled samplers are not reused by the next
        outcome = StudyOutcome(study=study, data=ds, laws=outcomes, schemes=[s[0] for s in schemes],
                               blocked=[s[0] for s in schemes if s[2] == "blocked"],
                               heldout={s[0]: s[1].heldout.any(axis=0) for s in schemes})
        if quick:
            outcome.extra["quick"] = {"settings": settings, "kfold": (study.kfold, kfold)}
        _assign_weights(outcome)
        # What `bayesfric size` needs to answer sizing questions later without refitting.
        record = sizing.weights_record(outcome)
        sizing.write_record(work, record)
        if questions:
            print(f"[{study.name}] sizing {len(questions)} question(s) ...", flush=True)
            law_sources = sizing.sources(record, work, [w.name for w in outcome.laws],
                                         fits={w.name: w.fit for w in outcome.laws})
            outcome.sizing = sizing.size_study(questions, ds, law_sources, record, study_name=study.name, seed=seed)
        outcome.table = score_table(outcome)
        outcome.claims = evaluate_claims(study.claims, outcome, outcome.table)
        outcome.seconds = time.perf_counter() - start
        from bayesfric.report.summary import write_reports  # here: bayesfric.report reads bayesfric.study

        write_reports(outcome, work)
        try:
            fsutil.install_folder(work, final, study.name)
        except fsutil.PathError as exc:
            raise StudyError(f"{study.path}: [study] name: {exc}") from None
    except BaseException:
        fsutil.remove_work_folder(work, study.name)
        raise
    print(f"[{study.name}] report written to {final} ({time.perf_counter() - start:.0f} s)")
    return final
