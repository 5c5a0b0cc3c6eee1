"""What a study run produces, as plain data: per-law results; the law × metric table of scores is
derived from them once (:mod:`bayesfric.study.scores`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from bayesfric.inference.diagnostics import Verdict
from bayesfric.laws.base import Law
from bayesfric.study.config import Study

__all__ = ["Estimate", "LawOutcome", "StudyOutcome"]


@dataclass(frozen=True)
class Estimate:
    """A number with its standard error (or Monte Carlo error); NaN when not computed."""

    value: float = math.nan
    error: float = math.nan

    def fmt(self, digits: int = 1) -> str:
        if not math.isfinite(self.value):
            return "–"
        return f"{self.value:.{digits}f} ± {self.error:.{digits}f}"


@dataclass
class LawOutcome:
    """Everything the study computed for one law."""

    law: Law
    fit: xr.DataTree
    fit_file: Path
    verdict: Verdict
    loo: Estimate = field(default_factory=Estimate)
    loo_pointwise: np.ndarray | None = None
    p_loo: float = math.nan
    pareto_k_max: float = math.nan
    n_high_k: int = 0
    high_k_handling: str = ""
    cv: dict[str, Estimate] = field(default_factory=dict)  # scheme label -> elpd ± se
    cv_pointwise: dict[str, np.ndarray] = field(default_factory=dict)
    cv_reliable: dict[str, bool] = field(default_factory=dict)
    penalty: dict[str, float] = field(default_factory=dict)  # blocked label -> nats per held-out point
    evidence: dict[str, Estimate] = field(default_factory=dict)  # estimator -> log Z ± MC error
    evidence_disagreement: float = math.nan
    evidence_agree: bool = True  # False: the two estimators disagree; the law leaves the evidence ranking
    weights: dict[str, float] = field(default_factory=dict)  # method -> weight
    weight_exclusions: dict[str, str] = field(default_factory=dict)  # method -> why the weighting left it out
    prior_implausible: float = math.nan  # fraction of prior draws with unphysical friction
    loo_pit_pvalue: float = math.nan
    loo_pit_ok: bool = True  # False: the LOO-PIT ECDF leaves its simultaneous band (miscalibrated)
    prior_sensitivity: str = ""
    flags: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)  # stages not run: the full fit failed the gate
    results: dict[str, Any] = field(default_factory=dict)  # "loo" / scheme label -> LooResult / CVResult
    timings: dict[str, float] = field(default_factory=dict)  # stage -> wall seconds computed in this run
    seconds: float = 0.0

    @property
    def name(self) -> str:
        return self.law.name

    @property
    def reliable(self) -> bool:
        return self.verdict.passed


@dataclass
class StudyOutcome:
    """The study, its data and every law's outcome, plus study-level findings."""

    study: Study
    data: xr.Dataset
    laws: list[LawOutcome]
    schemes: list[str]  # CV scheme labels in display order
    blocked: list[str]  # the blocked-extrapolation labels among them
    heldout: dict[str, np.ndarray] = field(default_factory=dict)
    findings: list[Any] = field(default_factory=list)  # bayesfric.report.findings.Finding
    ranking_sensitivity: str = ""
    ranking_changed: bool = False  # the LOO ranking changes under power-scaled priors
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)
    sizing: Any = None  # bayesfric.sizing.SizingResult when the study asks sizing questions
    table: Any = None  # the law × metric table (bayesfric.study.scores.score_table), computed once
    claims: list[Any] = field(default_factory=list)  # bayesfric.report.claims.ClaimResult per [[claims]] entry
