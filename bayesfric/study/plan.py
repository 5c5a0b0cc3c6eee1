"""Everything a study run checks and plans before anything is written: the study against its
data and laws (:func:`validate_against_data`), its sizing questions, its CV schemes, the run's
settings (``--quick``), its claims, and each law's units (:func:`_plan_laws`).

:func:`bayesfric.pipeline.runner.run_study` calls :func:`_prepare` first; a problem is a
:class:`~bayesfric.study.config.StudyError` naming the study file and the key, and nothing has
been written.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from pathlib import Path

from bayesfric import compare, fsutil, identifiability, limits, outpaths, sizing
from bayesfric.datasets import DataError, load_dataset, resolve, select
from bayesfric.datasets.rows import group_problem, levels_of, thin
from bayesfric.inference.config import SamplerConfig
from bayesfric.laws.variants import for_data
from bayesfric.model import build_program
from bayesfric.priors import PriorError
from bayesfric.quantities import QUANTITIES
from bayesfric.study import units
from bayesfric.study.claims import ClaimError, basis_problem, check_claim
from bayesfric.study.config import Study, StudyError, load_study, walkers_problem
from bayesfric.study.store import store_folder

__all__ = ["validate_against_data", "sizing_questions", "load_study_data", "QUICK", "QUICK_KFOLD", "QuickRun",
           "with_identifiability"]

#: ``--quick`` caps per sampler (a setting is lowered to its cap, never raised) and the cap on
#: K-fold folds: a smoke test of the whole pipeline, not for decisions (reports say so).
@dataclass(frozen=True)
class QuickRun:
    """The settings a ``--quick`` run capped: the sampler's configuration, and K-fold's (asked, used)."""

    config: SamplerConfig
    kfold: tuple[int, int]


QUICK = {"nuts": {"draws": 300, "tune": 300, "chains": 2}, "emcee": {"draws": 1000, "tune": 1000, "thin": 10}}
QUICK_KFOLD = 4
#: Unit labels of a law (:func:`bayesfric.study.rebuild.rebuild` finds results by label): no CV scheme may take one.
_RESERVED_LABELS = ("loo", "bridge", "SMC")


def validate_against_data(study: Study, ds) -> None:
    """Data-dependent checks of a study, before anything is written.

    Every key that names data must exist in it; every law must read inputs the data has and
    predict its response; every law's program must build (priors scaled by inputs the data
    has); random K-fold needs at most as many folds as points (or trajectories); emcee needs
    at least 2 walkers per free parameter; the sampler and SMC settings must fit in memory
    (:mod:`bayesfric.limits`).

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
    _check_groups(study, ds)
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
            program = build_program(law, ds, priors=spec.priors, noise=study.noise)
        except PriorError as exc:  # exc.key: priors.<parameter>.<key in its spec>
            key = f"laws[{i}].{exc.key}" if exc.key else f"laws[{i}]"
            raise StudyError(f"{where}: {key}: {exc.problem} (law {spec.name!r})") from None
        except DataError as exc:
            raise StudyError(f"{where}: laws[{i}] ({spec.name}): {exc}") from None
        _check_rows(study, spec, program)
        _check_sizes(study, spec, program)
    sizing_questions(study, ds)


def _group_keys(study: Study) -> list[tuple[str, str]]:
    """(key, column) of every group column the study names: the laws' ``vary_by`` and ``trend``
    (before ``[compare] grouped``, which defaults to such a column), the noise's group, the folds'."""
    keys = [(f"laws[{i}].{key}", c) for i, spec in enumerate(study.laws)
            for key, columns in (("vary_by", spec.vary_by), ("trend", spec.trend)) for c in columns]
    keys += [(key, c) for key, c in (("[noise] group", study.noise.group), ("[compare] grouped", study.grouped),
                                     ("[compare] forecast", study.forecast)) if c]
    return keys


def _check_groups(study: Study, ds) -> None:
    """Every group column the study names looks like one (:func:`bayesfric.datasets.rows.group_problem`)
    and has at most ``[data] max_levels`` levels: more are refused with their cost, unless confirmed."""
    named: dict[str, str] = {}  # column -> the first key naming it
    for key, column in _group_keys(study):
        if problem := group_problem(ds, column):
            raise StudyError(f"{study.path}: {key}: {problem}")
        named.setdefault(column, key)
    for column, key in named.items():
        levels = len(levels_of(ds, column))
        if levels <= study.max_levels:
            continue
        laws = len(study.laws)
        varying = sum(len(ps) for spec in study.laws for c, ps in spec.vary_by.items() if c == column)
        cost = [f"leave-one-{column}-out refits every law once per level, {levels} × {laws} = {levels * laws} "
                "refits, each about as long as a full fit"] if study.grouped == column else []
        cost += [f"vary_by samples {levels} × {varying} level values"] if varying else []
        raise StudyError(f"{study.path}: {key}: group column {column!r} has {levels} levels, more than [data] "
                         f"max_levels = {study.max_levels} ({'; '.join(cost) or 'a value per level and parameter'}); "
                         f"set [data] max_levels = {levels} to run it anyway, or group coarser")


def _check_rows(study: Study, spec, program) -> None:
    """The data left after ``[data] select`` and ``every`` hold at least as many rows as the law
    has free parameters (its own and the noise model's)."""
    free = limits.program_size(program)[0] - len(program.law.derived)
    rows = program.n_obs
    if rows >= free:
        return
    key = "[data] every" if study.every > 1 else "[data] select" if study.select else "[data] dataset"
    how = f"one row in {study.every} of each trajectory leaves" if study.every > 1 else "the data hold"
    raise StudyError(f"{study.path}: {key}: {how} {rows} row{'s' * (rows != 1)}, fewer than the {free} parameters "
                     f"of law {spec.name!r}: nothing could be learned from them; thin less or select more rows")


def _check_sizes(study: Study, spec, program) -> None:
    """emcee walkers against the free parameters of one law's ``program``, and the memory its
    sampler and SMC settings imply (:mod:`bayesfric.limits`), as the study file gives them."""
    where, sampler = study.path, study.sampler
    if sampler["name"] == "emcee" and (problem := walkers_problem(program, sampler["walkers"])):
        raise StudyError(f"{where}: [sampler] walkers: {problem}")
    size = limits.program_size(program)
    if found := limits.sampler_problem(sampler["name"], sampler, *size):
        raise StudyError(f"{where}: [sampler] {found[0]}: {found[1]} (law {spec.name!r})")
    if study.smc and (found := limits.smc_problem(study.smc_particles, study.smc_runs, *size)):
        raise StudyError(f"{where}: [compare] {found[0]}: {found[1]} (law {spec.name!r})")


def sizing_questions(study: Study, ds, questions: list[sizing.SizingQuestion] | None = None,
                     cli: bool = False, keys: dict[str, str] | None = None) -> list[sizing.SizingQuestion]:
    """The study's ``[[sizing]]`` questions (or ``questions``) checked against the data and the laws.

    Every input named must be an input of the data (or one a stateful law's steady state reads),
    every input a candidate law reads must be given (a trajectory law: its steady state's,
    :func:`bayesfric.sizing.sizing_law`), a capacity must be of the quantity sized (the data's
    response; a coast-down's steady state: torque), and every trajectory law must declare a steady
    state. Returns the questions with their capacity parsed.

    Raises
    ------
    StudyError
        One line naming the study file and the key (``sizing[i].at.velocity``), or with ``cli``
        the option (``--at velocity``) of a question given on the command line, or with ``keys``
        the key they name (``at.velocity``: :func:`bayesfric.size`'s arguments).
    """
    where = str(study.path)
    questions = study.sizing if questions is None else questions
    if not questions:
        return []
    inputs = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    laws = [for_data(spec.build(), ds) for spec in study.laws]  # inputs as the laws read this data
    for i, law in enumerate(laws):
        try:
            laws[i] = sizing.sizing_law(law)  # a trajectory law: its steady state at constant speed
        except sizing.SizingError as exc:
            raise StudyError(f"{where}: laws[{i}] ({law.name}): {exc.problem}; remove it or the [[sizing]] "
                             "questions") from None
    required = list(dict.fromkeys(q for law in laws for q in law.operating_inputs))
    inputs += [q for q in required if q not in inputs]
    responses = {law.response for law in laws}
    response = responses.pop() if len(responses) == 1 else ds.attrs["response"]
    checked = []
    for i, question in enumerate(questions):
        try:
            checked.append(sizing.check_question(question, inputs, required, response,
                                                 keys=sizing.CLI_KEYS if cli else keys))
        except sizing.SizingError as exc:
            raise StudyError(str(exc) if cli or keys is not None else f"{where}: sizing[{i}].{exc}") from None
        if question.horizon is not None and not any(spec.trend for spec in study.laws):
            raise StudyError(f"{where}: sizing[{i}].horizon: no law follows a trend over a service coordinate "
                             "(trend = { hours = [...] }), so none can forecast when the capacity is exceeded")
        if question.horizon is not None:  # converted into the service column's unit, as the runner will
            column = next(c for spec in study.laws for c in spec.trend)
            try:
                sizing.points.parse_horizon(question.horizon, ds[column].attrs.get("units", ""))
            except sizing.SizingError as exc:
                raise StudyError(f"{where}: sizing[{i}].horizon: {exc.problem} (column {column!r})") from None
    return checked


def load_study_data(study: Study):
    """The study's data set with its row selection; problems name the study file and key."""
    try:
        ds = load_dataset(resolve(study.dataset))
    except DataError as exc:
        raise StudyError(f"{study.path}: [data] dataset: {exc}") from None
    try:
        ds = select(ds, study.select)
    except DataError as exc:
        raise StudyError(f"{study.path}: [data] select: {exc}") from None
    return thin(ds, study.every)


def _fold_schemes(study: Study, ds, seed: int, kfold: int) -> list[tuple[str, object, str]]:
    """(label, Folds, kind) for every CV scheme the study asks for; kind: kfold, grouped, forecast or
    blocked.

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
    if study.forecast:
        try:
            folds = compare.forecast_masks(ds, study.forecast, study.forecast_first)
        except (DataError, ValueError) as exc:
            raise StudyError(f"{where}: [compare] forecast: {exc}") from None
        schemes.append((f"leave-future-{study.forecast}-out", folds, "forecast"))
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


def _plan_laws(study: Study, ds, schemes, config: SamplerConfig, seed: int) -> list:
    """(job, fit unit, following units) of every law, keyed by everything each depends on; each
    law runs with the run's ``config`` (:func:`_run_settings`) at the study's ``seed``, with its
    own metric where its entry gives one."""
    config = config.replace(seed=seed)
    plans = []
    for spec in study.laws:
        job = units.make_job(spec, study.noise, ds, spec.config(config))
        plans.append((job, *units.plan_law(job, study, schemes)))
    return plans


def _run_settings(study: Study, quick: bool) -> tuple[SamplerConfig, int]:
    """The sampler configuration and number of K-fold folds of this run: the study's (validated),
    or under ``--quick`` lowered to the :data:`QUICK` caps and at most :data:`QUICK_KFOLD` folds."""
    config = study.sampler_config
    if not quick:
        return config, study.kfold
    return config.replace(**{k: min(getattr(config, k), cap) for k, cap in QUICK[config.name].items()}), \
        min(study.kfold, QUICK_KFOLD)


def _check_claims(study: Study, labels: list[str], ds) -> None:
    """The ``[[claims]]`` checked against the study's laws as they run on ``ds``, its schemes and
    evidence estimators, and their ``basis`` against the data's provenance
    (:func:`bayesfric.study.claims.basis_problem`)."""
    estimators = (["bridge", "importance"] + (["SMC"] if study.smc else [])) if study.evidence else []
    laws = {spec.name: for_data(spec.build(), ds) for spec in study.laws} if study.claims else {}
    provenance = str(ds.attrs.get("provenance", ""))
    for i, claim in enumerate(study.claims):
        try:
            check_claim(claim, laws, labels, estimators)
        except ClaimError as exc:
            raise StudyError(f"{study.path}: claims[{i}].{exc}") from None
        if problem := basis_problem(claim, provenance):
            raise StudyError(f"{study.path}: claims[{i}].basis: {problem}")


def _companion(spec, checks: list, taken: set[str]):
    """The reduced variant of ``spec`` where its failed checks name one (None otherwise, or where its
    label is taken, or a reduced parameter varies by a group or a trend)."""
    suffix, fixed = identifiability.reduction(checks)
    label = f"{spec.name}_{suffix}"
    grouped = {p for terms in (spec.vary_by, getattr(spec, "trend", {})) for ps in terms.values() for p in ps}
    if not fixed or label in taken or set(fixed) & grouped:
        return None
    return dataclasses.replace(spec, name=label, fixed=spec.fixed | fixed, companion_of=spec.name,
                               priors={k: v for k, v in spec.priors.items() if k not in fixed})


def with_identifiability(study: Study, ds) -> Study:
    """``study`` (a copy) with each law's identifiability checks on ``ds``
    (:func:`bayesfric.identifiability.assess`, in ``identifiability``) and, under ``[compare]
    companions = true``, the reduced variant of each law whose parameters the data do not
    determine as a companion entry after the study's own (labelled ``<label>_<reduction>``,
    e.g. ``lugre_Fs_eq_Fc``), checked against the data as the study's entries are."""
    def assess(spec) -> list:
        law = for_data(spec.build(), ds)
        program = build_program(law, ds, priors=spec.priors, noise=study.noise)
        return identifiability.assess(law, spec.law or spec.name, ds, program.resolved)

    out = copy.copy(study)
    out.identifiability, added = [], []
    taken = {spec.name for spec in study.laws}
    for spec in study.laws:
        checks = assess(spec)
        out.identifiability += checks
        companion = _companion(spec, checks, taken) if study.companions and not spec.companion_of else None
        if companion is not None:
            added.append(companion)
            taken.add(companion.name)
    if added:
        out.laws = list(study.laws) + added
        validate_against_data(out, ds)
        out.identifiability += [c for spec in added for c in assess(spec)]  # what the companions still need
    return out


def _check_inputs_outside(study: Study, final: Path) -> None:
    """No file the study reads (its file, its data and sidecar, its law files) lies inside the
    report folder the run replaces as a whole (:func:`bayesfric.outpaths.overwrite_problem`)."""
    reads = [(study.path, "the study file", "[study] name")]
    reads += [(p, what, "[data] dataset") for p, what in outpaths.data_files(study.dataset)]
    modules = dict.fromkeys(m for spec in study.laws for m in spec.modules)
    reads += [(Path(m), "a law file", "[study] modules") for m in modules]
    for path, what, key in reads:
        if outpaths.overwrite_problem(path, folders=[(final, "the report folder")]):
            raise StudyError(f"{study.path}: {key}: {what} {path} lies inside the report folder {final}, which this "
                             "run replaces; move it out of the reports folder (or run with another --out)")


def _prepare(path: str | Path | Study, out_root: str | Path, quick: bool):
    """Every check of a run, before anything is written: study, report folder, data, folds."""
    study = path if isinstance(path, Study) else load_study(path)
    fsutil.check_output_folder(out_root)  # a root problem is not the study's: reported as the path's
    try:
        final = fsutil.report_folder(out_root, study.name)
    except fsutil.PathError as exc:
        raise StudyError(f"{study.path}: [study] name: {exc}") from None
    try:  # its folders below the reports root are real folders, as the report folder's are
        store_folder(out_root, study.name)
    except fsutil.PathError as exc:
        raise StudyError(f"{study.path}: run store: {exc}") from None
    _check_inputs_outside(study, final)
    ds = load_study_data(study)
    validate_against_data(study, ds)
    study = with_identifiability(study, ds)  # and the companion entries it adds
    settings, kfold = _run_settings(study, quick)
    schemes = _fold_schemes(study, ds, study.sampler["seed"], kfold)
    _check_claims(study, [label for label, _, _ in schemes], ds)
    return study, final, ds, settings, kfold, schemes, sizing_questions(study, ds)
