"""What a study run produces, as plain data: per-law results and the ranking table."""

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
    findings: list[str] = field(default_factory=list)
    ranking_sensitivity: str = ""
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)
    sizing: Any = None  # bayesfric.sizing.SizingResult when the study asks sizing questions

    def winner(self, key: str) -> str | None:
        """Best reliable law by ``"loo"``, a CV scheme label, or an evidence estimator."""
        best, best_value = None, -math.inf
        for w in self.laws:
            if not w.reliable and not self.study.include_failed:
                continue
            if key == "loo":
                value = w.loo.value
            elif key in w.cv:
                value = w.cv[key].value if w.cv_reliable.get(key, True) else math.nan
            elif w.evidence_agree:
                value = w.evidence.get(key, Estimate()).value
            else:
                value = math.nan  # estimators disagree: listed in the findings, never ranked
            if math.isfinite(value) and value > best_value:
                best, best_value = w.name, value
        return best

    def passed_over(self, key: str) -> list[str]:
        """Laws that score above :meth:`winner` under ``key`` but are not ranked: their fit or a
        fold of the scheme failed the diagnostics gate (the findings name them)."""
        winner = self.winner(key)
        if winner is None:
            return []

        def score(w) -> float:
            if key == "loo":
                return w.loo.value
            if key in w.cv:
                return w.cv[key].value
            return w.evidence.get(key, Estimate()).value

        top = score(next(w for w in self.laws if w.name == winner))
        return [w.name for w in self.laws if w.name != winner and math.isfinite(score(w)) and score(w) > top]
