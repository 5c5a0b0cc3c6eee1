"""Model weights and averaging: stacking / pseudo-BMA+ from LOO or from a CV scheme, Bayes
factors from log evidences, and model-averaged posterior predictions.

Weights are computed by arviz-stats' ``compare`` (stacking: Yao et al. 2018; ``BB-pseudo-BMA``:
pseudo-BMA+ with Bayesian-bootstrap stabilisation). From a blocked cross-validation scheme the
same optimisation runs on the held-out pointwise elpd, so the stacking weights say which mixture
of laws *extrapolates* best (the held-out points are the outer part of the envelope).

Stacking on a cross-validation scheme is **Bayesian-bootstrap stacking** (:func:`bootstrap_stacking`):
a blocked fold often holds out a few points, and a weight of 1.0 solved on them is not certain.
The held-out points get Dirichlet(1, …, 1) weights (Rubin 1981), the stacking is solved again for
each of :data:`BOOTSTRAP` draws, and the laws are mixed over the draws. For the marginal predictive
at any point (every quantile sizing reports) a mixture over draws of weights ``w_b`` is the
mixture with their mean ``mean_b w_b``, which is what the weights hold; the point estimate is kept
in ``Weights.point``. PSIS-LOO stacking (every point scored) is the plain optimum.

Unreliable results -- a fit that failed the diagnostics gate, a high-k refit or a CV fold that
failed it -- are excluded from the weights unless ``include_failed=True``; the result lists
what was excluded and why.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import arviz as az
import numpy as np
import pandas as pd
import xarray as xr
from arviz_stats import ELPDDataLOOKFold

from bayesfric.compare.loo import LooResult
from bayesfric.compare.refit import CVResult
from bayesfric.datasets.loader import OBS_DIM
from bayesfric.errors import UserError

__all__ = ["BOOTSTRAP", "Weights", "bootstrap_stacking", "model_weights", "new_group_weights", "BayesFactors",
           "bayes_factors", "averaged_predictive"]

#: Bayesian-bootstrap draws of the stacking weights on a cross-validation scheme.
BOOTSTRAP = 400

_METHODS = {
    "stacking": "stacking", "pseudo-bma+": "BB-pseudo-BMA", "bb-pseudo-bma": "BB-pseudo-BMA",
}


@dataclass
class Weights:
    """Model weights.

    Attributes
    ----------
    weights : dict of str to float
        Law -> weight (sums to 1 over the included laws).
    method : str
        arviz-stats method name (``"stacking"`` or ``"BB-pseudo-BMA"``).
    basis : str
        What the pointwise elpd came from (``"PSIS-LOO"`` or the CV scheme).
    excluded : dict of str to str
        Law -> reason, for unreliable results left out.
    table : pandas.DataFrame
        arviz-stats' comparison table of the included laws.
    point : dict of str to float
        Stacking on a CV scheme: the plain (point) stacking weights, before the Bayesian
        bootstrap (empty otherwise).
    """

    weights: dict[str, float]
    method: str
    basis: str
    excluded: dict[str, str] = field(default_factory=dict)
    table: pd.DataFrame | None = None
    point: dict[str, float] = field(default_factory=dict)

    def __str__(self) -> str:
        ranked = sorted(self.weights.items(), key=lambda x: -x[1])
        parts = ", ".join(f"{k} {w:.3f}" for k, w in ranked)
        text = f"{self.method} weights from {self.basis}: {parts}"
        if self.excluded:
            text += "; excluded: " + "; ".join(f"{k} ({v})" for k, v in self.excluded.items())
        return text


def _why_unreliable(result: LooResult | CVResult) -> str | None:
    if isinstance(result, LooResult):
        if not result.fit_passed:
            return "fit failed the diagnostics gate"
        if not result.reliable:
            return f"high Pareto k not resolved: {result.handling}"
        return None
    if not result.reliable:
        return result.failure
    return None


def _as_elpd_data(result: LooResult | CVResult):
    if isinstance(result, LooResult):
        return result.elpd_data
    scored = result.elpd_i[result.heldout]
    return ELPDDataLOOKFold(
        elpd=result.elpd, se=result.se, p=float("nan"), n_samples=0,
        n_data_points=int(scored.size), scale="log", warning=not result.reliable, good_k=None,
        elpd_i=xr.DataArray(scored, dims=[OBS_DIM],
                            coords={OBS_DIM: np.flatnonzero(result.heldout)}),
        pareto_k=None, n_folds=len(result.verdicts),
    )


def model_weights(
    results: Mapping[str, LooResult | CVResult],
    *,
    method: Literal["stacking", "BB-pseudo-BMA", "pseudo-BMA+"] = "stacking",
    include_failed: bool = False,
    fits: Mapping[str, xr.DataTree] | None = None,
) -> Weights:
    """Stacking or pseudo-BMA+ weights from PSIS-LOO results or from one CV scheme's results.

    Parameters
    ----------
    results : mapping
        Law -> :class:`~bayesfric.compare.loo.LooResult` (all) or
        :class:`~bayesfric.compare.refit.CVResult` (all, same scheme, same held-out points).
    method : {"stacking", "BB-pseudo-BMA", "pseudo-BMA+"}
        ``"pseudo-BMA+"`` is an alias of arviz-stats' ``"BB-pseudo-BMA"``.
    include_failed : bool
        Keep unreliable results in the weights (they are still listed in ``excluded`` = {}).
    fits : mapping, optional
        Law -> full fit; a fit whose stored verdict failed excludes its law (needed for CV
        results, which do not carry the full fit's verdict).

    Stacking on a joint CV scheme (each held-out group's rows scored together:
    :attr:`CVResult.elpd_fold`) weighs the folds' joint densities, one per fold, as the scheme
    ranks; otherwise the held-out rows one at a time.

    Raises
    ------
    ValueError
        Mixed result kinds or schemes, or fewer than one law left after exclusions.
    """
    from bayesfric.inference.diagnostics import verdict_of

    kinds = {type(r) for r in results.values()}
    if len(kinds) != 1:
        raise UserError("weights need results of one kind: all LooResult or all CVResult")
    if CVResult in kinds:
        schemes = {r.scheme for r in results.values()}
        heldouts = {r.heldout.tobytes() for r in results.values()}
        if len(schemes) != 1 or len(heldouts) != 1:
            raise UserError(f"CV weights need one scheme on the same held-out points: {schemes}")
    basis = "PSIS-LOO" if LooResult in kinds else next(iter(results.values())).scheme
    arviz_method = _METHODS.get(method.lower())
    if arviz_method is None:
        raise UserError(f"unknown method {method!r}: stacking, BB-pseudo-BMA, pseudo-BMA+", "method")
    excluded = {}
    for name, result in results.items():
        reason = _why_unreliable(result)
        failed_fit = fits is not None and name in fits and not verdict_of(fits[name]).passed
        if reason is None and failed_fit:
            reason = "fit failed the diagnostics gate"
        if reason is not None:
            excluded[name] = reason
    if include_failed:
        excluded = {}
    kept = {k: _as_elpd_data(r) for k, r in results.items() if k not in excluded}
    if not kept:
        raise UserError(f"every law was excluded as unreliable: {excluded}")
    if len(kept) == 1:
        return Weights({next(iter(kept)): 1.0}, arviz_method, basis, excluded, None)
    table = az.compare(kept, method=arviz_method, round_to="none")
    weights = {str(k): float(w) for k, w in table["weight"].items()}
    total = sum(weights.values())
    weights = {k: w / total for k, w in weights.items()}  # remove optimiser round-off
    if arviz_method != "stacking" or CVResult not in kinds:
        return Weights(weights, arviz_method, basis, excluded, table)
    names = list(kept)
    joint = [results[k].elpd_fold for k in names]
    # a joint scheme (leave-one-group-out, leave-future-out) ranks by each held-out group's rows
    # together: its stacking weighs those joint densities, one per fold, not the rows one at a time
    lpd = (np.column_stack([np.asarray(v, dtype=float) for v in joint]) if all(v is not None for v in joint)
           else np.column_stack([np.asarray(kept[k].elpd_i.values, dtype=float) for k in names]))
    mean = bootstrap_stacking(lpd).mean(axis=0)
    return Weights(dict(zip(names, map(float, mean / mean.sum()), strict=True)), "Bayesian-bootstrap stacking",
                   basis, excluded, table, point=weights)


def bootstrap_stacking(lpd: np.ndarray, draws: int = BOOTSTRAP, seed: int = 0, iterations: int = 2000,
                       tol: float = 1e-6) -> np.ndarray:
    """Stacking weights under Bayesian-bootstrap weights of the scored points.

    Each draw ``b`` maximises ``Σ_i α_bi log Σ_k w_k exp(lpd_ik)`` over the simplex, ``α_b ~
    Dirichlet(1, …, 1)`` over the points (Yao et al. 2018, §3 with the Bayesian bootstrap of
    Rubin 1981), by the EM fixed point of mixture weights (the objective is concave),
    all draws at once (SQUAREM-accelerated, Varadhan & Roland 2008), until no weight of a draw moves
    more than ``tol``.

    Parameters
    ----------
    lpd : ndarray, shape (n, K)
        Pointwise log predictive density of each of ``K`` laws at ``n`` scored points.
    draws, seed : int
        Bootstrap draws and the generator's seed (fixed: the same data give the same weights).

    Returns
    -------
    ndarray, shape (draws, K)
    """
    lpd = np.asarray(lpd, dtype=float)
    n, k = lpd.shape
    dens = np.exp(lpd - lpd.max(axis=1, keepdims=True))  # rows rescaled: the weights do not change
    alpha = np.random.default_rng(seed).dirichlet(np.ones(n), size=draws)

    def step(w, rows):  # one EM step of the draws ``rows``
        new = w * ((alpha[rows] / (w @ dens.T)) @ dens)
        return new / new.sum(axis=1, keepdims=True)

    def objective(w, rows):
        return np.sum(alpha[rows] * np.log(np.maximum(w @ dens.T, 1e-300)), axis=1)

    w = np.full((draws, k), 1.0 / k)
    live = np.arange(draws)
    for _ in range(iterations):  # SQUAREM-accelerated EM (Varadhan & Roland 2008), kept monotone
        w0 = w[live]
        w1 = step(w0, live)
        w2 = step(w1, live)
        r, v = w1 - w0, w2 - 2 * w1 + w0
        a = np.minimum(-np.sqrt(np.sum(r**2, axis=1) / np.maximum(np.sum(v**2, axis=1), 1e-300)), -1.0)[:, None]
        jump = np.clip(w0 - 2 * a * r + a**2 * v, 0.0, None)
        jump = step(jump / jump.sum(axis=1, keepdims=True), live)
        new = np.where((objective(jump, live) >= objective(w2, live))[:, None], jump, w2)
        w[live] = new
        live = live[np.max(np.abs(new - w0), axis=1) >= tol]
        if live.size == 0:
            break
    return w


def new_group_weights(results: Mapping[str, CVResult], fits: Mapping[str, xr.DataTree] | None = None,
                      include_failed: bool = False) -> Weights:
    """Bayesian-bootstrap stacking weights over each run's joint density as a new run's
    (:attr:`~bayesfric.compare.refit.CVResult.elpd_new_group` of one blocked scheme, by law:
    :mod:`bayesfric.compare.newgroup`).

    Raises
    ------
    bayesfric.errors.UserError
        Fewer than :data:`~bayesfric.compare.newgroup.MIN_GROUPS` runs held out (the scheme
        cannot tell laws apart: said as the weighting's reason), no law scored, or every law
        unreliable.
    """
    from bayesfric.compare.newgroup import MIN_GROUPS
    from bayesfric.inference.diagnostics import verdict_of

    scored = {k: r for k, r in results.items() if r.elpd_new_group is not None}
    if not scored:
        raise UserError("no law was scored for a new group")
    runs = min(len(r.elpd_new_group) for r in scored.values())
    scheme = next(iter(scored.values())).scheme
    if runs < MIN_GROUPS:
        raise UserError(f"cannot tell the laws apart for a new group: {runs} groups give {runs} joint scores, "
                        f"fewer than {MIN_GROUPS} (two values hold one degree of freedom about their spread)")
    excluded = {}
    for name, r in scored.items():
        failed = fits is not None and name in fits and not verdict_of(fits[name]).passed
        reason = _why_unreliable(r) or ("fit failed the diagnostics gate" if failed else None)
        if reason and not include_failed:
            excluded[name] = reason
    names = [k for k in scored if k not in excluded]
    if not names:
        raise UserError(f"every law was excluded as unreliable: {excluded}")
    lpd = np.column_stack([np.asarray(scored[k].elpd_new_group, dtype=float) for k in names])
    mean = bootstrap_stacking(lpd).mean(axis=0) if len(names) > 1 else np.ones(1)
    return Weights(dict(zip(names, map(float, mean / mean.sum()), strict=True)), "Bayesian-bootstrap stacking",
                   f"{scheme}, each group's rows jointly as a new group's", excluded, None)


@dataclass(frozen=True)
class BayesFactors:
    """Log Bayes factors ``log BF[i, j] = log Z_i − log Z_j`` with propagated errors.

    ``err[i, j] = sqrt(err_i² + err_j²)``: the estimators' errors are treated as independent
    (true for separate runs; nested-sampling errors are themselves approximate).
    """

    log_bf: pd.DataFrame
    err: pd.DataFrame

    def __str__(self) -> str:
        text = self.log_bf.round(2).astype(str) + " ± " + self.err.round(2).astype(str)
        return text.to_string()


def bayes_factors(log_evidence: Mapping[str, tuple[float, float]]) -> BayesFactors:
    """Matrix of log Bayes factors from ``{law: (log_Z, err)}`` (see :class:`BayesFactors`)."""
    names = list(log_evidence)
    log_z = np.array([float(log_evidence[k][0]) for k in names])
    err = np.array([float(log_evidence[k][1]) for k in names])
    if not np.all(np.isfinite(log_z)) or np.any(err < 0):
        raise UserError("log evidences must be finite and errors non-negative")
    return BayesFactors(
        pd.DataFrame(log_z[:, None] - log_z[None, :], index=names, columns=names),
        pd.DataFrame(np.sqrt(err[:, None] ** 2 + err[None, :] ** 2), index=names, columns=names),
    )


def averaged_predictive(
    fits: Mapping[str, xr.DataTree], weights: Weights | Mapping[str, float], *, seed: int = 0
) -> xr.DataTree:
    """Model-averaged posterior predictive: draws resampled from each fit's
    ``posterior_predictive`` in proportion to its weight (``arviz.weight_predictions``).

    Each law contributes ``floor(w · S_min)`` draws (S_min: the smallest number of draws over
    the fits), flattened into one ``sample`` dimension (first, before ``obs``). Laws with zero
    or no weight are left out; a single remaining law returns its own groups (chain, draw).
    """
    w = weights.weights if isinstance(weights, Weights) else dict(weights)
    names = [k for k in fits if w.get(k, 0.0) > 0]
    if not names:
        raise UserError("no fit has a positive weight", "weights")
    if len(names) == 1:
        only = fits[names[0]]
        return xr.DataTree.from_dict({
            "posterior_predictive": only["posterior_predictive"].to_dataset(),
            "observed_data": only["observed_data"].to_dataset(),
        })
    averaged = az.weight_predictions([fits[k] for k in names], weights=[w[k] for k in names],
                                     random_seed=seed)
    averaged["posterior_predictive"] = (
        averaged["posterior_predictive"].to_dataset().transpose("sample", ...))
    averaged.attrs["weights"] = str({k: round(w[k], 4) for k in names})
    return averaged
