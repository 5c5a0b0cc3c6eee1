"""Time to exceed: when will friction at an operating point first exceed what the drive can deliver?

For a fit of a law whose parameters follow a trend over a service coordinate (:mod:`bayesfric.trend`),
every posterior draw gives a friction curve over service time at the operating point: the law's
mean (its steady state for a stateful law, :func:`bayesfric.sizing.steady.sizing_law`) with the
trend's parameters at each time. Its first crossing of ``|friction| = capacity`` is that draw's
time to exceed; their distribution gives quantiles and ``P(exceed before t)``.

What the curve is. For a ``linear`` or ``loglinear`` trend it is the *typical* campaign's
friction (the trend itself, without campaign-to-campaign scatter), for a ``walk`` one simulated
path of the walk per draw, continued from the last fitted campaign. The fan also shows where a
*single new campaign* at each time may lie (with the scatter between campaigns). The crossing is
searched on a grid of :data:`GRID` service times from the last fitted campaign to the horizon
(linear interpolation between grid points); a draw that has not crossed by the horizon counts as
"not within the horizon" (``inf``), one already above the capacity at the last campaign crosses
there.

The model-form allowance. Where leave-future-out folds measured how far the law's forecasts of
campaigns it had not seen missed (:func:`bayesfric.sizing.forecast.forecast_miss`), every
draw's curve gets that miss, grown with the reach past the last campaign
(:func:`bayesfric.sizing.forecast.allowance`), before its crossing is found: ``crossing`` is
then the calibrated answer and ``crossing_within`` the trend's own (within-model) one. Without
folds (a single fit) or with folds that failed the gate, both are the within-model answer and
the ``allowance`` attribute says so.

The shape check. The interval assumes the trend's form. Where the fitted campaigns' friction at
the point bends upward away from the trend (accelerating wear against a linear trend: the
crossing comes sooner than forecast), the answer is marked not calibrated for that shape and
leads with a statement saying so (:mod:`bayesfric.sizing.bend`); a downward bend errs safe and
gets one clause. A model average (:func:`combine`) leads with it where every law carrying weight
bends that way.

Example
-------
>>> result = time_to_exceed(fit, {"velocity": "1400 rpm"}, capacity="1.8 N*m", horizon=15000)  # doctest: +SKIP
>>> float(result["crossing_q"].sel(quantile=0.5))                                            # doctest: +SKIP
9120.0
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.exported import program_options
from bayesfric.sizing.bend import law_attrs, lead, point_bend
from bayesfric.sizing.calibration import Miss
from bayesfric.sizing.forecast import allowance, widen_curves
from bayesfric.sizing.points import SizingError, parse_capacity, parse_horizon, parse_value
from bayesfric.sizing.steady import steady_note

__all__ = ["GRID", "QUANTILES", "service_unit", "time_to_exceed", "combine", "crossing_times", "parse_horizon"]

#: Service times on which a crossing is searched.
GRID = 241
#: Quantiles of the crossing time and of the fan.
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


def _points(law, at: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """One operating point, SI, for every operating input of ``law``."""
    out = {}
    for name in law.operating_inputs:
        if name not in at:
            raise SizingError("at", f"law {law.name!r} reads {name!r}, which the point does not give")
        value = at[name]
        out[name] = np.asarray([float(value) if isinstance(value, int | float) else
                                parse_value(value, name, f"at.{name}", allow_range=False).lo])
    return out


def _trend_params(program, flat: Mapping[str, np.ndarray], labels, times: np.ndarray, rng,
                  scatter: bool) -> dict[str, np.ndarray]:
    """Every law parameter's draws over ``times``: ``(S, T)`` for a trending one, ``(S, 1)`` else."""
    import numpyro.distributions as dist

    from bayesfric.trend import paths, support

    law = program.law
    out = {p: np.asarray(flat[p], dtype=float)[:, None] for p in law.params}
    for p, column in law.trending.items():
        z = rng.normal(size=(out[p].shape[0], times.size))
        u = paths(program.resolved[p], law.trend_form, flat, p, column, labels[column], times,
                  z if scatter or law.trend_form == "walk" else np.zeros_like(z))
        out[p] = np.asarray(dist.biject_to(support(program.resolved[p]))(jnp.asarray(u)), dtype=float)
    return out


def friction_curves(fit: xr.DataTree, at: Mapping[str, Any], times: Sequence[float], *, seed: int = 0,
                    scatter: bool = False) -> np.ndarray:
    """Mean friction at the point ``at`` over service ``times`` per posterior draw, ``(S, T)``.

    ``scatter=False``: the typical campaign (a walk's path is random either way); ``True``: a new
    campaign at each time, drawn independently.
    """
    from bayesfric.hierarchy import _flat, _labels
    from bayesfric.model import program_of_fit
    from bayesfric.sizing.steady import sizing_law

    program = program_of_fit(fit)
    law = sizing_law(program.law)
    if not law.trending:
        raise SizingError("", f"law {program.law.name!r} follows no trend over a service coordinate "
                              "(law.trend(column, ...) / trend = { hours = [...] })")
    post = fit["posterior"].to_dataset()
    times = np.asarray(times, dtype=float)
    program = dataclasses.replace(program, law=law).at(_points(law, at))
    flat, labels = _flat(post), _labels(post)
    params = _trend_params(program, flat, labels, times, np.random.default_rng(seed), scatter)
    inputs = {k: jnp.broadcast_to(jnp.asarray(v), (times.size,)) for k, v in program.inputs.items()}
    mean = jax.jit(jax.vmap(lambda p: law.mean(inputs, p, program.constants)),
                   compiler_options=program_options(times.size, optimised=False))
    s = next(iter(flat.values())).shape[0]
    step = max(1, 200_000 // max(times.size, 1))
    parts = [np.asarray(mean({k: jnp.asarray(np.broadcast_to(v[a:a + step], (min(step, s - a), v.shape[1])))
                              for k, v in params.items()})) for a in range(0, s, step)]
    return np.broadcast_to(np.concatenate(parts), (s, times.size)).astype(float)


def crossing_times(curves: np.ndarray, times: np.ndarray, capacity: float) -> np.ndarray:
    """First service time at which ``|curve|`` reaches ``capacity``, per draw (``inf``: not by the
    last time), linearly interpolated between grid points.

    Examples
    --------
    >>> crossing_times(np.array([[1.0, 2.0, 3.0], [1.0, 1.0, 1.0]]), np.array([0.0, 10.0, 20.0]), 2.5)
    array([15., inf])
    """
    y = np.abs(np.asarray(curves, dtype=float))
    above = y >= capacity
    first = np.argmax(above, axis=1)
    out = np.full(y.shape[0], np.inf)
    hit = above.any(axis=1)
    at_start = hit & (first == 0)
    out[at_start] = times[0]
    inner = hit & (first > 0)
    k = first[inner]
    rows = np.nonzero(inner)[0]
    y0, y1 = y[rows, k - 1], y[rows, k]
    frac = np.where(y1 > y0, (capacity - y0) / np.where(y1 > y0, y1 - y0, 1.0), 1.0)
    out[inner] = times[k - 1] + np.clip(frac, 0.0, 1.0) * (times[k] - times[k - 1])
    return out


def _campaigns(fit: xr.DataTree, at: Mapping[str, Any], column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fitted campaigns' coordinates, the quantiles of each one's friction at ``at`` and the
    posterior mean of its ``log |friction|`` there."""
    from bayesfric.hierarchy import mean_draws
    from bayesfric.model import program_of_fit
    from bayesfric.sizing.steady import sizing_law
    from bayesfric.trend import coordinates

    program = program_of_fit(fit)
    law = sizing_law(program.law)
    program = dataclasses.replace(program, law=law).at(_points(law, at))
    post = fit["posterior"].to_dataset()
    labels = [str(v) for v in post[column].values]
    draws = [mean_draws(program, post, group=g)[:, 0] for g in labels]
    values = [np.quantile(d, QUANTILES) for d in draws]
    return coordinates(labels), np.asarray(values), np.asarray([_log_mean(d) for d in draws])


def _log_mean(curves: np.ndarray) -> np.ndarray:
    """Posterior mean of ``log |friction|`` (draws first; floored at the smallest positive float)."""
    return np.mean(np.log(np.maximum(np.abs(curves), np.finfo(float).tiny)), axis=0)


def service_unit(fit: xr.DataTree, column: str) -> str:
    """The unit the fit's data declared for its service coordinate ``column`` (``"h"``), as the fit
    records it with the observations; ``""`` where it records none (a fit made before it did)."""
    if "observed_data" not in fit.children or column not in fit["observed_data"].coords:
        return ""
    return str(fit["observed_data"][column].attrs.get("units", ""))


def time_to_exceed(fit: xr.DataTree, at: Mapping[str, Any], capacity: Any, horizon: Any, *, seed: int = 0,
                   unit: str = "", grid: int = GRID, miss: Miss | None = None, why_none: str = "") -> xr.Dataset:
    """When friction at the operating point ``at`` first exceeds ``capacity``, per posterior draw.

    Parameters
    ----------
    fit : xarray.DataTree
        A fit of a law with a trend over a service coordinate (:meth:`Law.trend
        <bayesfric.laws.base.Law.trend>`).
    at : mapping
        Every operating input the law reads: SI numbers or texts with units (``"1400 rpm"``).
    capacity : str, (number, unit) or float
        The drive's torque or force (SI if a number).
    horizon : str or float
        The latest service time to look at (``"20000 h"``, or a number in the coordinate's unit).
    seed : int
        Seed of a walk's paths and of the new campaigns' scatter.
    unit : str
        The service coordinate's unit (the data column's), to convert ``horizon`` into; default
        the one the fit records (:func:`service_unit`). Where neither is known, a horizon with a
        unit is refused (it cannot be converted) and a plain number is taken in the column's unit.
    grid : int
        Service times searched between the last campaign and the horizon.
    miss : Miss, optional
        The law's forecast miss on leave-future-out folds
        (:func:`bayesfric.sizing.forecast.forecast_miss`): the model-form allowance.
    why_none : str
        Without ``miss``: why none was measured (stated in the answer).

    Returns
    -------
    xarray.Dataset
        ``crossing`` (draw): each draw's time to exceed (``inf``: not by the horizon), with the
        model-form allowance where ``miss`` is given; ``crossing_q`` (quantile); ``crossing_within``
        and ``crossing_within_q``: the same without the allowance; ``allowance`` (service): its
        relative sd; ``p_exceed`` (service): P(crossed by t); ``fan`` and ``fan_new``
        (quantile, service): the typical campaign's and a new campaign's friction; ``campaign_q``
        (campaign, quantile): each fitted campaign's; ``curve`` and ``curve_new`` (draw, service):
        the typical and the new campaigns' curves (drop them before storing). Attrs say what the answer is for;
        ``bend``, ``bend_test``, ``shape_calibrated`` and ``statement`` whether the campaign levels bend
        away from the trend at the point (:mod:`bayesfric.sizing.bend`): an upward bend marks the
        interval not calibrated for that shape (``shape_calibrated = 0``), its ``statement`` first.

    Raises
    ------
    SizingError
        The law follows no trend, the point misses an input, a bad capacity or horizon.

    Examples
    --------
    >>> out = time_to_exceed(fit, {"velocity": "1400 rpm"}, "1.8 N*m", "15000 h", unit="h")  # doctest: +SKIP
    >>> out["p_exceed"].sel(service=10000, method="nearest")                                 # doctest: +SKIP
    """
    from bayesfric.model import program_of_fit
    from bayesfric.sizing.steady import sizing_law
    from bayesfric.trend import coordinates

    fitted = program_of_fit(fit).law
    law = sizing_law(fitted)
    if not law.trending:
        raise SizingError("", f"law {fitted.name!r} follows no trend over a service coordinate")
    column = next(iter(law.trending.values()))
    cap = float(capacity) if isinstance(capacity, int | float) else parse_capacity(capacity, law.response).lo
    unit = unit or service_unit(fit, column)
    end = parse_horizon(horizon, unit)
    last = float(coordinates([str(v) for v in fit["posterior"][column].values]).max())
    if end <= last:
        raise SizingError("horizon", f"{horizon!r} is not after the last fitted campaign ({last:g} {unit})".rstrip())
    coords = coordinates([str(v) for v in fit["posterior"][column].values])
    times = np.linspace(last, end, grid)
    rel = allowance(miss, times, first=float(coords.min()), last=last)
    rng = np.random.default_rng(seed + 2)
    within = friction_curves(fit, at, times, seed=seed)
    curve = widen_curves(within, rel, rng)
    new = widen_curves(friction_curves(fit, at, times, seed=seed + 1, scatter=True), rel, rng)
    crossing, crossing_within = crossing_times(curve, times, cap), crossing_times(within, times, cap)
    where, campaign_q, campaign_log = _campaigns(fit, at, column)
    bend = point_bend(where, campaign_log, None if fitted.trend_form == "walk" else
                      _log_mean(friction_curves(fit, at, where, seed=seed)))
    return xr.Dataset(
        {"crossing": ("draw", crossing),
         "crossing_q": ("quantile", np.quantile(crossing, QUANTILES, method="inverted_cdf")),
         "crossing_within": ("draw", crossing_within),
         "crossing_within_q": ("quantile", np.quantile(crossing_within, QUANTILES, method="inverted_cdf")),
         "allowance": ("service", rel),
         "p_exceed": ("service", (crossing[:, None] <= times[None, :]).mean(axis=0)),
         "fan": (("quantile", "service"), np.quantile(np.abs(curve), QUANTILES, axis=0)),
         "fan_new": (("quantile", "service"), np.quantile(np.abs(new), QUANTILES, axis=0)),
         "campaign_q": (("campaign", "quantile"), np.abs(campaign_q)), "curve": (("draw", "service"), curve),
         "curve_new": (("draw", "service"), new)},
        coords={"service": times, "quantile": list(QUANTILES), "campaign": where},
        attrs={"law": fitted.name, "capacity": cap, "horizon": end, "column": column, "unit": unit,
               "form": fitted.trend_form, "at": repr(dict(at)), "response": law.response,
               "steady": steady_note(fitted, law), "allowance": _allowance_note(miss, rel, why_none, unit),
               "curve": ("one simulated path of the random walk per draw" if fitted.trend_form == "walk" else
                         "the typical campaign: the trend itself, without campaign-to-campaign scatter"),
               "p_within_horizon": float(np.isfinite(crossing).mean()), **law_attrs(bend, fitted.trend_form)})


def _allowance_note(miss: Miss | None, rel: np.ndarray, why_none: str, unit: str) -> str:
    """What the model-form allowance is, in one sentence."""
    if miss is None:
        return "none: " + (why_none or "no leave-future-out folds measured this law's forecasts") + \
            "; the answer is the trend's own (within-model)"
    if miss.rate <= 0:
        return (f"measured, zero: the leave-future-out forecasts ({miss.n} rows) missed within their own bands "
                f"(miss {miss.beta:.3g} ± {miss.se:.3g} per {unit or 'unit'}²)")
    return (f"from the leave-future-out misses ({miss.n} rows, rate {miss.rate:.3g} per {unit or 'unit'}²): "
            f"relative sd {rel[0]:.1%} at the last campaign, {rel[-1]:.1%} at the horizon")


def combine(results: Mapping[str, xr.Dataset], weights: Mapping[str, float], seed: int = 0) -> xr.Dataset:
    """The weighted mixture of several laws' :func:`time_to_exceed` answers (same times).

    Each law contributes draws in proportion to its weight (resampled, seeded: the crossing
    times, both fans); ``p_exceed`` is the weighted mean of the laws' (exact), the fitted
    campaigns' quantiles the weighted mean of the laws' (approximate: they differ little between
    laws fitted to the same campaigns). Laws with zero weight are left out.
    """
    names = [n for n in results if weights.get(n, 0.0) > 0]
    if not names:
        raise UserError("no law with a positive weight to combine", "weights")
    w = np.asarray([weights[n] for n in names], dtype=float)
    w = w / w.sum()
    rng = np.random.default_rng(seed)
    size = max(results[n].sizes["draw"] for n in names)
    picks = rng.choice(len(names), size=size, p=w)
    draws = [results[n]["crossing"].values[rng.integers(0, results[n].sizes["draw"], (picks == i).sum())]
             for i, n in enumerate(names)]
    rows = [rng.integers(0, results[n].sizes["draw"], (picks == i).sum()) for i, n in enumerate(names)]
    curve = np.concatenate([results[n]["curve"].values[r] for n, r in zip(names, rows, strict=True)])
    new = np.concatenate([results[n]["curve_new"].values[r] for n, r in zip(names, rows, strict=True)])
    crossing = np.concatenate(draws)
    within = np.concatenate([results[n]["crossing_within"].values[r] for n, r in zip(names, rows, strict=True)])
    first = results[names[0]]
    return first.copy(data={
        "crossing": crossing, "crossing_q": np.quantile(crossing, QUANTILES, method="inverted_cdf"),
        "crossing_within": within, "crossing_within_q": np.quantile(within, QUANTILES, method="inverted_cdf"),
        "allowance": sum(wi * results[n]["allowance"].values for wi, n in zip(w, names, strict=True)),
        "p_exceed": sum(wi * results[n]["p_exceed"].values for wi, n in zip(w, names, strict=True)),
        "fan": np.quantile(np.abs(curve), QUANTILES, axis=0),
        "fan_new": np.quantile(np.abs(new), QUANTILES, axis=0),
        "campaign_q": sum(wi * results[n]["campaign_q"].values for wi, n in zip(w, names, strict=True)),
        "curve": curve, "curve_new": new}).assign_attrs(
            law="model average", weights=repr(dict(zip(names, w.round(4), strict=True))),
            allowance="each law's own (a mixture of the laws' widened curves; the allowance variable is their "
                      "weighted mean)",
            p_within_horizon=float(np.isfinite(crossing).mean()), **lead(results, dict(zip(names, w, strict=True))))


def forecast_weights(tree: xr.DataTree) -> tuple[dict[str, float], str]:
    """The weights a time-to-exceed average uses, from a study's ``/weights`` node: stacking on its
    leave-future-out scheme (how well each law forecast the campaigns it had not seen), else on
    LOO; and the weighting's name."""
    node = tree["weights"].to_dataset()
    names = [str(w) for w in node["weighting"].values]
    label = next((w for w in names if w.startswith("stacking leave-future-")), "stacking LOO")
    if label not in names:
        return {}, label
    values = node["weight"].sel(weighting=label).values
    return {str(law): float(v) for law, v in zip(node["law"].values, values, strict=True) if np.isfinite(v)}, label


def answer_study(questions: Sequence[Any], fits: Mapping[str, xr.DataTree], tree: xr.DataTree, *, unit: str = "",
                 seed: int = 0, misses: Mapping[str, tuple[Miss | None, str]] | None = None) -> xr.DataTree:
    """Every time-to-exceed question of a study (``[[sizing]]`` with ``horizon``), per law with a
    trend and as their weighted average (:func:`forecast_weights`), as one DataTree: ``q<i>/<law>``
    and ``q<i>/average`` (each :func:`time_to_exceed`'s Dataset without its curves). Laws without a
    trend are listed in ``q<i>``'s attrs (``no_trend``): they cannot forecast service time.
    ``misses``: law -> (its forecast miss or None, why none), the model-form allowance
    (:func:`bayesfric.sizing.forecast.study_misses`)."""
    from bayesfric.laws.variants import law_of_fit

    weights, basis = forecast_weights(tree)
    nodes = {}
    for i, q in enumerate(questions):
        at = {k: v.lo for k, v in q.at.items()}
        trending = {n: f for n, f in fits.items() if law_of_fit(f.attrs).trending}
        results = {n: time_to_exceed(f, at, q.capacity.lo, q.horizon, seed=seed, unit=unit,
                                     miss=(misses or {}).get(n, (None, ""))[0],
                                     why_none=(misses or {}).get(n, (None, ""))[1])
                   for n, f in trending.items()}
        used = {n: weights.get(n, 0.0) for n in results}
        average = combine(results, used, seed=seed) if sum(used.values()) > 0 else None
        shape = average.attrs if average is not None else lead(results, {n: 1.0 for n in results})
        nodes[f"q{i}"] = xr.Dataset(attrs={
            "label": q.label, "point": q.describe(), "capacity": q.capacity.text, "horizon": q.horizon,
            "unit": unit, "weighting": basis, "weights": repr({n: round(w, 4) for n, w in used.items()}),
            "no_trend": ", ".join(n for n in fits if n not in trending),
            **{k: shape[k] for k in ("bend", "shape_calibrated", "statement")}})
        for name, result in results.items():
            nodes[f"q{i}/{name}"] = result.drop_vars(["curve", "curve_new"]).assign_attrs(weight=used[name])
        if average is not None:
            nodes[f"q{i}/average"] = average.drop_vars(["curve", "curve_new"])
    return xr.DataTree.from_dict(nodes)
