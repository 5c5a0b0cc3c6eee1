"""Predictions of fitted laws at the rows of a new log, and their scores there.

Per law
    The fit's own program (:func:`bayesfric.model.program_of_fit`: its law, variant, constants,
    noise model) is moved to the new log's rows (:func:`program_on`): its inputs, trajectory
    starts (a stateful law runs along the new log's trajectories from rest, as on the fit's
    data), response and ``response_se``. The law's mean function is evaluated for each posterior
    draw (evenly thinned to at most :data:`MAX_DRAWS`) over every row, in chunks of at most
    ``limits.CHUNK_NUMBERS`` draws × rows (:func:`_mean_draws`, modelled on
    :func:`bayesfric.compare.heldout._means_at`). With partial-pooled group offsets the answer is
    for a *new* group by default (one offset per draw from ``N(0, group_sd)``), or for a named
    group of the fit (its fitted offset). The noise is the program's observation distribution
    (:meth:`bayesfric.model.Program.observation`) at each row, a reduced log's ``se`` added in
    quadrature as the likelihood adds it; AR(1) noise is taken at its stationary marginal
    ``N(mu, σ² / (1 − ρ²))``, not the one-step-ahead conditional its likelihood scores (an
    approximation, stated in the results).
Mixtures
    A law's predictive at a row is the equally weighted mixture of its draws; the model average's
    is the mixture of the laws' draws under the study's weights (:mod:`bayesfric.mixture`, exact:
    no noise is resampled).
Scores
    ``elpd`` (sum and per row: log of the mean over draws of the predictive density of each row),
    the RMS error of the posterior-mean prediction, the share of rows inside the central 50 % and
    90 % bands of the noisy predictive (from each row's PIT value), and the rows scored.
"""

from __future__ import annotations

import dataclasses
import json
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
import xarray as xr

from bayesfric.datasets.loader import OBS_DIM
from bayesfric.datasets.views import law_inputs, response_se, trajectory_starts
from bayesfric.errors import DataError, UserError
from bayesfric.limits import CHUNK_NUMBERS
from bayesfric.mixture import Mixture, curve_mean, curve_quantiles, join, log_density, pit, predictive_quantiles

__all__ = ["MAX_DRAWS", "AVERAGE", "LawPrediction", "check_log", "program_on", "group_labels", "check_group",
           "law_prediction", "prediction_dataset", "score_frame", "METRICS", "envelope_note"]

#: Posterior draws of each law used per row (evenly thinned above it).
MAX_DRAWS = 1000
#: The ``law`` label of the model average.
AVERAGE = "model average"
#: The scores of :func:`score_frame`, in order.
METRICS = ("elpd", "elpd_per_point", "elpd_se", "rms", "coverage_50", "coverage_90", "n")


@dataclass(frozen=True)
class LawPrediction:
    """One law's predictive at the new log's rows: its draws' mixture, the draws used, what it
    answers for (``""``: the law has no group structure) and its noise approximation (``""``: exact)."""

    name: str
    mixture: Mixture
    draws: int
    answer_for: str
    noise_note: str


def check_log(law, ds: xr.Dataset, where: str) -> None:
    """The new log ``ds`` (``where``: its file) gives every input ``law`` reads, and its response,
    if any, is the law's quantity; else a one-line :class:`DataError`."""
    from bayesfric.quantities import QUANTITIES

    have = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
    for name in law.operating_inputs:
        if name not in ds.coords:
            meaning = f" ({QUANTITIES[name].meaning})" if name in QUANTITIES else ""
            raise DataError(f"{where}: no column gives input {name!r}{meaning}, which law {law.name!r} reads "
                            f"(inputs of the log: {', '.join(have) or 'none'})")
    response = ds.attrs.get("response")
    if response is not None and response in ds.data_vars and response != law.response:
        raise DataError(f"{where}: its response is {response}, but law {law.name!r} predicts {law.response}")


def program_on(fit: xr.DataTree, ds: xr.Dataset, where: str):
    """The program of ``fit`` (:func:`bayesfric.model.program_of_fit`) on the rows of ``ds``: the
    fit's law, constants, noise model and group labels with the new log's inputs, trajectory
    starts, response (zeros without one) and standard errors."""
    from bayesfric.model import program_of_fit

    program = program_of_fit(fit)
    check_log(program.law, ds, where)
    n = ds.sizes[OBS_DIM]
    response = ds.attrs.get("response")
    y = np.asarray(ds[response].values, dtype=float) if response in ds.data_vars else np.zeros(n)
    grouped = program.noise.group is not None
    groupings = getattr(program, "groupings", None)  # vary_by levels: the fit's labels, rows not assigned
    moved = {"groupings": {c: dataclasses.replace(g, index=np.zeros(n, dtype=int)) for c, g in groupings.items()}
             } if groupings else {}
    return dataclasses.replace(program, inputs=law_inputs(ds, program.law), response=y,
                               group_index=np.zeros(n, dtype=int) if grouped else None,
                               chain_start=trajectory_starts(ds) if program.noise.kind == "ar1" else None,
                               response_se=response_se(ds), **moved)


def _flat(posterior: xr.Dataset, name: str) -> np.ndarray:
    v = np.asarray(posterior[name].values, dtype=float)
    return v.reshape((v.shape[0] * v.shape[1],) + v.shape[2:])


def _thinned(posterior: xr.Dataset, keep: int) -> xr.Dataset:
    """At most ``keep`` draws, evenly spaced over chains × draws, as one chain."""
    stacked = posterior.stack(sample=("chain", "draw"))
    pick = np.unique(np.linspace(0, stacked.sizes["sample"] - 1, min(keep, stacked.sizes["sample"])).round()
                     .astype(int))
    out = stacked.isel(sample=pick).drop_vars(["sample", "chain", "draw"])
    return out.rename({"sample": "draw"}).expand_dims("chain").transpose("chain", "draw", ...)


def _mean_draws(program, posterior: xr.Dataset, group: str | None = None, seed: int = 0) -> np.ndarray:
    """``(S, n)``: the law's mean function at ``program.inputs`` for each posterior draw, times the
    group offset ``exp(b)`` of a new group (``b ~ N(0, group_sd)`` per draw; ``group=None``) or of
    the named group of the fit, where the program has partial-pooled group offsets."""
    import jax
    import jax.numpy as jnp

    law, n = program.law, program.n_obs
    params = {k: _flat(posterior, k) for k in law.params}
    s = posterior.sizes["chain"] * posterior.sizes["draw"]
    inputs = {k: jnp.asarray(v) for k, v in program.inputs.items()}
    mean = jax.vmap(lambda p: law.mean(inputs, p, program.constants))
    size = max(1, CHUNK_NUMBERS // max(1, n))
    mu = np.concatenate([np.broadcast_to(np.asarray(mean({k: jnp.asarray(v[a:a + size]) for k, v in params.items()}),
                                                    dtype=float), (min(size, s - a), n))
                         for a in range(0, s, size)])
    if program.noise.group is None:
        return mu
    if group is None:
        rng = np.random.default_rng([seed, zlib.crc32(law.name.encode())])
        offset = rng.normal(size=s) * _flat(posterior, "group_sd")
    else:
        labels = [str(g) for g in posterior["group"].values]  # as the fit records them (group_labels)
        offset = _flat(posterior, "group_offset")[:, labels.index(str(group))]
    return mu * np.exp(offset)[:, None]


def _mean_function():
    """:func:`bayesfric.hierarchy.mean_draws` where it exists (group-varying parameters), else
    :func:`_mean_draws` (the noise model's group offsets)."""
    try:
        from bayesfric.hierarchy import mean_draws
    except ImportError:
        return _mean_draws
    return mean_draws


def group_labels(fit: xr.DataTree) -> dict[str, list[str]]:
    """Each group column of ``fit`` (``[noise] group`` offsets, ``vary_by`` parameters) -> its
    levels as the fit records them (empty: the law has no group structure)."""
    from bayesfric.laws.variants import law_of_fit

    post = fit["posterior"]
    columns = [json.loads(fit.attrs["noise"]).get("group")]
    columns += list(getattr(law_of_fit(fit.attrs), "varying", {}).values())  # hierarchical laws
    out = {}
    for column in dict.fromkeys(c for c in columns if c):
        dim = "group" if column == columns[0] else column
        out[column] = [str(g) for g in post[dim].values] if dim in post.coords else []
    return out


def check_group(fits: Mapping[str, xr.DataTree], group: str | None, key: str, where: str) -> None:
    """``group`` (None: a new group) is a level of every fit with groups; else a one-line
    :class:`UserError` under ``key`` listing the levels (or saying that no law has any)."""
    if group is None:
        return
    grouped = {name: levels for name, fit in fits.items() if (levels := group_labels(fit))}
    if not grouped:
        raise UserError(f"{where} has no group structure (no law's parameters or offsets vary by group); "
                        "predictions are for the fitted laws as they are", key)
    for name, levels in grouped.items():
        if not any(str(group) in labels for labels in levels.values()):
            known = "; ".join(f"{c}: {', '.join(labels)}" for c, labels in levels.items())
            raise UserError(f"{group!r} is not a group of the fit of {name} ({known})", key)


def envelope_note(fits: Mapping[str, xr.DataTree], ds: xr.Dataset) -> str:
    """How far the new log's rows lie outside the data the fits were made from, per input, as
    sizing measures a point's distance (:func:`bayesfric.sizing.distance.point_distance`: tested
    ranges beyond the data, each sign against its own side); ``""`` when every row lies inside.

    Examples
    --------
    A log at 0.5–38 rad/s against fits made at 0–4 rad/s gives, for velocity, "38 of 40 rows,
    up to 8.5 tested ranges beyond (the log 0.5 … 38 rad/s, the fits 0 … 4 rad/s)".
    """
    from bayesfric.quantities import QUANTITIES
    from bayesfric.sizing.distance import point_distance

    parts = []
    for name in (k for k, v in ds.coords.items() if v.attrs.get("role") == "input"):
        fitted = [np.asarray(f["constant_data"][name].values, dtype=float).ravel() for f in fits.values()
                  if "constant_data" in f.children and name in f["constant_data"]]
        if not fitted or not (tested := np.concatenate(fitted)).size:
            continue
        x = np.asarray(ds[name].values, dtype=float)
        far = point_distance(x, tested)
        if (far > 0).any():
            unit = QUANTITIES[name].unit if name in QUANTITIES else "SI"
            parts.append(f"{name}: {int((far > 0).sum())} of {x.size} rows, up to {far.max():.3g} tested ranges "
                         f"beyond (the log {x.min():.4g} … {x.max():.4g} {unit}, the fits {tested.min():.4g} … "
                         f"{tested.max():.4g} {unit})")
    return "; ".join(parts)


def _answer_for(fit: xr.DataTree, group: str | None) -> str:
    columns = list(group_labels(fit))
    if not columns:
        return ""
    if group is not None:
        return f"{' / '.join(columns)} {group!r} (its fitted values)"
    return f"a new {' / '.join(columns)} (group terms drawn from the fitted group distribution per draw)"


def law_prediction(name: str, fit: xr.DataTree, ds: xr.Dataset, *, group: str | None = None, seed: int = 0,
                   where: str = "the log") -> LawPrediction:
    """One law's predictive mixture at the rows of ``ds`` (see the module)."""
    import jax.numpy as jnp

    program = program_on(fit, ds, where)
    posterior = _thinned(fit["posterior"].to_dataset(), MAX_DRAWS)
    mu = _mean_function()(program, posterior, group=group, seed=seed)
    s = mu.shape[0]
    values = {k: jnp.asarray(_flat(posterior, k))[:, None] for k in program.noise.sites() if k != "group_sd"}
    obs = program.observation(jnp.asarray(mu), values, program.response_se)

    def per_draw(x):
        x = np.asarray(x, dtype=float)
        return np.broadcast_to(x, np.broadcast_shapes(x.shape, (s, 1)))

    df = per_draw(obs.df) if hasattr(obs, "df") else None
    note = ("AR(1) noise: each row's predictive is the stationary marginal N(mu, sigma^2/(1 - rho^2)), not "
            "conditioned on the log's previous residual (an approximation)" if program.noise.kind == "ar1" else "")
    return LawPrediction(name, Mixture(mu, per_draw(obs.scale), df, np.full(s, 1.0 / s)), s, _answer_for(fit, group),
                         note)


def _average(preds: Sequence[LawPrediction], weights: Mapping[str, float]) -> Mixture | None:
    used = [p for p in preds if weights.get(p.name, 0.0) > 0]
    return join([p.mixture for p in used], [weights[p.name] for p in used]) if used else None


def _mixtures(preds: Sequence[LawPrediction], weights: Mapping[str, float] | None) -> dict[str, Mixture]:
    out = {p.name: p.mixture for p in preds}
    average = _average(preds, weights) if weights is not None else None
    return out | ({AVERAGE: average} if average is not None else {})


def prediction_dataset(preds: Sequence[LawPrediction], ds: xr.Dataset, levels: Sequence[float], *,
                       weights: Mapping[str, float] | None, attrs: Mapping[str, str]) -> xr.Dataset:
    """``mean`` (law, obs), ``curve`` and ``predictive`` quantiles (law, quantile, obs) of every law
    and, with ``weights`` (law -> weight > 0 for the laws averaged), of the model average."""
    mixtures = _mixtures(preds, weights)
    levels = [float(q) for q in levels]
    out = xr.Dataset(
        {"mean": (("law", OBS_DIM), np.array([curve_mean(m) for m in mixtures.values()])),
         "curve": (("law", "quantile", OBS_DIM), np.array([curve_quantiles(m, levels) for m in mixtures.values()])
                   .reshape(len(mixtures), len(levels), ds.sizes[OBS_DIM])),
         "predictive": (("law", "quantile", OBS_DIM),
                        np.array([predictive_quantiles(m, levels) for m in mixtures.values()])
                        .reshape(len(mixtures), len(levels), ds.sizes[OBS_DIM]))},
        coords={"law": list(mixtures), "quantile": levels}
        | {k: v for k, v in ds.coords.items() if v.attrs.get("role") in ("input", "group")},
        attrs=dict(attrs))
    response = ds.attrs.get("response")
    if response in ds.data_vars:
        out["response"] = ds[response]
    out["mean"].attrs["description"] = "posterior mean of the mean curve (SI)"
    out["curve"].attrs["description"] = "quantiles of the mean curve: parameter (and group) uncertainty (SI)"
    out["predictive"].attrs["description"] = "quantiles of a new observation: with the fit's noise model (SI)"
    return out


def _scores(m: Mixture, y: np.ndarray) -> dict[str, float]:
    lpd = log_density(m, y)
    u = pit(m, y)
    n = y.size
    return {"elpd": float(lpd.sum()), "elpd_per_point": float(lpd.mean()),
            "elpd_se": float(np.sqrt(n * lpd.var(ddof=1))) if n > 1 else float("nan"),
            "rms": float(np.sqrt(np.mean((y - curve_mean(m)) ** 2))),
            "coverage_50": float(np.mean((u >= 0.25) & (u <= 0.75))),
            "coverage_90": float(np.mean((u >= 0.05) & (u <= 0.95))), "n": float(n)}


def score_frame(preds: Sequence[LawPrediction], y: np.ndarray, *,
                weights: Mapping[str, float] | None) -> pd.DataFrame:
    """Tidy scores (``law``, ``metric``, ``value``) of every law and of the model average on the
    observed ``y`` (:data:`METRICS`; see the module)."""
    rows = [{"law": name, "metric": metric, "value": value}
            for name, m in _mixtures(preds, weights).items() for metric, value in _scores(m, y).items()]
    return pd.DataFrame(rows, columns=["law", "metric", "value"])
