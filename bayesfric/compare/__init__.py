"""Model comparison: PSIS-LOO, cross-validation with refits (random, grouped, blocked along the
operating envelope), log evidence from two estimators, weights and averaging, checks, recovery.

Layering follows arviz-stats' ``loo/``: fold masks (:mod:`folds`) -> compiled refits
(:mod:`refit`) -> elpd results (:mod:`loo`, :class:`CVResult`) -> weights (:mod:`weights`);
evidence (:mod:`evidence`), checks (:mod:`checks`) and the residual-structure tests
(:mod:`structure`) read a fit and its program.
"""

from bayesfric.compare.checks import (
    PitCheck,
    PlausibilityReport,
    RankingSensitivity,
    fit_prior_draws,
    loo_pit_check,
    power_scaled_loo,
    prior_predictive_check,
    prior_sensitivity,
    ranking_sensitivity,
)
from bayesfric.compare.evidence import (
    EstimatorAgreement,
    Evidence,
    bridge_log_evidence,
    compare_estimators,
    smc_log_evidence,
)
from bayesfric.compare.folds import Folds, blocked_masks, forecast_masks, grouped_masks, kfold_masks
from bayesfric.compare.importance import laplace_is_log_evidence
from bayesfric.compare.loo import LooResult, Penalty, extrapolation_penalty, psis_loo
from bayesfric.compare.pit import PitShape, pit_shape
from bayesfric.compare.recovery import RecoveryResult, model_recovery
from bayesfric.compare.refit import CVResult, RefitEngine, cross_validate
from bayesfric.compare.structure import StructureCheck, residual_structure, structure_dataset
from bayesfric.compare.weights import BayesFactors, Weights, averaged_predictive, bayes_factors, model_weights
from bayesfric.inference.diagnostics import verdict_of

__all__ = [
    "BayesFactors", "CVResult", "EstimatorAgreement", "Evidence", "Folds", "LooResult", "Penalty",
    "PitCheck", "PitShape", "PlausibilityReport", "RankingSensitivity", "RecoveryResult", "RefitEngine", "Weights",
    "averaged_predictive", "bayes_factors", "blocked_masks", "bridge_log_evidence", "compare_estimators",
    "cross_validate", "extrapolation_penalty", "forecast_masks", "grouped_masks", "kfold_masks",
    "laplace_is_log_evidence",
    "loo_pit_check", "model_recovery", "pit_shape",
    "model_weights", "power_scaled_loo", "prior_predictive_check", "fit_prior_draws", "prior_sensitivity", "psis_loo",
    "ranking_sensitivity", "smc_log_evidence", "verdict_of", "StructureCheck", "residual_structure",
    "structure_dataset",
]
