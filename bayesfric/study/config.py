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
    metric = "diag"                    # nuts only: diag | dense (mass matrix; dense for correlated coefficients)
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

    [compare]
    loo = true
    kfold = 10                         # 0 disables; else 2 … number of points (or trajectories)
    grouped = "series"                 # optional leave-one-group-out
    evidence = true                    # bridge sampling + Laplace-t importance sampling (two estimators)
    smc = false                        # also tempered SMC as a reference (opt-in: 3-13x the fit's cost)
    smc_particles = 300                # SMC particles per run (default 300, at least 20)
    smc_runs = 3                       # independent SMC runs (≥ 2); their spread gives the MC error
    failed_fits = "skip"               # skip | run: CV refits and evidence of a law whose fit failed the gate

    [[compare.blocked]]
    axis = "velocity"                  # any input coordinate of the data
    threshold = 0.5                    # SI units; or quantile = 0.7
    direction = "upper"                # train below, score above; "lower" for high -> low
    future = false                     # true: leave-future-out, split each trajectory at the cut
                                       # (e.g. axis = "time"): train on its past, score its future

    [[sizing]]                         # optional, repeatable: actuator sizing questions
    label = "top speed, cold joint"    # label in reports (default: the point)
    at = { velocity = "0.5..6 rad/s" } # every input the laws read, in any unit of its quantity
    confidence = 0.99                  # in (0, 1): size for this quantile of |T| (default 0.99)
    capacity = "40 N*m"                # optional: available drive torque (or force): P(|T| > it)
    # energy_rotation = "90 deg"       # optional (torque data): friction energy of one rotation

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
:data:`NOISE`, :data:`SAMPLER`, :data:`LAW`, :data:`COMPARE`, :data:`BLOCKED`, :data:`SIZING`) below;
:func:`bayesfric.study.schema.parse` derives validation, defaults and messages from them. The
sampler defaults are the backends' own (:data:`bayesfric.inference.SAMPLERS`). The study name
becomes a folder name, so it must be a plain name (letters, digits, ``-``, ``_``, ``.`` not first,
at most 64 characters; :func:`bayesfric.fsutil.name_problem`). The ``fit`` command validates its
sampler options against the same :data:`SAMPLER` table. Checks that need the data (coordinates,
inputs, number of K-fold folds, emcee walkers against the number of free parameters, sizing
inputs against the data and the laws) are in :func:`bayesfric.study.runner.validate_against_data`.

Every error is a :class:`StudyError` with one line naming the file and the key:
``path: [section] key: problem``, ``path: laws[i].key: problem`` or
``path: sizing[i].at.velocity: problem`` or ``path: claims[i].at.velocity: problem``.
"""

from __future__ import annotations

import inspect
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, get_args, get_type_hints

import numpy as np
from numpyro import handlers

from bayesfric.errors import UserError
from bayesfric.fsutil import name_problem
from bayesfric.inference import SAMPLERS
from bayesfric.inference.engine import METRICS
from bayesfric.inference.init import INITS
from bayesfric.laws import Law, get_law
from bayesfric.laws.plugins import LawModuleError, load_module, load_modules
from bayesfric.laws.variants import VariantError, vary
from bayesfric.model import Noise, Program
from bayesfric.priors import Prior, PriorError
from bayesfric.sizing.points import SizingError, SizingQuestion, make_question
from bayesfric.study.claims import BASES as CLAIM_BASES
from bayesfric.study.claims import KINDS as CLAIM_KINDS
from bayesfric.study.claims import Claim, ClaimError, make_claim
from bayesfric.study.schema import REQUIRED, Field, Schema, SchemaError, parse

__all__ = [
    "StudyError", "Study", "LawSpec", "BlockedSpec", "load_study", "study_from_raw", "FILE", "SAMPLER", "SIZING",
    "sampler_settings",
    "walkers_problem", "free_parameter_count", "EVIDENCE_MIN_DRAWS",
]

#: Bridge sampling splits every chain in halves of at least 20 draws.
EVIDENCE_MIN_DRAWS = 40


class StudyError(UserError):
    """A study file error: one line naming the file and key."""


@dataclass(frozen=True)
class LawSpec:
    """A candidate law with its overrides and variant options (:mod:`bayesfric.laws.variants`).

    ``name`` is the entry's label -- what fits, tables and ``weights.json`` call it (the law's
    name unless the entry gives ``label``); ``law`` is the registered law it is built from.
    """

    name: str
    priors: dict[str, Prior] = field(default_factory=dict)
    constants: dict[str, float] = field(default_factory=dict)
    law: str = ""
    fixed: dict[str, float] = field(default_factory=dict)
    add: tuple[str, ...] = ()
    asymmetric: tuple[str, ...] = ()
    metric: str | None = None  # this law's NUTS mass matrix, over [sampler] metric
    modules: tuple[str, ...] = ()  # the study's law files (absolute): loaded before the name is resolved

    def settings(self, study_settings: dict[str, Any]) -> dict[str, Any]:
        """The sampler settings this law runs with: the study's, with the entry's own metric."""
        return study_settings if self.metric is None else study_settings | {"metric": self.metric}

    def build(self) -> Law:
        """The entry's law: the registered law with its options applied, named by the label.

        The study's law files are loaded first (once per process), so this works in any process:
        a ``main --jobs`` study process, a Dask worker."""
        load_modules(self.modules)
        return vary(get_law(self.law or self.name), name=self.name, add=self.add, asymmetric=self.asymmetric,
                    fixed=self.constants | self.fixed)


@dataclass(frozen=True)
class BlockedSpec:
    """A blocked extrapolation fold along an operating input."""

    axis: str
    direction: str = "upper"
    threshold: float | None = None
    quantile: float | None = None
    label: str = ""
    future: bool = False  # leave-future-out: split inside each trajectory (compare.folds)

    def describe(self) -> str:
        cut = f"{self.threshold:g}" if self.threshold is not None else f"q{self.quantile:g}"
        arrow = "train ≤ cut, score above" if self.direction == "upper" else "train ≥ cut, score below"
        if self.future:
            arrow = "each trajectory's past trains, its future beyond the cut is scored"
        return self.label or f"{self.axis} {cut} ({arrow})"


@dataclass
class Study:
    """A validated study (``sampler``: every setting of the chosen sampler, defaults filled)."""

    path: Path
    name: str
    title: str
    question: str
    dataset: str
    select: dict[str, Any]
    noise: Noise
    sampler: dict[str, Any]
    laws: list[LawSpec]
    loo: bool = True
    kfold: int = 0
    grouped: str | None = None
    evidence: bool = True
    smc: bool = False  # opt-in reference: tempered SMC costs 3-13x the fit (bench_evidence.py)
    smc_particles: int = 300  # tempered SMC: within ~0.1 nat of bridge sampling at ~1/5 the cost of 1000
    smc_runs: int = 3
    blocked: list[BlockedSpec] = field(default_factory=list)
    include_failed: bool = False
    failed_fits: str = "skip"  # a law whose full fit failed the gate: "skip" its CV and evidence, or "run" them
    sizing: list[SizingQuestion] = field(default_factory=list)
    claims: list[Claim] = field(default_factory=list)
    raw: dict[str, Any] = field(default_factory=dict)


# -- the schema ----------------------------------------------------------------------------------
def _backend(key: str):
    """Default of a sampler setting: the chosen backend's own keyword default."""
    return lambda section: inspect.signature(SAMPLERS[section["name"]]).parameters[key].default


def _known_law(name: str) -> str | None:
    try:
        get_law(name)
    except KeyError as exc:
        return str(exc.args[0])
    return None


def _files(value: Any) -> str | None:
    ok = isinstance(value, list) and all(isinstance(v, str) and v.strip() for v in value)
    return None if ok else "must be a list of law file paths (.py, relative to the study file)"


def _law_modules(path: Path, raw: dict[str, Any]) -> tuple[str, ...]:
    """Load the study's ``[study] modules`` (before the schema: ``[[laws]]`` may name their laws)."""
    section = raw.get("study")
    value = section.get("modules", []) if isinstance(section, dict) else []
    if problem := _files(value):
        raise StudyError(f"{path}: [study] modules: {problem}")
    files = tuple(str((path.parent / v).absolute()) for v in value)
    for i, (given, file) in enumerate(zip(value, files, strict=True)):
        try:
            load_module(file, label=given)
        except LawModuleError as exc:
            raise StudyError(f"{path}: [study] modules[{i}]: {exc}") from None
    return files


def _kfold(k: int) -> str | None:
    return None if k == 0 or k >= 2 else f"must be 0 (off) or ≥ 2, got integer {k}"


NUTS, EMCEE = ("nuts",), ("emcee",)

STUDY = Schema((
    Field("name", "name", None, doc="report folder name (default: the study file's name)"),
    Field("title", "text", None, doc="report title (default: the name)"),
    Field("question", "text", "", doc="the question the study asks"),
    Field("modules", "value", [], rule=_files, doc="law files (.py, relative to the study file) whose laws "
                                                   "[[laws]] may name (bayesfric.laws.plugins)"),
))
DATA = Schema((
    Field("dataset", "str", REQUIRED, doc="built-in data set or CSV path relative to the study file"),
    Field("select", "table", {}, items="value", doc="rows whose coordinates equal these values"),
))
NOISE = Schema((
    Field("kind", "str", "normal", choices=get_args(get_type_hints(Noise)["kind"]),
          doc="observation noise model"),
    Field("group", "str", None, doc="group coordinate of partial-pooled offsets"),
))
SAMPLER = Schema((
    Field("name", "str", "nuts", choices=tuple(SAMPLERS), doc="sampling backend"),
    Field("seed", "int", 0, min=0, max=2**32 - 1, doc="seed of every random draw"),
    Field("draws", "int", _backend("draws"), min=1, doc="draws per chain (emcee: steps before thinning)"),
    Field("tune", "int", _backend("tune"), min=0, doc="warm-up draws (emcee: burn-in steps)"),
    Field("chains", "int", _backend("chains"), min=1, only=("name", NUTS), doc="NUTS chains"),
    Field("target_accept", "number", _backend("target_accept"), gt=0, lt=1, only=("name", NUTS),
          doc="NUTS target acceptance probability"),
    Field("retry_target_accept", "number", _backend("retry_target_accept"), min=0, lt=1, only=("name", NUTS),
          doc="draws with divergent transitions are sampled again at this target acceptance "
              "(above target_accept); 0 switches the retry off"),
    Field("metric", "str", _backend("metric"), choices=METRICS, only=("name", NUTS),
          doc="mass matrix of the warm-up: diagonal, or dense for strongly correlated coefficients"),
    Field("init", "str", _backend("init"), choices=INITS, only=("name", NUTS),
          doc="chain starts: prior medians, or multi-path Pathfinder draws (posteriors with minor modes)"),
    Field("walkers", "int", _backend("walkers"), min=2, only=("name", EMCEE),
          doc="emcee walkers: at least 2 × free parameters (default max(32, 4 × free parameters))"),
    Field("thin", "int", _backend("thin"), min=1, only=("name", EMCEE), doc="emcee thinning"),
), only_label="sampler")
def _names(value: Any) -> str | None:
    items = value if isinstance(value, list) else [value]
    return None if all(isinstance(v, str) and v.strip() for v in items) else "must be a name or a list of names"


LAW = Schema((
    Field("name", "str", REQUIRED, rule=_known_law, doc="registered law (bayesfric laws --names)"),
    Field("label", "name", None, doc="name of this entry in reports and fit files (default: the law's name); "
                                     "required to list one law twice"),
    Field("priors", "table", {}, items="table", doc="prior overrides by parameter name"),
    Field("constants", "table", {}, items="number", doc="constant overrides by name"),
    Field("fixed", "table", {}, items="number", doc="parameters (or constants) held at a value, SI units"),
    Field("add", "value", [], rule=_names, doc='additive parts: "offset", "viscous" or registered laws'),
    Field("offset", "bool", False, doc='add a constant offset term (same as add = ["offset"])'),
    Field("asymmetric", "value", [], rule=_names,
          doc="parameters with one value per direction: <p>_pos (velocity ≥ 0), <p>_neg (velocity < 0)"),
    Field("metric", "str", None, choices=METRICS,
          doc="NUTS mass matrix of this law, over [sampler] metric (dense for strongly correlated coefficients)"),
))
BLOCKED = Schema((
    Field("axis", "str", REQUIRED, doc="input coordinate to block along"),
    Field("direction", "str", "upper", choices=("upper", "lower"), doc="upper: train below, score above"),
    Field("threshold", "number", None, doc="cut in SI units"),
    Field("quantile", "number", None, gt=0, lt=1, doc="cut as a quantile of the axis"),
    Field("label", "text", "", doc="label in reports"),
    Field("future", "bool", False, doc="leave-future-out: split each trajectory at the cut, train on its past"),
), exactly_one=(("threshold", "quantile"),))
COMPARE = Schema((
    Field("loo", "bool", True, doc="PSIS-LOO"),
    Field("kfold", "int", 0, min=0, rule=_kfold, doc="random K-fold folds (0: off)"),
    Field("grouped", "str", None, doc="leave-one-group-out coordinate"),
    Field("evidence", "bool", True, doc="bridge sampling + Laplace-t importance sampling"),
    Field("smc", "bool", False, doc="tempered SMC reference estimator (opt-in: 3-13x the fit)"),
    Field("smc_particles", "int", 300, min=20, doc="SMC particles per run"),
    Field("smc_runs", "int", 3, min=2, doc="independent SMC runs"),
    Field("include_failed", "bool", False, doc="weight fits that failed the gate"),
    Field("failed_fits", "str", "skip", choices=("skip", "run"),
          doc="a law whose full fit failed the gate: skip its CV refits and evidence, or run them anyway"),
    Field("blocked", "tables", [], schema=BLOCKED, doc="blocked extrapolation folds"),
))
SIZING = Schema((
    Field("label", "text", "", doc="label in reports (default: the point)"),
    Field("at", "table", REQUIRED, items="value",
          doc='input -> "<value> <unit>" or "<low>..<high> <unit>"; every input the laws read'),
    Field("confidence", "number", 0.99, gt=0, lt=1, doc="size for this quantile of |T| with noise"),
    Field("capacity", "str", None, doc="available drive torque or force, with its unit"),
    Field("energy_rotation", "str", None, doc="angle of one rotation whose friction energy is asked (torque)"),
))
def _claimed_range(value) -> str | None:
    ok = isinstance(value, list) and len(value) == 2 and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    return None if ok and value[0] <= value[1] else "must be [low, high]: two numbers, low ≤ high"


CLAIM = Schema((
    Field("text", "str", REQUIRED, doc="the claim, as the paper states it"),
    Field("source", "str", REQUIRED, doc="where the paper states it (seed, section, figure)"),
    Field("kind", "str", REQUIRED, choices=CLAIM_KINDS, doc="ratio | parameter | score | best"),
    Field("law", "str", REQUIRED, doc="the candidate (its label) the claim is about (best: the claimed winner)"),
    Field("expect", "value", None, rule=_claimed_range, doc="claimed range [low, high] (not for best)"),
    Field("at", "table", {}, items="value", doc='ratio: numerator point, input -> "<value> <unit>"'),
    Field("minus", "table", {}, items="value", doc="ratio: subtract the law at this point (a chord)"),
    Field("fixed", "table", {}, items="number", doc="ratio: numerator parameters/constants fixed (SI)"),
    Field("reference", "str", None, doc="ratio: denominator law (default: law); score: subtract its score"),
    Field("reference_at", "table", {}, items="value", doc="ratio: denominator point (default: at)"),
    Field("reference_minus", "table", {}, items="value", doc="ratio: denominator chord start (default: minus)"),
    Field("parameter", "str", None, doc="parameter: the law's parameter"),
    Field("metric", "str", None, doc="score, best: a metric of bayesfric.study.scores.METRICS"),
    Field("scheme", "text", "", doc="score, best: CV scheme label or evidence estimator ('' for LOO)"),
    Field("basis", "str", None, choices=CLAIM_BASES,
          doc='"pipeline check": the number was used to build the data (reconstructed data); "evidence": it was '
              'not. Required on reconstructed data'),
))
FILE = Schema((
    Field("study", "table", {}, schema=STUDY),
    Field("data", "table", REQUIRED, schema=DATA),
    Field("noise", "table", {}, schema=NOISE),
    Field("sampler", "table", {}, schema=SAMPLER),
    Field("laws", "tables", REQUIRED, min=1, schema=LAW),
    Field("compare", "table", {}, schema=COMPARE),
    Field("sizing", "tables", [], schema=SIZING, doc="actuator sizing questions"),
    Field("claims", "tables", [], schema=CLAIM, doc="claims of the source paper checked against the posterior"),
))


# -- sampler helpers shared with the CLI ---------------------------------------------------------
def sampler_settings(section: dict[str, Any]) -> dict[str, Any]:
    """Backend keyword arguments of a parsed ``[sampler]`` section (no name, seed or unset values)."""
    return {k: v for k, v in section.items() if k not in ("name", "seed") and v is not None}


def free_parameter_count(program: Program) -> int:
    """Number of free (sampled, unobserved) scalar parameters of a program."""
    trace = handlers.trace(handlers.seed(program.model, 0)).get_trace(**program.model_kwargs)
    return sum(int(np.size(s["value"])) for s in trace.values() if s["type"] == "sample" and not s["is_observed"])


def walkers_problem(program: Program, walkers: int | None) -> str | None:
    """Why ``walkers`` emcee walkers cannot sample ``program`` (None if they can, or if unset)."""
    if walkers is None:
        return None
    ndim = free_parameter_count(program)
    if walkers < 2 * ndim:
        return (f"emcee needs at least 2 × {ndim} = {2 * ndim} walkers for the {ndim} free parameters "
                f"of law {program.law.name!r}, got {walkers}")
    return None


# -- loading ---------------------------------------------------------------------------------------
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


def _listed(value: Any) -> tuple[str, ...]:
    return tuple(value) if isinstance(value, list) else (value,)


def _variant(where: str, entry: dict[str, Any]) -> Law:
    """The entry's law with its options, each checked in turn so an error names its key."""
    law = get_law(entry["name"])
    add = _listed(entry["add"]) + (("offset",) if entry["offset"] and "offset" not in _listed(entry["add"]) else ())
    for key, options in (("add", {"add": add}), ("asymmetric", {"asymmetric": _listed(entry["asymmetric"])}),
                         ("constants", {"fixed": entry["constants"]}), ("fixed", {"fixed": entry["fixed"]})):
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
    known = list(law.params) + list(noise.sites())
    priors = {}
    for pname, spec in entry["priors"].items():
        if pname not in known:
            raise StudyError(f"{where}.priors.{pname}: law {law.name!r} has no parameter {pname!r} "
                             f"(parameters: {', '.join(law.params)}; noise: {', '.join(noise.sites()) or 'none'})")
        try:
            priors[pname] = Prior.from_dict(spec)
        except PriorError as exc:  # exc.key: where inside the spec (scaled_by.response), if anywhere
            raise StudyError(f"{where}.{exc.within(f'priors.{pname}')}") from None
    add = _listed(entry["add"]) + (("offset",) if entry["offset"] and "offset" not in _listed(entry["add"]) else ())
    return LawSpec(entry["label"] or entry["name"], priors, dict(entry["constants"]), law=entry["name"],
                   fixed=dict(entry["fixed"]), add=add, asymmetric=_listed(entry["asymmetric"]),
                   metric=entry["metric"], modules=modules)


def _sizing_question(path: Path, i: int, entry: dict[str, Any]) -> SizingQuestion:
    """Data-independent checks of a parsed ``[[sizing]]`` entry: values, units, ranges, bounds."""
    try:
        return make_question(entry["at"], entry["confidence"], label=entry["label"], capacity=entry["capacity"],
                             energy_rotation=entry["energy_rotation"])
    except SizingError as exc:
        raise StudyError(f"{path}: sizing[{i}].{exc}") from None


def _claim(path: Path, i: int, entry: dict[str, Any], laws: dict[str, Law]) -> Claim:
    """Data-independent checks of a parsed ``[[claims]]`` entry against the study's candidates
    (``laws``: label -> law; :func:`bayesfric.study.claims.make_claim`)."""
    try:
        return make_claim(entry, laws)
    except ClaimError as exc:
        raise StudyError(f"{path}: claims[{i}].{exc}") from None


def retry_problem(sampler: dict[str, Any]) -> str | None:
    """Why a parsed ``[sampler]`` section's retry target cannot be used (None if it can)."""
    retry = sampler.get("retry_target_accept")
    if retry and retry <= sampler["target_accept"]:
        return f"must be above target_accept ({sampler['target_accept']}) or 0 (off), got {retry}"
    return None


def _check_retry(path: Path, sampler: dict[str, Any]) -> None:
    if problem := retry_problem(sampler):
        raise StudyError(f"{path}: [sampler] retry_target_accept: {problem}")


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
    laws = [_law_spec(path, i, entry, noise, modules) for i, entry in enumerate(spec["laws"])]
    names = [w.name for w in laws]
    for i, label in enumerate(names):
        if label in names[:i]:
            key = "label" if spec["laws"][i]["label"] else "name"
            raise StudyError(f"{path}: laws[{i}].{key}: {label!r} is listed twice: give each entry of the "
                             "same law its own label")
    _check_retry(path, spec["sampler"])
    for i, entry in enumerate(spec["laws"]):
        if entry["metric"] is not None and spec["sampler"]["name"] not in NUTS:
            raise StudyError(f"{path}: laws[{i}].metric: applies only to sampler {NUTS[0]} "
                             f"(here {spec['sampler']['name']!r})")
    if compare["evidence"]:
        _check_evidence_draws(path, spec["sampler"])
    blocked = [BlockedSpec(b["axis"], b["direction"], b["threshold"], b["quantile"], b["label"], b["future"])
               for b in compare["blocked"]]
    sizing = [_sizing_question(path, i, entry) for i, entry in enumerate(spec["sizing"])]
    built = {w.name: w.build() for w in laws} if spec["claims"] else {}
    claims = [_claim(path, i, entry, built) for i, entry in enumerate(spec["claims"])]
    return Study(
        path=path, name=name, title=meta["title"] if meta["title"] is not None else name,
        question=meta["question"], dataset=dataset, select=data["select"], noise=noise,
        sampler=spec["sampler"], laws=laws, loo=compare["loo"], kfold=compare["kfold"],
        grouped=compare["grouped"], evidence=compare["evidence"], smc=compare["smc"],
        smc_particles=compare["smc_particles"],
        smc_runs=compare["smc_runs"], blocked=blocked, include_failed=compare["include_failed"],
        failed_fits=compare["failed_fits"], sizing=sizing, claims=claims, raw=raw,
    )
