"""PSIS-LOO of a fit, with high Pareto-k points handled by exact refits (never ignored).

The Pareto-smoothed importance-sampling estimate comes from arviz-stats (``arviz.loo`` on the
fit's ``log_likelihood`` group, variable ``response`` over dimension ``obs``). Points whose
Pareto k̂ exceeds arviz-stats' sample-size-dependent threshold ``good_k = min(1 - 1/log10(S),
0.7)`` (S = number of posterior draws; 0.7 for S >= 2154) have an unreliable importance-sampling
estimate; each is refitted exactly with that point left out, using the compile-once
:class:`~bayesfric.compare.refit.RefitEngine`, and its ``elpd_i`` replaced by the exact
``log mean_s p(y_i | θ_s^(-i))``. A refit that fails the diagnostics gate is flagged in the
result.

``p_loo = Σ_i (lppd_i − elpd_i)`` with ``lppd_i = log mean_s p(y_i | θ_s)`` from the full fit;
``se = sqrt(n · var(elpd_i))`` as in arviz-stats.

A large fit keeps thinned pointwise draws (:mod:`bayesfric.inference.pointwise`): PSIS-LOO then
runs on the draws it holds, in float64, with the posterior restricted to them
(:func:`~bayesfric.inference.pointwise.stored_draws`), so S above is the number kept.

Above :data:`~bayesfric.limits.LOO_SUBSAMPLE_ROWS` data rows PSIS-LOO is **subsampled**
(:mod:`bayesfric.compare.loo_subsample`, arviz-stats' ``loo_subsample``): the high-k points of
the subsample are refitted as above, and the elpd, its se and its subsampling se come from the
difference estimator. Below the limit nothing changes.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import arviz as az
import numpy as np
import xarray as xr

from bayesfric.compare.loo_subsample import Subsample, describe, estimate, is_subsampled, releases_views, subsample_psis
from bayesfric.compare.refit import CVResult, RefitEngine, pointwise_lpd, program_from_fit
from bayesfric.errors import UserError
from bayesfric.inference.diagnostics import verdict_of
from bayesfric.inference.pointwise import stored_draws
from bayesfric.model import OBS_SITE, Program

__all__ = ["LooResult", "psis_loo", "loo_from_values", "K_THRESHOLD_RULE", "Penalty", "extrapolation_penalty"]

K_THRESHOLD_RULE = "arviz-stats good_k = min(1 - 1/log10(S), 0.7), S = posterior draws"


@dataclass
class LooResult:
    """PSIS-LOO of one fit.

    Attributes
    ----------
    law : str
    elpd, se, p_loo : float
    elpd_i : ndarray
        ``(n_obs,)`` pointwise elpd, exact refit values at the high-k points.
    pareto_k : ndarray
        ``(n_obs,)`` Pareto k̂ of the PSIS estimate (before any refit).
    k_threshold : float
        Threshold used (:data:`K_THRESHOLD_RULE`).
    high_k : ndarray
        Indices of points with ``k̂ > k_threshold``.
    handling : str
        How the high-k points were handled, one line.
    refit_failed : list of int
        High-k points whose exact refit failed the diagnostics gate (their elpd is flagged).
    fit_passed : bool
        Whether the full fit passed the diagnostics gate (``fit.attrs["diagnostics"]``).
    refitted : bool
        Whether every high-k point was refitted exactly (False: their PSIS values were kept).
    elpd_data : arviz_stats.ELPDDataLOO
        arviz-stats' object with the refit values substituted (feeds ``arviz.compare``).
    psis : arviz_stats.ELPDDataLOO or None
        arviz-stats' plain PSIS-LOO of the fit, before any substitution (the α = 1 baseline of
        :func:`bayesfric.compare.checks.ranking_sensitivity`).
    subsample : Subsample or None
        Above :data:`~bayesfric.limits.LOO_SUBSAMPLE_ROWS` rows, the rows scored exactly; the
        other rows' ``elpd_i`` are the approximation and their ``pareto_k`` NaN.
    subsampling_se : float
        The part of ``se`` due to subsampling (0 when every row was scored).
    """

    law: str
    elpd: float
    se: float
    p_loo: float
    elpd_i: np.ndarray
    pareto_k: np.ndarray
    k_threshold: float
    high_k: np.ndarray
    handling: str
    refit_failed: list[int]
    fit_passed: bool
    elpd_data: object
    refitted: bool = True
    psis: object = None
    subsample: Subsample | None = None
    subsampling_se: float = 0.0

    @property
    def n_high_k(self) -> int:
        return int(self.high_k.size)

    @property
    def reliable(self) -> bool:
        """Full fit passed the gate, and every high-k point was refitted by a passing fit."""
        return self.fit_passed and self.refitted and not self.refit_failed

    def __str__(self) -> str:
        flag = "" if self.reliable else "  [FLAGGED: unreliable]"
        sub = f"; {self.subsampled}" if self.subsample is not None else ""
        return (f"{self.law}: elpd_loo {self.elpd:.2f} ± {self.se:.2f}, p_loo {self.p_loo:.1f}, "
                f"{self.n_high_k} k̂ > {self.k_threshold:.2f} ({self.handling}){sub}{flag}")

    @property
    def subsampled(self) -> str:
        """``"subsampled: n of N rows, subsampling se X (...)"``, or ``""`` when every row was scored."""
        return describe(self.subsample, self.subsampling_se) if self.subsample is not None else ""


def psis_loo(
    fit: xr.DataTree,
    ds: xr.Dataset | None = None,
    *,
    program: Program | None = None,
    engine: RefitEngine | Callable[[], RefitEngine] | None = None,
    seed: int = 0,
    no_refit: str = "",
) -> LooResult:
    """PSIS-LOO of ``fit`` with exact refits of the high Pareto-k points.

    Parameters
    ----------
    fit : xarray.DataTree
        A fit from :func:`bayesfric.inference.fit`.
    ds : xarray.Dataset, optional
        The data of the fit; needed (or ``program`` / ``engine``) to refit high-k points.
    program : Program, optional
        The fit's program, if already built (e.g. with a known-sigma noise model).
    engine : RefitEngine or callable, optional
        A compiled refit engine of the same program (reused across calls), or a function
        returning one, called only when some point needs a refit (a study's warm-started
        engine costs ~0.1 s to set up; most fits have no high-k point).
    seed : int
        Seed of the refits.
    no_refit : str, optional
        Why no point may be refitted (a study's fit that failed the gate under ``[compare]
        failed_fits = "skip"``): the PSIS values are kept and ``handling`` gives the reason.

    Returns
    -------
    LooResult
        If high-k points exist and no data were given to refit them (or ``no_refit`` says why
        not), ``refitted`` is False, ``handling`` says so and the result is flagged unreliable.
    """
    data, sub = subsample_psis(fit, program, ds) if is_subsampled(fit) else (_psis(fit), None)
    pareto_k = np.asarray(data.pareto_k.values, dtype=float).ravel()  # NaN off a subsample
    elpd_i = np.asarray(data.elpd_i.values, dtype=float).ravel()
    threshold = float(data.good_k)
    high = np.flatnonzero(pareto_k > threshold)
    refit_failed: list[int] = []
    refitted = True
    if high.size == 0:
        handling = "none above threshold"
    elif no_refit:
        handling = f"{high.size} point(s) not refitted: {no_refit} (PSIS values kept)"
        refitted = False
    elif engine is None and program is None and ds is None:
        handling = f"{high.size} point(s) not refitted: no data given (PSIS values kept)"
        refitted = False
    else:
        passed = "diagnostics" in fit.attrs and verdict_of(fit).passed
        if callable(engine) and not isinstance(engine, RefitEngine):
            engine = engine()
        engine = engine or RefitEngine.build(program or program_from_fit(fit, ds), warm_start=fit if passed else None)
        masks = np.ones((high.size, elpd_i.size), dtype=bool)
        masks[np.arange(high.size), high] = False
        refits = engine.run(masks, seed=seed)
        elpd_i[high] = refits.lpd[np.arange(high.size), high]
        refit_failed = [int(high[j]) for j in refits.failed]
        handling = f"exact refits leaving out each of {high.size} point(s)"
        if refit_failed:
            handling += f"; refits of {refit_failed} failed the gate"
    return _result(fit, data, elpd_i, threshold, high, handling, refit_failed, refitted, sub)


@releases_views
def _psis(fit: xr.DataTree):
    """arviz-stats' PSIS-LOO of ``fit``; its warning on high Pareto k̂ is held back: those points
    are refitted, or the result says they were not (``handling``, ``reliable``)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Estimated shape parameter of Pareto", category=UserWarning)
        return az.loo(stored_draws(fit, ("log_likelihood",)), pointwise=True, var_name=OBS_SITE)


def _result(fit: xr.DataTree, data, elpd_i: np.ndarray, threshold: float, high: np.ndarray, handling: str,
            refit_failed: list[int], refitted: bool, sub: Subsample | None = None) -> LooResult:
    """The :class:`LooResult` of ``fit`` from arviz-stats' ``data`` and the (refitted) ``elpd_i``
    (of the subsample's rows only, when ``sub`` is given: the others are approximated)."""
    sub_se, extra = 0.0, {}
    if sub is None:
        ll = np.asarray(fit["log_likelihood"][OBS_SITE].values, dtype=float)  # a thinned fit's may be float32
        lppd_i = pointwise_lpd(ll.reshape((-1, ll.shape[-1])))
        n = elpd_i.size
        elpd, se = float(elpd_i.sum()), float(np.sqrt(n * elpd_i.var()))
        p_loo = float((lppd_i - elpd_i).sum())
    else:
        exact = np.asarray(elpd_i, dtype=float)[sub.rows]  # PSIS or exact-refit values
        elpd, se, sub_se, p_loo = estimate(fit, sub, exact)
        elpd_i = sub.approx.copy()
        elpd_i[sub.rows] = exact
        extra = {"subsampling_se": sub_se}
    updated = dataclasses.replace(
        data, elpd=elpd, se=se, p=p_loo, **extra,
        elpd_i=data.elpd_i.copy(data=elpd_i.reshape(data.elpd_i.shape)),
        warning=bool(high.size) and (bool(refit_failed) or not refitted),
    )
    return LooResult(
        law=str(fit.attrs.get("law", "")),
        elpd=elpd, se=se, p_loo=p_loo, elpd_i=elpd_i,
        pareto_k=np.asarray(data.pareto_k.values, dtype=float).ravel(),
        k_threshold=threshold, high_k=high, handling=handling, refit_failed=refit_failed,
        fit_passed=verdict_of(fit).passed if "diagnostics" in fit.attrs else False,
        elpd_data=updated, refitted=refitted, psis=data, subsample=sub, subsampling_se=sub_se,
    )


def loo_from_values(fit: xr.DataTree, elpd_i: np.ndarray, handling: str, refit_failed: list[int],
                    refitted: bool) -> LooResult:
    """Rebuild the :class:`LooResult` of ``fit`` from a stored ``elpd_i`` (refit values in place).

    The Pareto-smoothed part is recomputed from the fit (deterministic, cheap); only the exact
    refits' values come from the store (:mod:`bayesfric.study.units`).
    """
    data, sub = subsample_psis(fit) if is_subsampled(fit) else (_psis(fit), None)
    threshold = float(data.good_k)
    high = np.flatnonzero(np.asarray(data.pareto_k.values, dtype=float).ravel() > threshold)
    return _result(fit, data, np.asarray(elpd_i, dtype=float), threshold, high, handling, list(refit_failed),
                   refitted, sub)


@dataclass(frozen=True)
class Penalty:
    """Extrapolation penalty of one law: what blocking the envelope costs per held-out point.

    ``per_point = mean_i (elpd_loo_i − elpd_blocked_i)`` over the blocked scheme's held-out
    points (the SAME points for both terms), ``se = sd_i(·) / sqrt(n_points)``. Positive: the
    law predicts the outer envelope worse when it has not seen it than LOO suggests. A subsampled
    LOO (:mod:`~bayesfric.compare.loo_subsample`) scores only its subsample exactly: the penalty
    then runs over the held-out points in the subsample (``n_points`` says how many).
    """

    law: str
    scheme: str
    per_point: float
    se: float
    n_points: int
    reliable: bool

    def __str__(self) -> str:
        flag = "" if self.reliable else "  [FLAGGED]"
        return (f"{self.law} / {self.scheme}: extrapolation penalty {self.per_point:.3f} "
                f"± {self.se:.3f} nats per point over {self.n_points} points{flag}")


def extrapolation_penalty(loo: LooResult, blocked: CVResult) -> Penalty:
    """``(elpd_LOO − elpd_blocked)`` per held-out point of a blocked scheme (see :class:`Penalty`).

    Raises
    ------
    ValueError
        The two results belong to different laws or data sizes.
    """
    if loo.law != blocked.law or loo.elpd_i.size != blocked.elpd_i.size:
        raise UserError("LOO and blocked CV must be of the same law on the same data")
    points = np.asarray(blocked.heldout, dtype=bool).copy()
    if loo.subsample is not None:  # the approximated rows are no LOO values
        exact = np.zeros_like(points)
        exact[loo.subsample.rows] = True
        points &= exact
    diff = loo.elpd_i[points] - blocked.elpd_i[points]
    return Penalty(loo.law, blocked.scheme, float(diff.mean()),
                   float(diff.std(ddof=1) / np.sqrt(diff.size)) if diff.size > 1 else float("nan"),
                   int(diff.size), loo.reliable and blocked.reliable)
