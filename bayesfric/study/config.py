"""Study files: parse and validate a study TOML into a :class:`Study`.

A study names a data set, candidate laws (with prior overrides and constants), the noise model,
sampler settings, comparison methods and extrapolation folds::

    [study]
    name = "robot_joint"               # report folder reports/<name>/; default: the file name
    title = "Stäubli RX90 joint 1"
    question = "Which law, fitted on 0-0.5 rad/s, predicts the torque above 0.5 rad/s?"
    modules = ["my_laws.py"]           # optional: law files (relative to the study file) [[laws]] may name

    [data]
    dataset = "robot_joint"            # built-in name or a CSV path (relative to the study file)
    select = { series = [1, 2, 3] }    # optional row selection on coordinates
    every = 1                          # keep one row in n (a large log), per trajectory from its start

    [noise]
    kind = "normal"                    # normal | student_t | proportional | ar1 (AR(1) along trajectories)
    group = "series"                   # optional partial-pooled offsets

    [sampler]
    name = "nuts"                      # nuts | emcee
    draws = 1000                       # ≥ 1 (≥ 40 per chain, after thinning, when evidence = true)
    tune = 1000                        # ≥ 0
    chains = 4                         # nuts only, ≥ 1
    target_accept = 0.9                # nuts only, in (0, 1)
    retry_target_accept = 0.99         # nuts only: sample draws with divergences again at this target; 0: off
    metric = "auto"                    # nuts only: auto | diag | dense (auto: dense where correlations are strong)
    init = "median"                    # nuts only: median | pathfinder (chains start at Pathfinder draws)
    # walkers = 32                     # emcee only: ≥ 2 × free parameters (default max(32, 4 × them))
    # thin = 10                        # emcee only, ≥ 1
    seed = 0                           # 0 … 2³² − 1

    [[laws]]
    name = "armstrong_helouvry"
    priors = { delta = { dist = "LogNormal", loc = -1.1, scale = 0.3 } }

    [[laws]]                           # the same law again, as a variant (bayesfric.laws.variants)
    name = "stribeck"
    label = "stribeck_asym"            # required when a law is listed twice; names fits and tables
    add = ["viscous", "offset"]        # additive parts: terms "offset", "viscous" or registered laws
    offset = true                      # the same as add = ["offset"]
    asymmetric = ["T_C", "offset"]     # one value per direction: T_C_pos (velocity ≥ 0), T_C_neg (< 0)
    fixed = { delta = 1.0 }            # hold parameters (or constants) at a value, SI units
    vary_by = { series = ["T_C"] }     # group terms: T_C varies between series, partially pooled
                                       # (answers are then for a new series; bayesfric.hierarchy)
    trend = { hours = ["T_C"] }        # T_C follows a trend over the campaigns' service hours
    trend_form = "linear"              # linear | loglinear | walk (bayesfric.trend)

    [compare]
    loo = true
    kfold = 10                         # 0 disables; else 2 … number of points (or trajectories)
    grouped = "series"                 # leave-one-group-out (default: the column a law varies by)
    forecast = "hours"                 # leave-future-out over campaigns (default: a law's trend column)
    forecast_first = 2                 # campaigns only trained on before the first forecast
    evidence = true                    # bridge sampling + Laplace-t importance sampling (two estimators)
    smc = false                        # also tempered SMC as a reference (opt-in: 3-13x the fit's cost)
    smc_particles = 300                # SMC particles per run (default 300, at least 20)
    smc_runs = 3                       # independent SMC runs (≥ 2); their spread gives the MC error
    failed_fits = "skip"               # skip | run: CV refits, exact LOO refits and evidence of a law whose
                                       # fit failed the gate (skip: its LOO is PSIS only, no refit)
    companions = true                  # add a stateful law's reduced variant where the data do not identify
                                       # the full law (LuGre -> lugre_Fs_eq_Fc: F_s = F_c), ranked like any law

    [[compare.blocked]]
    axis = "velocity"                  # any input coordinate of the data
    threshold = "0.5 rad/s"            # with its unit ("300 rpm"), or a number in SI units; or quantile = 0.7
    direction = "upper"                # train below, score above; "lower" for high -> low
    future = false                     # true: leave-future-out, split each trajectory at the cut
                                       # (e.g. axis = "time"): train on its past, score its future

    [[sizing]]                         # optional, repeatable: actuator sizing questions
    label = "top speed, cold joint"    # label in reports (default: the point)
    at = { velocity = "0.5..6 rad/s" } # every input the laws read, in any unit of its quantity
    confidence = 0.99                  # in (0, 1): size for this quantile of |T| (default 0.99)
    capacity = "40 N*m"                # optional: available drive torque (or force): P(|T| > it)
    # energy_rotation = "90 deg"       # optional (torque data): friction energy of one rotation
    # horizon = "20000 h"              # optional (laws with a trend, one point, a capacity): when does
                                       # |friction| first exceed the capacity, forecast up to this service time

    [[claims]]                         # optional, repeatable: a claim of the source paper
    text = "Eq. 41 predicts above 0.5 rad/s"
    source = "seed 004 §3.3"
    kind = "best"                      # ratio | parameter | score | best (bayesfric.study.claims)
    law = "joint_tribological"
    metric = "elpd_cv"                 # a metric of bayesfric.study.scores.METRICS
    scheme = "train ≤ 0.5 rad/s, score above"
    # expect = [low, high]             # ratio, parameter, score: the claimed range
    basis = "pipeline check"           # or "evidence": was the claim's number used to build the data?
                                       # (required on reconstructed data; reports mark pipeline checks)

Sizing (``bayesfric size``, :mod:`bayesfric.sizing`): each ``at`` value is a string with its
unit, ``"8 MN*m"``, ``"1.04 rpm"``, ``"5 degC"``, or a range ``"<low>..<high> <unit>"`` (smaller
first) sized at :data:`bayesfric.sizing.RANGE_POINTS` evenly spaced points; at most one input per
question may be a range (the fan figure's axis). The keys are input quantities of the data, and
every input that a candidate law reads must be given: no input is silently held at a default (a
law that does not read an input ignores it). Values outside a quantity's physical bound, units
of another dimension, a capacity that is not of the data's response quantity, and an energy for
force data are errors. Trajectory (stateful) laws cannot be sized at a point: a study with
``[[sizing]]`` may not list one.

The schema — allowed keys, kinds, ranges, defaults, and which sampler each sampler setting
belongs to — is declared once, as the tables :data:`FILE` (with :data:`STUDY`, :data:`DATA`,
:data:`NOISE`, :data:`SAMPLER`, :data:`LAW`, :data:`COMPARE`, :data:`BLOCKED`, :data:`SIZING`,
:data:`CLAIM`) of :mod:`bayesfric.study.sections`;
:func:`bayesfric.study.schema.parse` derives validation, defaults and messages from them. The
sampler settings' rules and defaults are those of the one sampler configuration
(:class:`bayesfric.inference.config.SamplerConfig`), which also checks the table as a whole. The
study name becomes a folder name, so it must be a plain name (letters, digits, ``-``, ``_``, ``.``
not first, at most 64 characters; :func:`bayesfric.fsutil.name_problem`). The ``fit`` command and
``bayesfric.fit`` validate their sampler settings through the same configuration. Checks that
need the data (coordinates, inputs, number of K-fold folds, emcee walkers against the number of
free parameters, sizing inputs against the data and the laws) are in
:func:`bayesfric.study.runner.validate_against_data`.

Every error is a :class:`StudyError` with one line naming the file and the key:
``path: [section] key: problem``, ``path: laws[i].key: problem`` or
``path: sizing[i].at.velocity: problem`` or ``path: claims[i].at.velocity: problem``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from bayesfric.errors import UserError
from bayesfric.fsutil import name_problem
from bayesfric.inference.config import SamplerConfig
from bayesfric.laws import Law, get_law
from bayesfric.laws.plugins import LawModuleError, load_module
from bayesfric.laws.variants import VariantError, vary
from bayesfric.model import Noise
from bayesfric.priors import Prior, PriorError
from bayesfric.quantities import QUANTITIES
from bayesfric.sizing.points import SizingError, SizingQuestion, make_question, parse_value
from bayesfric.study.claimspec import Claim, ClaimError, make_claim
from bayesfric.study.samplers import (
    EVIDENCE_MIN_DRAWS,
    free_parameter_count,
    walkers_problem,
)
from bayesfric.study.schema import SchemaError, parse
from bayesfric.study.sections import (
    BLOCKED,
    CLAIM,
    COMPARE,
    DATA,
    FILE,
    LAW,
    NOISE,
    NUTS,
    SAMPLER,
    SIZING,
    STUDY,
    law_files_problem,
)
from bayesfric.study.spec import BlockedSpec, LawSpec, Study, StudyError

# Re-exported: the types (bayesfric.study.spec), the schema tables (bayesfric.study.sections) and
# the sampler checks (bayesfric.study.samplers) are imported from here as well.
__all__ = [
    "StudyError", "Study", "LawSpec", "BlockedSpec", "load_study", "study_from_raw",
    "FILE", "STUDY", "DATA", "NOISE", "SAMPLER", "LAW", "BLOCKED", "COMPARE", "SIZING", "CLAIM",
    "walkers_problem", "free_parameter_count", "EVIDENCE_MIN_DRAWS",
]


def _read(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise StudyError(f"{path}: study file not found" if not path.exists() else f"{path}: not a file")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{path}: invalid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise StudyError(f"{path}: not a UTF-8 text file") from None
    except OSError as exc:
        raise StudyError(f"{path}: cannot read ({exc.strerror})") from None


def _law_modules(path: Path, raw: dict[str, Any]) -> tuple[str, ...]:
    """Load the study's ``[study] modules`` (before the schema: ``[[laws]]`` may name their laws)."""
    section = raw.get("study")
    value = section.get("modules", []) if isinstance(section, dict) else []
    if problem := law_files_problem(value):
        raise StudyError(f"{path}: [study] modules: {problem}")
    files = tuple(str((path.parent / v).absolute()) for v in value)
    for i, (given, file) in enumerate(zip(value, files, strict=True)):
        try:
            load_module(file, label=given)
        except LawModuleError as exc:
            raise StudyError(f"{path}: [study] modules[{i}]: {exc}") from None
    return files


def _listed(value: Any) -> tuple[str, ...]:
    return tuple(value) if isinstance(value, list) else (value,)


def _added(entry: dict[str, Any]) -> tuple[str, ...]:
    """The entry's additive parts: ``add``, and ``offset`` when ``offset = true``."""
    add = _listed(entry["add"])
    return add + (("offset",) if entry["offset"] and "offset" not in add else ())


def _groups(entry: dict[str, Any], key: str = "vary_by") -> dict[str, tuple[str, ...]]:
    """The entry's group terms (or ``trend``s): column -> the parameters that vary between its levels."""
    return {str(k): _listed(v) for k, v in entry.get(key, {}).items()}


def _variant(where: str, entry: dict[str, Any]) -> Law:
    """The entry's law with its options, each checked in turn so an error names its key."""
    law = get_law(entry["name"])
    for key, options in (("add", {"add": _added(entry)}), ("asymmetric", {"asymmetric": _listed(entry["asymmetric"])}),
                         ("constants", {"fixed": entry["constants"]}), ("fixed", {"fixed": entry["fixed"]}),
                         ("vary_by", {"vary_by": _groups(entry)}),
                         ("trend", {"trend": _groups(entry, "trend"), "trend_form": entry.get("trend_form")})):
        if key == "constants" and (bad := [c for c in entry["constants"] if c not in law.constants]):
            raise StudyError(f"{where}.constants.{bad[0]}: law {law.name!r} has no constant {bad[0]!r} "
                             f"(constants: {', '.join(law.constants) or 'none'})")
        try:
            law = vary(law, **options)
        except VariantError as exc:  # exc.key names the option within the entry (fixed.i)
            sub = exc.key.split(".", 1)[1] if "." in exc.key else ""
            raise StudyError(f"{where}.{key}{'.' + sub if sub else ''}: {exc.problem}") from None
    return law


def _law_spec(path: Path, i: int, entry: dict[str, Any], noise: Noise, modules: tuple[str, ...]) -> LawSpec:
    """Law-specific checks of a parsed ``[[laws]]`` entry: options, parameter and constant names, priors."""
    where = f"{path}: laws[{i}]"
    law = _variant(where, entry)
    known = (list(law.params) + [f"{p}_sd" for p in law.varying] + [f"{p}_trend" for p in law.trending]
             + list(noise.sites()))
    priors = {}
    for pname, spec in entry["priors"].items():
        if pname not in known:
            raise StudyError(f"{where}.priors.{pname}: law {law.name!r} has no parameter {pname!r} "
                             f"(parameters: {', '.join(law.params)}; noise: {', '.join(noise.sites()) or 'none'})")
        try:
            priors[pname] = Prior.from_dict(spec)
        except PriorError as exc:  # exc.key: where inside the spec (scaled_by.response), if anywhere
            raise StudyError(f"{where}.{exc.within(f'priors.{pname}')}") from None
    return LawSpec(entry["label"] or entry["name"], priors, dict(entry["constants"]), law=entry["name"],
                   fixed=dict(entry["fixed"]), add=_added(entry), asymmetric=_listed(entry["asymmetric"]),
                   vary_by=_groups(entry), trend=_groups(entry, "trend"), trend_form=entry.get("trend_form"),
                   metric=entry["metric"], modules=modules)


def _threshold(path: Path, i: int, entry: dict[str, Any]) -> float | None:
    """A ``[[compare.blocked]]`` cut in SI units: a number as it is, a text (``"300 rpm"``) or a
    ``(number, unit)`` pair converted from the unit of its axis's quantity, as every
    operating-point key is."""
    value, axis = entry["threshold"], entry["axis"]
    if value is None or isinstance(value, int | float):
        return value
    text = f"{value[0]} {value[1]}" if isinstance(value, list) else value
    if axis not in QUANTITIES:
        raise StudyError(f"{path}: compare.blocked[{i}].threshold: {text!r} has a unit, but axis {axis!r} is not an "
                         "operating quantity to convert it for (give the cut in SI units)")
    try:
        return parse_value(text, axis, allow_range=False).lo
    except SizingError as exc:
        raise StudyError(f"{path}: compare.blocked[{i}].threshold: {exc.problem}") from None


def _sizing_question(path: Path, i: int, entry: dict[str, Any]) -> SizingQuestion:
    """Data-independent checks of a parsed ``[[sizing]]`` entry: values, units, ranges, bounds."""
    try:
        return make_question(entry["at"], entry["confidence"], label=entry["label"], capacity=entry["capacity"],
                             energy_rotation=entry["energy_rotation"], horizon=entry["horizon"])
    except SizingError as exc:
        raise StudyError(f"{path}: sizing[{i}].{exc}") from None


def _claim(path: Path, i: int, entry: dict[str, Any], laws: dict[str, Law]) -> Claim:
    """Data-independent checks of a parsed ``[[claims]]`` entry against the study's candidates
    (``laws``: label -> law; :func:`bayesfric.study.claims.make_claim`)."""
    try:
        return make_claim(entry, laws)
    except ClaimError as exc:
        raise StudyError(f"{path}: claims[{i}].{exc}") from None


def _law_specs(path: Path, spec: dict[str, Any], noise: Noise, modules: tuple[str, ...]) -> list[LawSpec]:
    """Every ``[[laws]]`` entry checked (:func:`_law_spec`), labels unique, ``metric`` only under NUTS."""
    laws = [_law_spec(path, i, entry, noise, modules) for i, entry in enumerate(spec["laws"])]
    names = [w.name for w in laws]
    for i, label in enumerate(names):
        if label in names[:i]:
            key = "label" if spec["laws"][i]["label"] else "name"
            raise StudyError(f"{path}: laws[{i}].{key}: {label!r} is listed twice: give each entry of the "
                             "same law its own label")
    for i, entry in enumerate(spec["laws"]):
        if entry["metric"] is not None and spec["sampler"]["name"] not in NUTS:
            raise StudyError(f"{path}: laws[{i}].metric: applies only to sampler {NUTS[0]} "
                             f"(here {spec['sampler']['name']!r})")
    return laws


def _check_sampler(path: Path, sampler: dict[str, Any]) -> None:
    """The ``[sampler]`` table as a configuration: what the schema cannot check (the retry target
    above ``target_accept``), keyed by the setting."""
    try:
        SamplerConfig.from_table(sampler)
    except UserError as exc:
        raise StudyError(f"{path}: [sampler] {exc.key}: {exc.problem}") from None


def _check_evidence_draws(path: Path, sampler: dict[str, Any]) -> None:
    per_chain = sampler["draws"] // sampler.get("thin", 1)
    if per_chain < EVIDENCE_MIN_DRAWS:
        thin = f" after thinning by {sampler['thin']}" if "thin" in sampler else ""
        raise StudyError(f"{path}: [sampler] draws: evidence = true (bridge sampling) needs at least "
                         f"{EVIDENCE_MIN_DRAWS} draws per chain{thin}, got {per_chain}")


def load_study(path: str | Path) -> Study:
    """Parse and validate a study file (data-dependent checks happen in the runner).

    Parameters
    ----------
    path : str or Path
        The study TOML file.

    Returns
    -------
    Study
        With every default filled (sampler settings: those of the chosen sampler).

    Raises
    ------
    StudyError
        Unreadable file, invalid TOML, unknown keys, values of the wrong kind or out of range,
        settings of another sampler, an invalid name, unknown law, parameter or constant, a bad
        prior, a law file (``[study] modules``) that is missing, fails to import or declares a
        law name already taken — one line naming the file and the key.
    """
    path = Path(path)
    return study_from_raw(path, _read(path))


def _group_column(laws: list[LawSpec], noise: Noise) -> str | None:
    """The column leave-one-group-out folds by when ``[compare] grouped`` is not given: the first
    column a law varies by (``vary_by``), else the noise model's group; None without groups. A
    study with groups is so scored on new groups, the question its answers are for."""
    columns = [c for w in laws for c in w.vary_by] + ([noise.group] if noise.group else [])
    return columns[0] if columns else None


def _trend_column(laws: list[LawSpec]) -> str | None:
    """The column leave-future-out folds along when ``[compare] forecast`` is not given: the
    first service coordinate a law follows a trend over; None without trends."""
    columns = [c for w in laws for c in w.trend]
    return columns[0] if columns else None


def study_from_raw(path: Path, raw: dict[str, Any]) -> Study:
    """Validate a study given as the parsed TOML (``raw``; :func:`load_study` reads it from
    ``path``, :class:`bayesfric.Study` builds it from Python objects). ``path`` names the study
    in every error, and relative paths (``[data] dataset``, ``[study] modules``) are resolved
    against its folder. Raises :class:`StudyError` as :func:`load_study` does."""
    modules = _law_modules(path, raw)
    try:
        spec = parse(FILE, raw)
    except SchemaError as exc:
        raise StudyError(f"{path}: {exc}") from None
    meta, data, compare = spec["study"], spec["data"], spec["compare"]
    name = meta["name"] if meta["name"] is not None else path.stem
    if meta["name"] is None and (problem := name_problem(name)):
        raise StudyError(f"{path}: [study] name: not given, and the file name cannot serve: {problem}")
    dataset = data["dataset"]
    if dataset.endswith(".csv"):  # beside the path as written (a link's sidecar is beside the link, as in `data check`)
        dataset = str((path.parent / dataset).absolute())
    noise = Noise(kind=spec["noise"]["kind"], group=spec["noise"]["group"])
    laws = _law_specs(path, spec, noise, modules)
    _check_sampler(path, spec["sampler"])
    if compare["evidence"]:
        _check_evidence_draws(path, spec["sampler"])
    blocked = [BlockedSpec(b["axis"], b["direction"], _threshold(path, i, b), b["quantile"], b["label"], b["future"])
               for i, b in enumerate(compare["blocked"])]
    sizing = [_sizing_question(path, i, entry) for i, entry in enumerate(spec["sizing"])]
    built = {w.name: w.build() for w in laws} if spec["claims"] else {}
    claims = [_claim(path, i, entry, built) for i, entry in enumerate(spec["claims"])]
    return Study(
        path=path, name=name, title=meta["title"] if meta["title"] is not None else name,
        question=meta["question"], dataset=dataset, select=data["select"], noise=noise,
        sampler=spec["sampler"], laws=laws, loo=compare["loo"], kfold=compare["kfold"],
        grouped=compare["grouped"] or _group_column(laws, noise), evidence=compare["evidence"], smc=compare["smc"],
        forecast=compare["forecast"] or _trend_column(laws), forecast_first=compare["forecast_first"],
        smc_particles=compare["smc_particles"],
        smc_runs=compare["smc_runs"], blocked=blocked, include_failed=compare["include_failed"],
        failed_fits=compare["failed_fits"], sizing=sizing, claims=claims, raw=raw, every=data["every"],
        max_levels=data["max_levels"],
        companions=compare["companions"],
    )
