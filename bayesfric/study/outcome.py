"""What a study run produces, as plain data: per-law results; the law × metric table of scores is
derived from them once (:mod:`bayesfric.study.scores`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr

from bayesfric.inference.diagnostics import Verdict
from bayesfric.laws.base import Law
from bayesfric.study.spec import Study

if TYPE_CHECKING:  # annotations only (compare is below study: no cycle at any level)
    import pandas as pd

    from bayesfric.compare import CVResult, EstimatorAgreement, Evidence, LooResult, PitShape, RankingSensitivity

__all__ = ["Checks", "LawOutcome", "QuickRun", "StudyOutcome", "UnitSeconds", "Weight"]


@dataclass(frozen=True)
class Checks:
    """The checks unit of one law (:mod:`bayesfric.compare.checks`), as computed."""

    prior_implausible: float = math.nan  # fraction of prior draws with unphysical friction
    loo_pit_pvalue: float = math.nan  # KS p-value of the LOO-PIT values against uniform
    loo_pit_ok: bool = True  # False: the LOO-PIT ECDF leaves its simultaneous band (miscalibrated)
    ci_prob: float = 0.94  # coverage of that band
    psense: tuple[str, ...] = ()  # parameters power-scaling flags as prior- or likelihood-sensitive
    pit: np.ndarray | None = field(default=None, compare=False, repr=False)  # the LOO-PIT values
    pit_band: np.ndarray | None = field(default=None, compare=False, repr=False)  # (points, lower, upper) of the ECDF
    pit_shape: PitShape | None = None  # which way the PIT departs from uniform

    @property
    def prior_sensitivity(self) -> str:
        return ("psense flags " + ", ".join(self.psense) if self.psense
                else "no parameter flagged by power-scaling (psense)")


@dataclass(frozen=True)
class Weight:
    """A law's weight under one weighting, or why the weighting left it out (weight 0)."""

    value: float
    excluded: str = ""


@dataclass(frozen=True)
class LawOutcome:
    """What the study computed for one law: its fit and each scorer's result object, computed once.

    Every score, verdict and flag is read from these results (the law × metric table of
    :mod:`bayesfric.study.scores`, the report's flags); nothing is stored as text to be parsed back.
    The record is frozen: the runner adds study-level results (weights, timings) with
    :func:`dataclasses.replace`.
    """

    law: Law
    fit: xr.DataTree
    fit_file: Path
    verdict: Verdict
    loo: LooResult | None = None
    cv: Mapping[str, CVResult] = field(default_factory=dict)  # scheme label -> its result
    penalty: Mapping[str, float] = field(default_factory=dict)  # blocked label -> nats per held-out point
    penalty_se: Mapping[str, float] = field(default_factory=dict)  # blocked label -> its standard error
    evidence: Mapping[str, Evidence] = field(default_factory=dict)  # estimator -> its estimate
    agreement: EstimatorAgreement | None = None  # of bridge and importance
    checks: Checks | None = None
    weights: Mapping[str, Weight] = field(default_factory=dict)  # weighting -> weight
    skipped: tuple[str, ...] = ()  # stages not run: the full fit failed the gate
    failed_fits: str = "skip"  # the study's [compare] failed_fits, for the message about them
    timings: Mapping[str, float] = field(default_factory=dict)  # stage -> wall seconds computed in this run

    @property
    def name(self) -> str:
        return self.law.name

    @property
    def reliable(self) -> bool:
        return self.verdict.passed

    @property
    def seconds(self) -> float:
        return float(sum(self.timings.values()))

    @property
    def evidence_agree(self) -> bool:
        """False when the two estimators disagree: the law leaves the evidence ranking."""
        return self.agreement is None or self.agreement.agree

    @property
    def cv_reliable(self) -> bool:
        """Every fold of every cross-validation scheme passed the gate."""
        return all(cv.reliable for cv in self.cv.values())

    @property
    def loo_pit_ok(self) -> bool:
        return self.checks is None or self.checks.loo_pit_ok

    @property
    def flags(self) -> list[str]:
        """One line per problem found in this law's results, in the order the stages ran."""
        out = []
        if not self.verdict.passed:
            note = self.verdict.predictions_note
            out.append("diagnostics FAILED: " + "; ".join(self.verdict.problems) + (f" ({note})" if note else ""))
        if self.skipped:
            out.append(f"{', '.join(self.skipped)} skipped: the full fit failed the diagnostics gate "
                       f"([compare] failed_fits = \"{self.failed_fits}\"; \"run\" computes them anyway)")
        if self.loo is not None and not self.loo.reliable:
            why = "the full fit failed the gate" if not self.loo.fit_passed else self.loo.handling
            out.append(f"LOO unreliable ({why})")
        out += [f"{label}: {cv.failure}" for label, cv in self.cv.items() if not cv.reliable]  # scores.fold_failure
        if not self.evidence_agree:
            out.append(_disagreement(self.agreement))
        if self.checks is not None and not self.checks.loo_pit_ok:
            shape = self.checks.pit_shape
            p = self.checks.loo_pit_pvalue
            ks = "< 0.001" if p < 1e-3 else f"= {p:.2g}"
            out.append(f"LOO-PIT outside the {self.checks.ci_prob:.0%} band (KS p {ks}): miscalibrated"
                       + (f", {shape.label}" if shape is not None else ""))
        return out


def _disagreement(agreement: EstimatorAgreement) -> str:
    importance = agreement.b
    why = (f"importance weights heavy-tailed (Pareto k = {importance.diagnostics['pareto_k']:.2f})"
           if not importance.diagnostics.get("reliable", True) else f"> {agreement.threshold:.2f} nat")
    return f"evidence estimators disagree by {abs(agreement.difference):.2f} nat ({why}); not ranked by evidence"


@dataclass(frozen=True)
class QuickRun:
    """The settings a ``--quick`` run capped: the sampler's, and K-fold's (asked, used)."""

    settings: Mapping[str, Any]
    kfold: tuple[int, int]


@dataclass(frozen=True)
class UnitSeconds:
    """Seconds the units computed in this run took, and what the reused ones cost when computed
    (``unknown``: reused units stored without their seconds)."""

    computed: float
    reused: int
    saved: float
    unknown: int


@dataclass
class StudyOutcome:
    """The study, its data and every law's outcome, plus study-level results: what the result
    tree is built from (:func:`bayesfric.study.tree.study_tree`). The claims' results and the
    sizing result are not kept here: the runner evaluates them from the tree and passes them to
    the report."""

    study: Study
    data: xr.Dataset
    laws: list[LawOutcome]
    schemes: list[str]  # CV scheme labels in display order
    blocked: list[str]  # the blocked-extrapolation labels among them
    heldout: dict[str, np.ndarray] = field(default_factory=dict)
    sensitivity: RankingSensitivity | None = None  # the LOO ranking under power-scaled priors (two or more fits)
    weight_errors: list[tuple[str, str]] = field(default_factory=list)  # (weighting, why it was not computed)
    quick: QuickRun | None = None  # the capped settings of a --quick run
    table: pd.DataFrame | None = None  # the law × metric table (bayesfric.study.scores.score_table), computed once
