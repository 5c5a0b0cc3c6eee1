"""The claims of a study file as a specification: a parsed ``[[claims]]`` entry (:class:`Claim`),
its data-independent checks (:func:`make_claim`) and its checks against the study
(:func:`check_claim`, :func:`basis_problem`). What the vocabulary means and how a claim is checked
against the posterior: :mod:`bayesfric.study.claims`, which re-exports these names.

Split from the evaluation so that the study's types (:class:`bayesfric.study.spec.Study` holds
its claims) sit below the law × metric table and the result tree, which the evaluation reads.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from bayesfric.errors import UserError
from bayesfric.laws import Law, get_law
from bayesfric.sizing.points import SizingError, parse_value
from bayesfric.study.metrics import METRICS

__all__ = ["KINDS", "BASES", "Claim", "ClaimError", "ClaimResult", "make_claim", "check_claim", "basis_problem"]

KINDS = ("ratio", "parameter", "score", "best")
#: ``basis`` values: whether the claim's number was used to build the data (a pipeline check) or not.
BASES = ("evidence", "pipeline check")


class ClaimError(UserError):
    """A claim that cannot be checked: ``key`` (relative to ``claims[i]``) and a one-line problem."""

    def __init__(self, key: str, problem: str):
        super().__init__(problem, key)


@dataclass(frozen=True)
class Claim:
    """A parsed ``[[claims]]`` entry (points in SI units; ``basis`` None: not declared)."""

    text: str
    source: str
    kind: str
    law: str
    expect: tuple[float, float]
    at: dict[str, float] = field(default_factory=dict)
    minus: dict[str, float] = field(default_factory=dict)
    fixed: dict[str, float] = field(default_factory=dict)
    reference: str = ""
    reference_at: dict[str, float] = field(default_factory=dict)
    reference_minus: dict[str, float] = field(default_factory=dict)
    parameter: str = ""
    metric: str = ""
    scheme: str = ""
    basis: str | None = None

    @property
    def pipeline_check(self) -> bool:
        """The claim's number was used to build the data: a verdict checks the pipeline, not the paper."""
        return self.basis == "pipeline check"

    @property
    def basis_label(self) -> str:
        """How the reports mark the claim."""
        return "pipeline check, not evidence" if self.pipeline_check else "evidence"


def _points(table: Mapping[str, Any], key: str) -> dict[str, float]:
    out = {}
    for name, text in table.items():
        try:
            value = parse_value(text, name, key=f"{key}.{name}", allow_range=False)
        except SizingError as exc:
            raise ClaimError(exc.key, exc.problem) from None
        out[name] = float(value.lo)
    return out


def _law(name: str, key: str, laws: Mapping[str, Law] | None) -> Law:
    """The study's entry labelled ``name`` (a variant, perhaps), else the registered law."""
    if laws is not None and name in laws:
        return laws[name]
    try:
        return get_law(name)
    except KeyError as exc:
        known = f" (candidates of the study: {', '.join(laws)})" if laws is not None else ""
        raise ClaimError(key, f"{exc.args[0]}{known}") from None


_NEEDS = {"ratio": ("law", "at"), "parameter": ("law", "parameter"), "score": ("law", "metric"),
          "best": ("law", "metric")}
_ALLOWED = {"ratio": {"at", "minus", "fixed", "reference", "reference_at", "reference_minus"},
            "parameter": {"parameter"}, "score": {"metric", "scheme", "reference"}, "best": {"metric", "scheme"}}
_KIND_KEYS = ("at", "minus", "fixed", "reference", "reference_at", "reference_minus", "parameter", "metric", "scheme")


def _check_keys(entry: Mapping[str, Any]) -> None:
    """Keys required for the entry's kind, keys of another kind, the claimed range, the basis."""
    kind = entry["kind"]
    for key in _NEEDS[kind]:
        if not entry.get(key):
            raise ClaimError(key, f"is required for kind {kind!r}")
    allowed = _ALLOWED[kind]
    for key in _KIND_KEYS:
        if entry.get(key) and key not in allowed:
            raise ClaimError(key, f"does not apply to kind {kind!r} (keys of {kind!r}: {', '.join(sorted(allowed))})")
    expect = entry.get("expect")
    if kind != "best" and (expect is None or len(expect) != 2 or not expect[0] <= expect[1]):
        raise ClaimError("expect", f"kind {kind!r} needs the claimed range as [low, high] with low ≤ high, "
                                   f"got {expect!r}")
    if entry.get("basis") is not None and entry["basis"] not in BASES:
        raise ClaimError("basis", f"must be one of {', '.join(repr(b) for b in BASES)}, got {entry['basis']!r}")


def make_claim(entry: Mapping[str, Any], laws: Mapping[str, Law] | None = None) -> Claim:
    """A :class:`Claim` from a schema-parsed entry; data-independent checks of its keys.

    Parameters
    ----------
    entry : mapping
        The parsed ``[[claims]]`` entry.
    laws : mapping, optional
        The study's candidates by label (variants built); without it, ``law`` and ``reference``
        are registered laws.

    Raises
    ------
    ClaimError
        A key missing for the kind or given for another kind, an unknown law or parameter, a
        reversed ``expect`` range, a point that cannot be read, an unknown basis.
    """
    _check_keys(entry)
    kind, expect = entry["kind"], entry.get("expect")
    law = _law(entry["law"], "law", laws)
    reference = _law(entry["reference"], "reference", laws).name if entry.get("reference") else ""
    sites = (list(law.params) + [f"{p}_sd" for p in law.varying]  # a group term's spread, a trend's slope
             + ([f"{p}_trend" for p in law.trending] if law.trend_form != "walk" else []))
    if kind == "parameter" and entry["parameter"] not in sites:
        raise ClaimError("parameter", f"law {law.name!r} has no parameter {entry['parameter']!r} "
                                      f"(parameters: {', '.join(sites)})")
    if entry.get("metric") and entry["metric"] not in METRICS:
        raise ClaimError("metric", f"unknown metric {entry['metric']!r} (metrics: {', '.join(METRICS)})")
    for name in entry.get("fixed") or {}:
        if name not in law.params and name not in law.constants:
            raise ClaimError(f"fixed.{name}", f"law {law.name!r} has no parameter or constant {name!r}")
    at = _points(entry.get("at") or {}, "at")
    minus = _points(entry.get("minus") or {}, "minus")
    return Claim(
        text=entry["text"], source=entry["source"], kind=kind, law=law.name,
        expect=(float(expect[0]), float(expect[1])) if expect is not None else (math.nan, math.nan),
        at=at, minus=minus, fixed={k: float(v) for k, v in (entry.get("fixed") or {}).items()},
        reference=reference,
        reference_at=_points(entry.get("reference_at") or {}, "reference_at") or at,
        reference_minus=_points(entry.get("reference_minus") or {}, "reference_minus") or minus,
        parameter=entry.get("parameter") or "", metric=entry.get("metric") or "", scheme=entry.get("scheme") or "",
        basis=entry.get("basis"),
    )


def check_claim(claim: Claim, laws: Mapping[str, Law], schemes: list[str], estimators: list[str]) -> None:
    """Checks of a claim against the study: its laws are candidates (``laws``: label -> law as
    built for the study), its points give every input the laws read, its scheme exists.

    Raises
    ------
    ClaimError
    """
    for key, name in (("law", claim.law), ("reference", claim.reference)):
        if name and name not in laws:
            raise ClaimError(key, f"{name!r} is not a candidate law of the study ({', '.join(laws)})")
    if claim.kind == "ratio":
        for key, name in (("law", claim.law), ("reference", claim.reference)):
            if name and laws[name].trajectory:
                raise ClaimError(key, f"law {name!r} is a trajectory (stateful) law: it has no value at a point")
        for key, name, points in (("at", claim.law, claim.at), ("minus", claim.law, claim.minus),
                                  ("reference_at", claim.reference or claim.law, claim.reference_at),
                                  ("reference_minus", claim.reference or claim.law, claim.reference_minus)):
            if key.endswith("minus") and not points:
                continue
            missing = [q for q in laws[name].operating_inputs if q not in points]
            if missing:
                raise ClaimError(key, f"law {name!r} reads {', '.join(missing)}; give it in {key}")
    if claim.metric:
        known = {"elpd_loo": [""], "elpd_cv": schemes, "penalty": schemes, "log_evidence": estimators,
                 "weight": None}[claim.metric]
        if known is not None and claim.scheme not in known:
            raise ClaimError("scheme", f"{claim.scheme!r} is not a scheme of metric {claim.metric!r} in this study "
                                       f"({', '.join(repr(k) for k in known) or 'none'})")


def basis_problem(claim: Claim, provenance: str) -> str | None:
    """Why a claim cannot stand on data of this ``provenance`` (None if it can): on RECONSTRUCTED
    data, calibrated to the paper's own statements, every claim must say whether its number was
    used to build the data."""
    if provenance == "reconstructed" and claim.basis is None:
        return ("the data set is RECONSTRUCTED from the paper: say whether this claim's number was used to build "
                "it (basis = \"pipeline check\": a verdict checks the pipeline, not the paper) or not "
                "(basis = \"evidence\"); its README lists the facts used")
    return None


@dataclass(frozen=True)
class ClaimResult:
    """A claim with what the posterior says: ``value`` (median or estimate), ``lo``/``hi`` (90 %
    interval, or ± one standard error for scores), ``winner`` for ``best``, the verdict and why."""

    claim: Claim
    verdict: str
    value: float = math.nan
    lo: float = math.nan
    hi: float = math.nan
    winner: str = ""
    why: str = ""
