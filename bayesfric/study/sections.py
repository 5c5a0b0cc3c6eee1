"""The schema of a study file, one table per section: :data:`STUDY`, :data:`DATA`, :data:`NOISE`,
:data:`SAMPLER`, :data:`LAW` (``[[laws]]``), :data:`COMPARE` with :data:`BLOCKED`, :data:`SIZING`,
:data:`CLAIM`, and :data:`FILE` over them all. :func:`bayesfric.study.schema.parse` derives
validation, defaults and messages from them; the file format is described in
:mod:`bayesfric.study.config`, which re-exports these tables. :data:`SAMPLER` is built from the
sampler configuration's rules and defaults (:data:`bayesfric.inference.config.RULES`,
:class:`~bayesfric.inference.config.SamplerConfig`), which the ``fit`` command and
``bayesfric.fit`` check their settings against.
"""

from __future__ import annotations

from typing import Any, get_args, get_type_hints

from bayesfric.datasets.rows import MAX_LEVELS
from bayesfric.inference.config import METRICS, RULES, default_of
from bayesfric.laws import get_law
from bayesfric.model import Noise
from bayesfric.study.claimspec import BASES, KINDS
from bayesfric.study.schema import REQUIRED, Field, Schema

__all__ = ["STUDY", "DATA", "NOISE", "SAMPLER", "LAW", "BLOCKED", "COMPARE", "SIZING", "CLAIM", "FILE", "NUTS", "EMCEE",
           "law_files_problem"]


def _sampler_field(key: str) -> Field:
    """The ``[sampler]`` field of a setting: its rule, and its default under the chosen backend."""
    rule = RULES[key]
    default = {"name": "nuts", "seed": 0}.get(key, lambda section: default_of(section["name"], key))
    return Field(key, rule.kind, default, min=rule.min, max=rule.max, gt=rule.gt, lt=rule.lt, choices=rule.choices,
                 only=("name", rule.only) if rule.only else None, doc=rule.doc)


def _known_law(name: str) -> str | None:
    try:
        get_law(name)
    except KeyError as exc:
        return str(exc.args[0])
    return None


def law_files_problem(value: Any) -> str | None:
    """Why ``value`` is not a list of law files for ``[study] modules`` (None if it is)."""
    ok = isinstance(value, list) and all(isinstance(v, str) and v.strip() for v in value)
    return None if ok else "must be a list of law file paths (.py, relative to the study file)"


def _kfold(k: int) -> str | None:
    return None if k == 0 or k >= 2 else f"must be 0 (off) or ≥ 2, got integer {k}"


NUTS, EMCEE = ("nuts",), ("emcee",)

STUDY = Schema((
    Field("name", "name", None, doc="report folder name (default: the study file's name)"),
    Field("title", "text", None, doc="report title (default: the name)"),
    Field("question", "text", "", doc="the question the study asks"),
    Field("modules", "value", [], rule=law_files_problem, doc="law files (.py, relative to the study file) whose laws "
                                                   "[[laws]] may name (bayesfric.laws.plugins)"),
))
DATA = Schema((
    Field("dataset", "str", REQUIRED, doc="built-in data set or CSV path relative to the study file"),
    Field("select", "table", {}, items="value", doc="rows whose coordinates equal these values"),
    Field("every", "int", 1, min=1, doc="keep every n-th row (of each trajectory, its first row kept): thins a "
                                        "large log"),
    Field("max_levels", "int", MAX_LEVELS, min=1,
          doc="most levels a group column (vary_by, trend, grouped or forecast folds, [noise] group) may have; "
              "raise it to confirm that many leave-one-group-out refits"),
))
NOISE = Schema((
    Field("kind", "str", "normal", choices=get_args(get_type_hints(Noise)["kind"]),
          doc="observation noise model"),
    Field("group", "str", None, doc="group coordinate of partial-pooled offsets"),
))
SAMPLER = Schema(tuple(_sampler_field(key) for key in RULES), only_label="sampler")


def _names(value: Any) -> str | None:
    items = value if isinstance(value, list) else [value]
    return None if all(isinstance(v, str) and v.strip() for v in items) else "must be a name or a list of names"


def _threshold_problem(value: Any) -> str | None:
    """A blocked cut: a number (SI), a text with its unit, or (from Python) ``(number, unit)``."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    pair = isinstance(value, list) and len(value) == 2 and isinstance(value[1], str) \
        and isinstance(value[0], int | float) and not isinstance(value[0], bool)
    if number or pair or (isinstance(value, str) and value.strip()):
        return None
    return 'must be a number in SI units or a text with its unit ("0.5 rad/s")'


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
    Field("vary_by", "table", {}, items="value", rule=lambda t: next(
              (f"{k}: {problem}" for k, v in t.items() if (problem := _names(v))), None),
          doc="group terms: column -> parameters that vary between its levels, partially pooled "
              '(e.g. { run = ["T_C", "c_v"] }); answers are then for a new level'),
    Field("trend", "table", {}, items="value", rule=lambda t: next(
              (f"{k}: {problem}" for k, v in t.items() if (problem := _names(v))), None),
          doc="trends over a service coordinate: column (one number per campaign: hours, cycles) -> parameters "
              'that follow a trend across campaigns, partially pooled about it (e.g. { hours = ["T_C"] })'),
    Field("trend_form", "str", None, choices=("linear", "loglinear", "walk"),
          doc="the trends' form: linear (default), loglinear or walk (random walk; bayesfric.trend)"),
    Field("metric", "str", None, choices=METRICS,
          doc="NUTS mass matrix of this law, over [sampler] metric (dense for strongly correlated coefficients)"),
))
BLOCKED = Schema((
    Field("axis", "str", REQUIRED, doc="input coordinate to block along"),
    Field("direction", "str", "upper", choices=("upper", "lower"), doc="upper: train below, score above"),
    Field("threshold", "value", None, rule=lambda v: _threshold_problem(v),
          doc='cut: a number in SI units, or with its unit ("0.5 rad/s", "300 rpm")'),
    Field("quantile", "number", None, gt=0, lt=1, doc="cut as a quantile of the axis"),
    Field("label", "text", "", doc="label in reports"),
    Field("future", "bool", False, doc="leave-future-out: split each trajectory at the cut, train on its past"),
), exactly_one=(("threshold", "quantile"),))
COMPARE = Schema((
    Field("loo", "bool", True, doc="PSIS-LOO"),
    Field("kfold", "int", 0, min=0, rule=_kfold, doc="random K-fold folds (0: off)"),
    Field("grouped", "str", None, doc="leave-one-group-out coordinate"),
    Field("forecast", "str", None, doc="leave-future-out over campaigns: the service-coordinate column (hours)"),
    Field("forecast_first", "int", 2, min=1, doc="campaigns only trained on before the first forecast"),
    Field("evidence", "bool", True, doc="bridge sampling + Laplace-t importance sampling"),
    Field("smc", "bool", False, doc="tempered SMC reference estimator (opt-in: 3-13x the fit)"),
    Field("smc_particles", "int", 300, min=20, doc="SMC particles per run"),
    Field("smc_runs", "int", 3, min=2, doc="independent SMC runs"),
    Field("include_failed", "bool", False, doc="weight fits that failed the gate"),
    Field("failed_fits", "str", "skip", choices=("skip", "run"),
          doc="a law whose full fit failed the gate: skip its CV refits, LOO refits and evidence, or run them "
              "anyway"),
    Field("companions", "bool", True,
          doc="add a stateful law's reduced variant (e.g. LuGre with F_s = F_c) as a companion entry where the "
              "data do not identify the full law (bayesfric.identifiability)"),
    Field("blocked", "tables", [], schema=BLOCKED, doc="blocked extrapolation folds"),
))
SIZING = Schema((
    Field("label", "text", "", doc="label in reports (default: the point)"),
    Field("at", "table", REQUIRED, items="value",
          doc='input -> "<value> <unit>" or "<low>..<high> <unit>"; every input the laws read'),
    Field("confidence", "number", 0.99, gt=0, lt=1, doc="size for this quantile of |T| with noise"),
    Field("capacity", "str", None, doc="available drive torque or force, with its unit"),
    Field("energy_rotation", "str", None, doc="angle of one rotation whose friction energy is asked (torque)"),
    Field("horizon", "str", None, doc='time to exceed the capacity, forecast up to this service time ("20000 h"; '
                                      "laws with a trend)"),
))


def _claimed_range(value) -> str | None:
    ok = isinstance(value, list) and len(value) == 2 and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    return None if ok and value[0] <= value[1] else "must be [low, high]: two numbers, low ≤ high"


CLAIM = Schema((
    Field("text", "str", REQUIRED, doc="the claim, as the paper states it"),
    Field("source", "str", REQUIRED, doc="where the paper states it (seed, section, figure)"),
    Field("kind", "str", REQUIRED, choices=KINDS, doc="ratio | parameter | score | best"),
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
    Field("basis", "str", None, choices=BASES,
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
