"""Model recovery: can the comparison methods tell the candidate laws apart on a given design?

For every candidate law, data sets are simulated on the design (the inputs of a planned or
existing test campaign) with parameters drawn from the law's priors -- redrawn while the prior
predictive plausibility check fails -- and Gaussian noise of a stated level. Every law is fitted
to every simulated set; each method (log evidence, PSIS-LOO, and optionally blocked
extrapolation CV) picks its best law; the confusion matrix true law × chosen law and the hit
rate (fraction of sets where the true law was chosen) are reported per method.

Simulation priors are resolved at a stated response scale (data-scaled priors need one before
any data exist); the fits then resolve their priors on each simulated set, exactly as a user's
fit would. A "miss" is not always a failure of the method: a law drawn with a negligible extra
term *is* its simpler neighbour on that design, and evidence rightly prefers the simpler one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import arviz as az
import jax
import numpy as np
import pandas as pd
import xarray as xr
from numpyro.infer import Predictive

from bayesfric.compare.checks import plausible_draws
from bayesfric.compare.evidence import bridge_log_evidence, smc_log_evidence
from bayesfric.datasets.synthetic import make_dataset, simulate
from bayesfric.errors import UserError
from bayesfric.inference import fit, release_compiled_code
from bayesfric.inference.pointwise import stored_draws
from bayesfric.laws.base import Law
from bayesfric.model import OBS_SITE, Noise, build_program
from bayesfric.priors import DataScale, Prior

__all__ = ["RecoveryResult", "draw_plausible_parameters", "model_recovery"]


@dataclass(frozen=True)
class RecoveryResult:
    """Confusion matrices (rows: true law, columns: chosen law) and hit rates per method."""

    laws: list[str]
    confusion: dict[str, np.ndarray]
    hit_rate: dict[str, float]
    records: list[dict[str, Any]] = field(default_factory=list)

    def table(self, method: str) -> pd.DataFrame:
        """The confusion matrix of ``method`` as a labelled table (counts)."""
        index = pd.Index(self.laws, name="true law")
        columns = pd.Index(self.laws, name="chosen law")
        return pd.DataFrame(self.confusion[method], index=index, columns=columns)

    def __str__(self) -> str:
        rates = ", ".join(f"{m}: {r:.0%}" for m, r in self.hit_rate.items())
        return f"model recovery over {len(self.records)} simulated sets; hit rate {rates}"


def draw_plausible_parameters(
    law: Law,
    design: Mapping[str, np.ndarray],
    scale: DataScale,
    *,
    priors: Mapping[str, Prior] | None = None,
    seed: int = 0,
    max_tries: int = 100,
) -> dict[str, np.ndarray]:
    """One parameter set of ``law`` from its priors (resolved at ``scale``) that passes
    :func:`bayesfric.compare.checks.plausible_draws` on the design.

    Raises
    ------
    RuntimeError
        No plausible draw among ``max_tries`` (the priors themselves are implausible).
    """
    n = len(next(iter(design.values())))
    template = make_dataset(design, np.zeros(n), response_quantity=law.response)
    program = build_program(law, template, priors=priors, scale=scale)
    draws = Predictive(program.model, num_samples=max_tries, return_sites=list(law.params))(
        jax.random.PRNGKey(seed), **dict(program.model_kwargs, response=None)
    )
    ok, _ = plausible_draws(program, draws, seed=seed)
    if not ok.any():
        raise RuntimeError(f"no plausible prior draw of law {law.name!r} in {max_tries} tries")
    first = int(np.argmax(ok))
    return {k: np.asarray(v[first]) for k, v in draws.items()}


def _scores(
    program_fit: xr.DataTree,
    law: Law,
    ds: xr.Dataset,
    method: str,
    *,
    fit_kwargs: dict,
    seed: int,
    blocked: Any,
) -> float:
    """Higher is better, for every method."""
    if method == "loo":
        return float(az.loo(stored_draws(program_fit, ("log_likelihood",)), var_name=OBS_SITE).elpd)
    program = build_program(law, ds, priors=fit_kwargs.get("priors"), noise=fit_kwargs.get("noise"))
    if method == "evidence":
        return bridge_log_evidence(program, program_fit, seed=seed).log_z
    if method == "evidence_smc":
        return smc_log_evidence(program, seed=seed).log_z
    if method == "blocked_cv":
        folds_fn, engine_cls, cross_validate, axis, quantile, settings = blocked
        engine = engine_cls(program, seed=seed, **settings)
        return float(cross_validate(engine, folds_fn(ds, axis, quantile=quantile), seed=seed).elpd)
    raise UserError(f"unknown method {method!r}", "methods")


def _blocked_cv_api(axis: str | None, quantile: float, settings: Mapping[str, Any]):
    if axis is None:
        return None
    try:  # written in parallel by the cross-validation work; used when present
        from bayesfric.compare.folds import blocked_masks
        from bayesfric.compare.refit import RefitEngine, cross_validate
    except ImportError as exc:  # pragma: no cover - depends on the other module's presence
        raise RuntimeError("blocked CV needs bayesfric.compare.refit, which is missing") from exc
    return blocked_masks, RefitEngine.build, cross_validate, axis, quantile, dict(settings)


def model_recovery(
    laws: Sequence[Law],
    design: Mapping[str, np.ndarray],
    *,
    sigma: float,
    response_scale: float,
    replicates: int = 2,
    methods: Sequence[str] = ("evidence", "loo"),
    priors: Mapping[str, Mapping[str, Prior]] | None = None,
    noise: Noise | None = None,
    fit_settings: Mapping[str, Any] | None = None,
    blocked_axis: str | None = None,
    blocked_quantile: float = 0.75,
    seed: int = 0,
) -> RecoveryResult:
    """Simulate from each law, fit every law to every set, and score how often each method
    picks the true law.

    Parameters
    ----------
    laws : sequence of Law
        Candidate laws (at least two), all reading inputs present in ``design``.
    design : mapping
        Input quantity -> values (SI), the operating points of every simulated set.
    sigma : float
        Standard deviation of the simulated Gaussian noise (SI).
    response_scale : float
        Typical largest |response| (SI), to resolve data-scaled priors for the simulation.
    replicates : int
        Simulated sets per law.
    methods : sequence of str
        Any of ``"evidence"`` (bridge sampling on the fit), ``"evidence_smc"`` (tempered SMC,
        one more compilation per fit), ``"loo"`` (PSIS-LOO elpd) and ``"blocked_cv"``
        (extrapolation fold along ``blocked_axis``; needs :mod:`bayesfric.compare.refit`).
    priors : mapping, optional
        Law name -> prior overrides, used both to simulate and to fit.
    noise : Noise, optional
        Noise model of the fits (default: normal with sampled sigma).
    fit_settings : mapping, optional
        NUTS settings of every fit (default: 500 draws, 300 tuning steps, 2 chains); also the
        refit settings of blocked CV.
    blocked_axis, blocked_quantile
        Axis and boundary quantile of the blocked extrapolation fold (upper block held out).
    seed : int
        Seed of parameter draws, noise and fits.

    Returns
    -------
    RecoveryResult
        ``confusion[method][i, j]``: sets simulated from ``laws[i]`` on which ``laws[j]`` won.
    """
    if len(laws) < 2:
        raise UserError("model recovery needs at least two laws", "laws")
    methods = list(methods)
    if "blocked_cv" in methods and blocked_axis is None:
        raise UserError("method 'blocked_cv' needs blocked_axis", "blocked_axis")
    settings = dict(draws=500, tune=300, chains=2) | dict(fit_settings or {})
    blocked = _blocked_cv_api(blocked_axis if "blocked_cv" in methods else None,
                              blocked_quantile, settings)
    inputs = {k: np.asarray(v, dtype=float) for k, v in design.items()}
    scale = DataScale.of(np.array([response_scale]), inputs)
    names = [law.name for law in laws]
    confusion = {m: np.zeros((len(laws), len(laws)), dtype=int) for m in methods}
    records = []
    for i, true_law in enumerate(laws):
        law_priors = dict((priors or {}).get(true_law.name, {}))
        for r in range(replicates):
            set_seed = seed + 1000 * i + r
            params = draw_plausible_parameters(true_law, inputs, scale, priors=law_priors,
                                               seed=set_seed)
            # every design input becomes a coordinate, also those the true law ignores
            ds = simulate(true_law, inputs, params, sigma=sigma, seed=set_seed)
            scores = {m: {} for m in methods}
            for candidate in laws:
                fit_kwargs = {"priors": dict((priors or {}).get(candidate.name, {})),
                              "noise": noise}
                dt = fit(candidate, ds, seed=set_seed, **fit_kwargs, **settings)
                for m in methods:
                    scores[m][candidate.name] = _scores(
                        dt, candidate, ds, m, fit_kwargs=fit_kwargs, seed=set_seed, blocked=blocked
                    )
            release_compiled_code()  # each replicate's fits compile afresh; free them
            chosen = {m: max(scores[m], key=scores[m].get) for m in methods}
            for m in methods:
                confusion[m][i, names.index(chosen[m])] += 1
            records.append({"true": true_law.name, "replicate": r, "seed": set_seed,
                            "params": {k: float(np.asarray(v)) if np.ndim(v) == 0 else
                                       np.asarray(v).tolist() for k, v in params.items()},
                            "scores": scores, "chosen": chosen})
    total = len(laws) * replicates
    hit_rate = {m: float(np.trace(confusion[m]) / total) for m in methods}
    return RecoveryResult(names, confusion, hit_rate, records)

