"""The metrics a study scores laws by, and its ranking criteria: plain types that the study file's
checks (:mod:`bayesfric.study.claimspec`), the law × metric table (:mod:`bayesfric.study.scores`,
which re-exports them) and the report share, below all of them."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["METRICS", "Criterion"]

#: metric -> (display name, higher is better, unit)
METRICS = {
    "elpd_loo": ("elpd PSIS-LOO", True, "nats"),
    "elpd_cv": ("elpd", True, "nats"),
    "penalty": ("extrapolation penalty", False, "nats per held-out point"),
    "log_evidence": ("log evidence", True, "nats"),
    "weight": ("weight", True, "1"),
}


@dataclass(frozen=True)
class Criterion:
    """A ranking criterion of the study: a metric under a scheme, with how to read it."""

    metric: str
    scheme: str
    kind: str  # "interpolation", "extrapolation", "cross-validation", "evidence"

    @property
    def label(self) -> str:
        name = METRICS[self.metric][0]
        return f"{name} {self.scheme}".strip() if self.metric != "elpd_loo" else name
