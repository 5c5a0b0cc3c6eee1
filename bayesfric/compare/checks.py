"""Model checks: prior predictive plausibility, LOO-PIT calibration, prior sensitivity.

* :func:`prior_predictive_check` -- draw parameters from a program's priors, evaluate the law on
  the data's inputs and on random points of the operating envelope, and report how often the
  prior proposes physically wrong friction (:func:`plausible_draws` says which rules apply).
* :func:`loo_pit_check` -- LOO-PIT values (arviz-stats ``loo_pit``) with a Kolmogorov-Smirnov
  statistic and the simultaneous PIT-ECDF band of arviz-stats.
* :func:`prior_sensitivity` -- arviz-stats ``psense_summary`` on a fit (needs the fit's
  ``log_prior`` group, written by :func:`bayesfric.inference.datatree.assemble`).
* :func:`ranking_sensitivity` -- PSIS-LOO elpd of several fits under power-scaled priors
  p(θ)^α, by importance reweighting of the existing draws, and whether the ranking changes.

Above :data:`~bayesfric.limits.LOO_SUBSAMPLE_ROWS` data rows, LOO-PIT and the ranking
sensitivity read a random subsample of :data:`~bayesfric.limits.LOO_SUBSAMPLE_SIZE` rows (the
rows the subsampled PSIS-LOO scores exactly, :func:`~bayesfric.compare.loo_subsample.subsample_rows`),
and say so (``PitCheck.n_rows``, ``RankingSensitivity.details``); the prior predictive check
evaluates its draws in chunks (every row, bounded memory). Below the limit nothing changes.
"""

from __future__ import annotations

import contextlib
import io
import logging
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import arviz as az
import jax
import numpy as np
import pandas as pd
import xarray as xr
from arviz_stats.ecdf_utils import ecdf_pit
from numpyro.infer import Predictive
from scipy.stats import kstest

from bayesfric.compare.loo_subsample import n_rows, on_rows, releases_views, rows_summed, subsample_rows
from bayesfric.errors import UserError
from bayesfric.exported import program_jit
from bayesfric.inference.pointwise import stored_draws
from bayesfric.limits import CHUNK_NUMBERS
from bayesfric.model import OBS_SITE, Program

__all__ = [
    "PlausibilityReport",
    "PitCheck",
    "RankingSensitivity",
    "sign_rule",
    "plausible_draws",
    "prior_predictive_check",
    "fit_prior_draws",
    "loo_pit_check",
    "prior_sensitivity",
    "power_scaled_loo",
    "ranking_sensitivity",
]

_MOTION_INPUTS = ("velocity", "linear_velocity")
_SAMPLE_DIMS = ["chain", "draw"]


# -- prior predictive plausibility ----------------------------------------------------------------
@dataclass(frozen=True)
class PlausibilityReport:
    """Fractions of prior draws whose friction is physically wrong (each in [0, 1])."""

    law: str
    n_draws: int
    sign_rule: str
    wrong_sign: float
    static_below_kinetic: float | None  # None where the law has no static/kinetic pair
    non_finite: float
    implausible: float  # fraction failing any rule
    n_points: int  # data points + envelope points evaluated per draw


def sign_rule(program: Program) -> str:
    """Which sign rule applies to a law's friction (see :func:`plausible_draws`)."""
    law = program.law
    if law.response not in ("torque", "force"):
        return "none (response is not a friction torque or force)"
    if law.trajectory:
        return "none (stateful law: friction may lag the motion)"
    motion = [q for q in _MOTION_INPUTS if q in law.inputs]
    if motion:
        return f"opposes motion: sign(response) = sign({motion[0]}) where {motion[0]} != 0"
    return "load-driven: response >= 0"


def _static_kinetic(program: Program) -> tuple[str, str] | None:
    """(static, kinetic) names: a derived quantity meaning 'static ...' and a parameter or
    derived quantity meaning 'Coulomb'/'kinetic' (read from the law's declaration)."""
    law = program.law
    static = [k for k, d in law.derived.items() if "static" in d.meaning.lower()]
    kinetic = [k for k, p in law.params.items()
               if any(w in p.meaning.lower() for w in ("coulomb", "kinetic"))]
    return (static[0], kinetic[0]) if static and kinetic else None


def _envelope_points(program: Program, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Data inputs, plus (for laws without state) ``n`` uniform points in the inputs' box."""
    points = {k: np.asarray(v) for k, v in program.inputs.items()}
    if program.law.trajectory or n <= 0:
        return points
    for name, values in points.items():
        finite = values[np.isfinite(values)] if values.dtype.kind == "f" else values
        extra = rng.uniform(finite.min(), finite.max(), n) if finite.size else np.zeros(n)
        points[name] = np.concatenate([values, extra])
    return points


def plausible_draws(
    program: Program,
    params: Mapping[str, np.ndarray],
    *,
    envelope_points: int = 200,
    seed: int = 0,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Per-draw plausibility of parameter draws (leading axis = draws).

    Rules, each applied where it makes sense (:func:`sign_rule`):

    * friction opposes motion: a law reading a velocity must give response · velocity >= 0
      at every point with non-zero velocity; a load-driven law (no velocity input) must give a
      non-negative torque/force; stateful (trajectory) laws and non-friction responses are
      exempt;
    * static >= kinetic where the law declares a derived static level (meaning "static ...")
      and a Coulomb/kinetic parameter;
    * every value finite.

    Returns
    -------
    ok : numpy.ndarray of bool, shape (draws,)
    failures : dict
        ``wrong_sign``, ``static_below_kinetic`` (absent if not applicable), ``non_finite``:
        boolean arrays per draw.
    """
    law = program.law
    points = _envelope_points(program, envelope_points, np.random.default_rng(seed))
    inputs = {k: np.asarray(v) for k, v in points.items()}
    law_params = {k: np.asarray(params[k]) for k in law.params}
    n_draws = len(next(iter(law_params.values())))
    # chunks of draws × points ≤ CHUNK_NUMBERS: one chunk (as always) up to ~8000 rows at 500 draws
    size = max(1, CHUNK_NUMBERS // max(1, len(next(iter(inputs.values())))))
    parts = [_sign_failures(program, points, {k: v[a:a + size] for k, v in law_params.items()})
             for a in range(0, n_draws, size)]
    failures = {"wrong_sign": np.concatenate([w for w, _ in parts]),
                "non_finite": np.concatenate([f for _, f in parts])}
    pair = _static_kinetic(program)
    if pair is not None:
        derived = law.derived_values(law_params)
        static, kinetic = pair
        kinetic_values = law_params[kinetic] if kinetic in law_params else derived[kinetic]
        failures["static_below_kinetic"] = np.asarray(derived[static] < kinetic_values).reshape(-1)
    ok = ~np.any(np.stack(list(failures.values())), axis=0)
    return ok, failures


def _sign_failures(program: Program, points: Mapping[str, np.ndarray], law_params: Mapping[str, np.ndarray]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(wrong sign, non-finite) per draw of ``law_params`` at ``points`` (see :func:`plausible_draws`)."""
    law = program.law
    inputs = {k: np.asarray(v) for k, v in points.items()}
    # one compiled program (kept on disk), not the law's operations dispatched one by one
    means = np.asarray(program_jit(program, "plausible_draws means", partial(_means, law, program.constants))(
        law_params, inputs))
    means = means.reshape(means.shape[0], -1)
    non_finite = ~np.all(np.isfinite(means), axis=1)
    rule = sign_rule(program)
    wrong_sign = np.zeros(means.shape[0], dtype=bool)
    if rule.startswith("opposes"):
        motion = next(q for q in _MOTION_INPUTS if q in law.inputs)
        velocity = np.asarray(points[motion]).reshape(-1)
        wrong_sign = np.any((means * velocity < 0) & (velocity != 0), axis=1)
    elif rule.startswith("load"):
        wrong_sign = np.any(means < 0, axis=1)
    return wrong_sign, non_finite


def _means(law, constants, params, inputs):
    return jax.vmap(lambda p: law.mean(inputs, p, constants))(params)


def prior_predictive_check(
    program: Program, *, draws: int = 500, seed: int = 0, envelope_points: int = 200,
    prior: Mapping[str, np.ndarray] | None = None,
) -> PlausibilityReport:
    """Fractions of prior draws of ``program`` that give physically wrong friction.

    Parameters
    ----------
    program : Program
        Law, priors and data (the data's inputs and their envelope are evaluated).
    draws : int
        Prior draws.
    seed : int
        Seed of the prior draws and of the envelope points.
    envelope_points : int
        Uniform random points in the bounding box of the inputs, added to the data's own
        (ignored for stateful laws, which only make sense along the measured trajectories).
    prior : mapping, optional
        Prior draws of the law's parameters already at hand (leading axis: draws), e.g. a fit's
        ``prior`` group (:func:`fit_prior_draws`); ``draws`` is then their number. Drawn here
        otherwise.
    """
    if prior is None:
        prior = Predictive(program.model, num_samples=draws, return_sites=list(program.law.params))(
            jax.random.PRNGKey(seed), **dict(program.model_kwargs, response=None)
        )
    draws = len(next(iter(prior.values())))
    ok, failures = plausible_draws(program, prior, envelope_points=envelope_points, seed=seed)
    n_points = program.n_obs + (0 if program.law.trajectory else envelope_points)
    static = failures.get("static_below_kinetic")
    return PlausibilityReport(
        law=program.law.name,
        n_draws=draws,
        sign_rule=sign_rule(program),
        wrong_sign=float(failures["wrong_sign"].mean()),
        static_below_kinetic=None if static is None else float(static.mean()),
        non_finite=float(failures["non_finite"].mean()),
        implausible=float(1.0 - ok.mean()),
        n_points=n_points,
    )


def fit_prior_draws(fit: xr.DataTree, names: Sequence[str]) -> dict[str, np.ndarray]:
    """The prior draws of parameters ``names`` stored with a fit (chain and draw flattened)."""
    prior = fit["prior"]
    return {k: np.asarray(prior[k].values).reshape((-1,) + prior[k].shape[2:]) for k in names}


# -- posterior predictive: LOO-PIT ----------------------------------------------------------------
@dataclass(frozen=True)
class PitCheck:
    """LOO-PIT uniformity of one fit."""

    pit: np.ndarray
    ks_statistic: float
    ks_pvalue: float
    within_band: bool  # PIT-ECDF inside the simultaneous band at ci_prob
    ci_prob: float
    notes: str = ""
    band: np.ndarray | None = field(default=None, repr=False)  # (3, m): evaluation points, lower, upper
    n_rows: int = 0  # rows of the data; above pit.size when the check read a subsample (0: not recorded)

    @property
    def subsampled(self) -> bool:
        return self.n_rows > self.pit.size


@releases_views
def loo_pit_check(dt: xr.DataTree, *, ci_prob: float = 0.99, n_simulations: int = 1000,
                  seed: int = 0) -> PitCheck:
    """LOO-PIT values of a fit with two uniformity summaries.

    Parameters
    ----------
    dt : xarray.DataTree
        A fit (posterior, posterior_predictive, log_likelihood, observed_data).
    ci_prob : float
        Level of the simultaneous PIT-ECDF band (arviz-stats' simulation method, as in
        ``plot_loo_pit``).
    n_simulations, seed
        Simulations and seed of that band (kept in ``band``: the report draws it).

    Notes
    -----
    LOO-PIT values are only approximately independent; the KS p-value is a screening number,
    not an exact test. The band is the calibrated summary that arviz draws. A thinned fit
    (:mod:`bayesfric.inference.pointwise`) is read on the draws it keeps, in float64. Above
    ``limits.LOO_SUBSAMPLE_ROWS`` rows only a random subsample of rows is read (``n_rows`` and
    ``notes`` say how many of how many).
    """
    rows, n = subsample_rows(n_rows(dt)), n_rows(dt)
    view = stored_draws(dt) if rows is None else on_rows(dt, rows, ("log_likelihood", "posterior_predictive"))
    pit = np.asarray(az.loo_pit(view, var_names=OBS_SITE)[OBS_SITE]).reshape(-1)
    ks = kstest(pit, "uniform")
    points, ecdf, lower, upper = ecdf_pit(pit, ci_prob, n_simulations, rng=np.random.default_rng(seed))
    within = bool(np.all((ecdf >= lower - 1e-12) & (ecdf <= upper + 1e-12)))
    notes = "LOO-PIT via arviz-stats; KS p-value approximate (PIT values are dependent)"
    if rows is not None:
        notes += f"; on a random subsample of {rows.size} of {n} rows"
    return PitCheck(pit, float(ks.statistic), float(ks.pvalue), within, ci_prob, notes,
                    np.stack([points, lower, upper]), n)



# -- prior sensitivity ----------------------------------------------------------------------------
def _parameters(dt: xr.DataTree) -> list[str]:
    """Posterior variables but the per-group ones (offsets, a varying parameter's levels), whose
    extra dimension is a group column, not the parameter's own ``<name>_dim_<k>``, and but those
    constant in every draw (a derived quantity that fixed values hold, σ1 = 0 where ρ1 = 0: no
    sensitivity to measure), unless every one is."""
    post = dt["posterior"]
    own = [v for v in post.data_vars
           if set(post[v].dims) <= {"chain", "draw"} | {f"{v}_dim_{i}" for i in range(post[v].ndim)}]
    moving = [v for v in own if not (post[v].size and bool((post[v] == post[v].values.flat[0]).all()))]
    return moving or own


@releases_views
def prior_sensitivity(dt: xr.DataTree, threshold: float = 0.05) -> pd.DataFrame:
    """Power-scaling prior and likelihood sensitivity per parameter (arviz-stats ``psense_summary``,
    Kallioinen et al. 2024): columns ``prior``, ``likelihood``, ``diagnosis``.

    arviz-stats also prints and logs a paragraph on how to read the diagnosis whenever one is flagged;
    it is held back here (the diagnosis is in the table and reaches the report from there).
    """
    if "log_prior" not in dt.children:
        raise UserError("fit has no log_prior group; refit with a current bayesfric")
    with contextlib.redirect_stdout(io.StringIO()), _quiet(logging.getLogger("arviz_stats.psense")):
        # the log-likelihood summed per draw in chunks: the same numbers, no copies of draws × rows
        return az.psense_summary(rows_summed(dt), var_names=_parameters(dt), threshold=threshold)


@contextlib.contextmanager
def _quiet(logger: logging.Logger):
    """Hold back ``logger``'s warnings for the duration (arviz-stats logs its reading advice)."""
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


@releases_views
def power_scaled_loo(dt: xr.DataTree, alpha: float, rows: np.ndarray | None = None):
    """PSIS-LOO of a fit as if its prior were p(θ)^α (renormalised), without refitting.

    The leave-one-out posterior under the scaled prior is reached from the posterior draws with
    importance ratios ∝ p(θ)^(α-1) / p(y_i | θ), Pareto-smoothed per observation (r_eff = 1);
    the result is arviz-stats' ``ELPDData`` (check its ``pareto_k`` / ``warning``: large α
    moves the posterior far and the reweighting becomes unreliable). ``rows``: only those rows
    (its elpd is then their sum).
    """
    if "log_prior" not in dt.children:
        raise UserError("fit has no log_prior group; refit with a current bayesfric")
    # a thinned fit: the draws its log-likelihood holds, in float64
    dt = stored_draws(dt, ("log_likelihood",)) if rows is None else on_rows(dt, rows, ("log_likelihood",))
    log_prior = dt["log_prior"].to_dataset()
    total_prior = sum(log_prior[v] for v in log_prior.data_vars)
    log_lik = dt["log_likelihood"][OBS_SITE]
    # psislw smooths the ratios exp(-ary): pass ary = log p(y_i|θ) - (α-1) log p(θ)
    log_weights, pareto_k = (log_lik - (alpha - 1.0) * total_prior).azstats.psislw(
        r_eff=1.0, dim=_SAMPLE_DIMS
    )
    return az.loo(dt, var_name=OBS_SITE, log_weights=log_weights, pareto_k=pareto_k, pointwise=True)


@dataclass(frozen=True)
class RankingSensitivity:
    """elpd_LOO of each fit at each prior power α (α = 1: the fitted prior), and the rankings.

    ``max_pareto_k`` is the largest Pareto k̂ of each fit's PSIS at each α: above
    :data:`PARETO_K_RELIABLE` the reweighted elpd of that fit is unreliable (:meth:`unreliable`).
    """

    elpd: dict[float, dict[str, float]]
    ranking: dict[float, list[str]]
    max_pareto_k: dict[float, dict[str, float]]
    changed: bool
    details: dict[str, Any] = field(default_factory=dict)

    def unreliable(self) -> dict[str, list[float]]:
        """Fit name -> the prior powers α at which its PSIS reweighting has k̂ above the threshold."""
        found: dict[str, list[float]] = {}
        for alpha, ks in self.max_pareto_k.items():
            for name, k in ks.items():
                if not k <= PARETO_K_RELIABLE:
                    found.setdefault(name, []).append(alpha)
        return found


#: Pareto k̂ above which a PSIS estimate is unreliable (Vehtari et al. 2024; arviz-stats' warning).
PARETO_K_RELIABLE = 0.7


def ranking_sensitivity(
    fits: Mapping[str, xr.DataTree], alphas: Sequence[float] = (0.5, 2.0), *,
    baseline: Mapping[str, Any] | None = None,
) -> RankingSensitivity:
    """Does the elpd_LOO ranking of ``fits`` change when every prior is power-scaled by α?

    Parameters
    ----------
    fits : mapping
        Name -> fit, all on the same data.
    alphas : sequence of float
        Prior powers besides 1 (α < 1 weakens, α > 1 sharpens the priors).
    baseline : mapping, optional
        Name -> arviz-stats' plain PSIS-LOO of that fit (``LooResult.psis``), already computed:
        the α = 1 results are taken from it instead of computed again (missing names are).

    Above ``limits.LOO_SUBSAMPLE_ROWS`` rows every α (1 included, ``baseline`` unused) is
    computed on the same random subsample of rows and scaled to the data (``N / m`` times the
    subsample's sum); ``details["rows"]`` says how many of how many.
    """
    first = next(iter(fits.values()))
    rows = subsample_rows(n_rows(first))
    baseline = (baseline or {}) if rows is None else {}
    elpd: dict[float, dict[str, float]] = {}
    ranking: dict[float, list[str]] = {}
    max_k: dict[float, dict[str, float]] = {}
    for alpha in (1.0, *alphas):
        with warnings.catch_warnings():  # high Pareto k is kept in max_pareto_k and reported from there
            warnings.filterwarnings("ignore", message="Estimated shape parameter of Pareto", category=UserWarning)
            results = {name: (power_scaled_loo(dt, alpha, rows) if alpha != 1.0 or rows is not None
                              else baseline[name] if baseline.get(name) is not None
                              else az.loo(stored_draws(dt, ("log_likelihood",)), var_name=OBS_SITE, pointwise=True))
                       for name, dt in fits.items()}
        scale = 1.0 if rows is None else n_rows(first) / rows.size
        elpd[alpha] = {name: float(r.elpd) * scale for name, r in results.items()}
        max_k[alpha] = {name: float(np.max(r.pareto_k)) for name, r in results.items()}
        ranking[alpha] = sorted(elpd[alpha], key=lambda n: -elpd[alpha][n])
    changed = any(ranking[a] != ranking[1.0] for a in alphas)
    details = {"method": "PSIS reweighting by p(θ)^(α-1), no refits"}
    if rows is not None:
        details["rows"] = f"a random subsample of {rows.size} of {n_rows(first)} rows, elpd scaled by N/m"
    return RankingSensitivity(elpd, ranking, max_k, changed, details)

