"""Subsampled PSIS-LOO for data sets above :data:`~bayesfric.limits.LOO_SUBSAMPLE_ROWS` rows.

PSIS fits a Pareto tail per row (seconds per thousand rows whatever the draws), so above the
limit :func:`bayesfric.compare.loo.psis_loo` scores only :data:`~bayesfric.limits.LOO_SUBSAMPLE_SIZE`
rows exactly, drawn at random without replacement (seed :data:`SEED`, the same rows for every law
of a data set), with arviz-stats' public ``loo_subsample`` (Magnusson et al. 2019): the other
rows enter through an approximation, and the difference estimator gives the elpd, its total
standard error and its **subsampling** standard error (the part due to scoring a subsample).

The approximation is the point log predictive density ``plpd_i = log p(y_i | θ̄)`` at the
posterior mean θ̄ of the law's sampled parameters (``method="plpd"``), computed from the fit's
program; a fit whose program cannot be rebuilt uses the log predictive density of its stored
draws instead (``method="lpd"``), and says so. The exact rows' PSIS runs on the draws the fit
keeps (:func:`~bayesfric.inference.pointwise.stored_draws`), as the full PSIS-LOO does.

Pointwise values of a subsampled result are approximate away from the subsample: ``elpd_i``
holds the PSIS (or exact-refit) value at the subsampled rows and the approximation elsewhere,
which is what stacking weights and claims read (stated in the report); an extrapolation
penalty uses only the subsampled rows (:func:`bayesfric.compare.loo.extrapolation_penalty`).
"""

from __future__ import annotations

import functools
import gc
import warnings
from dataclasses import dataclass
from typing import Any

import arviz_stats as azs
import numpy as np
import xarray as xr
from numpyro.handlers import seed as seed_handler
from numpyro.handlers import trace
from numpyro.infer import log_likelihood as numpyro_log_likelihood

from bayesfric.inference.pointwise import stored_draws, trim_memory
from bayesfric.limits import CHUNK_NUMBERS, LOO_SUBSAMPLE_ROWS, LOO_SUBSAMPLE_SIZE
from bayesfric.model import OBS_SITE, Program, program_from_fit, program_of_fit

__all__ = ["SEED", "Subsample", "n_rows", "is_subsampled", "subsample_rows", "on_rows", "rows_summed",
           "releases_views", "subsample_psis", "estimate", "describe"]

#: Seed of the subsample's rows: fixed, so every law of a study scores the same rows (arviz-stats'
#: ``compare`` then uses its difference estimator on shared rows) and a stored result recomputes.
SEED = 315


@dataclass(frozen=True)
class Subsample:
    """The rows of a subsampled PSIS-LOO and how the rest were approximated.

    Attributes
    ----------
    rows : ndarray
        Indices of the rows scored exactly (in arviz-stats' order).
    n_rows : int
        Rows of the data set (N).
    method : {"plpd", "lpd"}
        The approximation of the other rows.
    approx : ndarray
        ``(N,)`` approximate elpd of every row.
    """

    rows: np.ndarray
    n_rows: int
    method: str
    approx: np.ndarray

    @property
    def size(self) -> int:
        return int(self.rows.size)


def n_rows(fit: xr.DataTree) -> int:
    """Data rows of ``fit`` (its observed response)."""
    return int(fit["observed_data"][OBS_SITE].size)


def is_subsampled(fit: xr.DataTree) -> bool:
    """Whether :func:`~bayesfric.compare.loo.psis_loo` subsamples ``fit`` (rows above the limit)."""
    return n_rows(fit) > LOO_SUBSAMPLE_ROWS


def subsample_rows(n: int) -> np.ndarray | None:
    """The rows checks read on a data set of ``n`` rows above the limit (None: every row).

    The rows the subsampled PSIS-LOO scores exactly (arviz-stats draws them as
    ``default_rng(SEED).choice(n, LOO_SUBSAMPLE_SIZE, replace=False)``), sorted.
    """
    if n <= LOO_SUBSAMPLE_ROWS:
        return None
    return np.sort(np.random.default_rng(SEED).choice(n, min(LOO_SUBSAMPLE_SIZE, n), replace=False))


def releases_views(fn):
    """Decorate a consumer of a fit (its first argument) that builds views of it (:func:`on_rows`,
    :func:`~bayesfric.inference.pointwise.stored_draws`): when the fit is large (a log-likelihood
    of at least :data:`~bayesfric.limits.CHUNK_NUMBERS` numbers), a garbage collection and a trim
    of the C heap (:func:`~bayesfric.inference.pointwise.trim_memory`) before it runs and after it
    returns. Its numbers are unchanged.

    A view is a ``DataTree``, whose nodes point at their parents: a reference cycle, freed only by
    Python's cyclic collector, which runs on counts of new objects, not of bytes. The float64
    copies the views held (0.16 GB of log-likelihood at 10⁴ rows × 2000 kept draws) lingered: a
    3-law study at 10⁴ rows held 0.3 GB of them entering its weights, and the ranking's prior
    sensitivity (9 power-scaled PSIS-LOO runs) left ~0.1 GB more per run (2026-11-26). Before
    the call: what other stages left, so that the consumer's own peak starts from less.
    """
    @functools.wraps(fn)
    def collected(*args, **kwargs):
        large = bool(args) and _is_large(args[0])
        if large:
            _release()
        try:
            return fn(*args, **kwargs)
        finally:
            if large:
                _release()
    return collected


def _release() -> None:
    gc.collect()
    trim_memory()


def _is_large(fit: Any) -> bool:
    try:
        return fit["log_likelihood"][OBS_SITE].size >= CHUNK_NUMBERS
    except (KeyError, TypeError):
        return False


def on_rows(dt: xr.DataTree, rows: np.ndarray, cast: tuple[str, ...]) -> xr.DataTree:
    """``dt`` on the draws its pointwise groups keep (:func:`stored_draws`), its per-row groups
    restricted to ``rows`` (``cast`` ones in float64, after the restriction: no copy of every row)."""
    view = stored_draws(dt, ()).copy(deep=False)  # never the caller's tree
    for group in ("log_likelihood", "posterior_predictive", "observed_data"):
        if group in view.children:
            part = view[group].to_dataset().isel(obs=rows)
            view[group] = part.astype(np.float64) if group in cast else part
    return view


def rows_summed(dt: xr.DataTree) -> xr.DataTree:
    """``dt`` on the draws its log-likelihood keeps (:func:`stored_draws`), that group replaced by
    its sum over every row per draw, in float64: all that arviz-stats' ``psense`` reads of it.

    psense sums it itself (``to_stacked_array`` over the non-sample dimensions, then ``sum``),
    after :func:`stored_draws` cast every draw × row to float64: three copies of the whole group
    (0.8 GB for 10⁵ rows of a thinned fit). Here the same two calls run on at most
    :data:`~bayesfric.limits.CHUNK_NUMBERS` draws × rows at a time; each draw's sum reads its own
    rows only, so the sums are the ones psense computes, and its own sum over one value per draw
    returns them unchanged.
    """
    view = stored_draws(dt, ()).copy(deep=False)  # never the caller's tree
    ll = view["log_likelihood"].to_dataset()
    per_draw = sum(v.size for v in ll.data_vars.values()) // ll.sizes["draw"]
    step = max(1, CHUNK_NUMBERS // max(1, per_draw))
    parts = [ll.isel(draw=slice(start, start + step)).astype(np.float64)
             .to_stacked_array("latent-obs_var", sample_dims=["chain", "draw"]).sum("latent-obs_var")
             for start in range(0, ll.sizes["draw"], step)]
    view["log_likelihood"] = xr.Dataset({OBS_SITE: xr.concat(parts, dim="draw")})
    return view


def _program(fit: xr.DataTree, program: Program | None, ds: xr.Dataset | None) -> Program | None:
    """The fit's program: given, rebuilt on ``ds``, or from the fit alone (None if it cannot be)."""
    if program is not None:
        return program
    try:
        return program_from_fit(fit, ds) if ds is not None else program_of_fit(fit)
    except (KeyError, ValueError, OSError):  # an unknown law or an old fit: the lpd approximation
        return None


def _plpd(program: Program):
    """arviz-stats' ``log_lik_fn`` for ``method="plpd"``: ``log p(y_i | θ̄)`` of every row at the
    posterior means it is given (only the program's sampled sites; deterministic ones follow)."""
    tr = trace(seed_handler(program.model, 0)).get_trace(**program.model_kwargs)
    latent = [k for k, s in tr.items() if s["type"] == "sample" and not s.get("is_observed", False)]

    def log_lik_fn(observed: xr.DataArray, data) -> np.ndarray:
        point = {k: np.asarray(data.posterior[k].values)[None] for k in latent}
        values = numpyro_log_likelihood(program.model, point, **program.model_kwargs)[OBS_SITE][0]
        return np.asarray(values, dtype=float).reshape(observed.shape)

    return log_lik_fn


@releases_views
def subsample_psis(fit: xr.DataTree, program: Program | None = None, ds: xr.Dataset | None = None):
    """arviz-stats' ``loo_subsample`` of ``fit`` (pointwise) and its :class:`Subsample`.

    Its warning on high Pareto k̂ is held back (:func:`~bayesfric.compare.loo.psis_loo` refits
    those rows or flags the result).
    """
    prog = _program(fit, program, ds)
    method = "plpd" if prog is not None else "lpd"
    size = min(LOO_SUBSAMPLE_SIZE, n_rows(fit))
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Estimated shape parameter of Pareto", category=UserWarning)
        warnings.filterwarnings("ignore", message=".*pointwise.*", category=UserWarning)
        data = azs.loo_subsample(stored_draws(fit, ("log_likelihood",)), size, pointwise=True, var_name=OBS_SITE,
                                 seed=SEED, method=method, log_lik_fn=_plpd(prog) if prog is not None else None)
    rows = np.asarray(data.loo_subsample_observations, dtype=int)
    approx = np.asarray(data.elpd_loo_approx.values, dtype=float).ravel()
    return data, Subsample(rows, int(approx.size), method, approx)


def estimate(fit: xr.DataTree, sub: Subsample, elpd_sub: np.ndarray) -> tuple[float, float, float, float]:
    """``(elpd, se, subsampling_se, p_loo)`` by arviz-stats' difference estimator from the
    subsample's (possibly refitted) pointwise values ``elpd_sub`` (in ``sub.rows`` order).

    ``p_loo`` is the simple-random-sampling estimate of ``Σ_i (lppd_i − elpd_i)`` with ``lppd_i``
    over the draws the fit keeps.
    """
    elpd_sub = np.asarray(elpd_sub, dtype=float).ravel()
    sample = xr.DataArray(elpd_sub, dims=["__obs__"])
    elpd, sub_se, se = sample.azstats.diff_srs_estimator(
        lpd_approx_sample=xr.DataArray(sub.approx[sub.rows], dims=["__obs__"]),
        lpd_approx_all=xr.DataArray(sub.approx, dims=["obs"]), n_data_points=sub.n_rows)
    ll = stored_draws(fit, ())["log_likelihood"][OBS_SITE].isel(obs=sub.rows)
    values = np.asarray(ll.values, dtype=float).reshape((-1, sub.size))
    top = values.max(axis=0)
    lppd = top + np.log(np.mean(np.exp(values - top), axis=0))
    p_loo, _, _ = xr.DataArray(lppd - elpd_sub, dims=["__obs__"]).azstats.srs_estimator(n_data_points=sub.n_rows)
    return float(elpd), float(se), float(sub_se), float(p_loo)


def describe(sub: Subsample, subsampling_se: float) -> str:
    """One line for tables and reports: ``subsampled: n of N rows, subsampling se X (plpd)``."""
    return (f"subsampled: {sub.size} of {sub.n_rows} rows, subsampling se {subsampling_se:.2f} "
            f"({sub.method} approximation of the rest)")
