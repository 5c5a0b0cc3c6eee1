"""Trends over a service coordinate: law parameters that drift or wear across test campaigns.

A law made with :meth:`Law.trend <bayesfric.laws.base.Law.trend>` (study file:
``trend = { hours = ["T_C", "c_v"] }``, ``trend_form = "linear"``) reads a data column that holds
one number per test campaign: its service coordinate ``t`` (operating hours, cycles, distance).
Each campaign is a level of that column, as in :mod:`bayesfric.hierarchy`, but the levels are
ordered and scatter about a *trend* instead of a constant typical value. With ``T`` the
bijection onto the parameter's support (``exp`` for a positive one), ``τ = t / t_span``
(``t_span``: the largest ``|t|`` of the fitted campaigns, so the trend's prior is data-scaled)
and a level ``g`` at ``τ_g``, the level's unconstrained value ``u_g`` is:

``linear`` (default)
    ``u_g ~ Normal(T⁻¹(m(τ_g)), p_sd)`` with ``m(τ) = p · max(1 + p_trend · τ, 10⁻³)`` for a positive
    parameter (``p_trend``: its relative change over ``t_span``; the floor keeps a falling trend
    positive where it is extrapolated past zero) and ``m(τ) = p + p_trend · τ`` for a real one (an
    offset; ``p_trend`` in its unit). Wear that removes material at a constant rate (Archard)
    raises a friction coefficient about linearly in sliding distance.
``loglinear``
    ``u_g ~ Normal(T⁻¹(p) + p_trend · τ_g, p_sd)``: a constant *factor* per unit of service.
    A bounded parameter's ``linear`` trend is this one (on its logit scale).
``walk``
    A random walk (Brownian motion) on the unconstrained scale, the non-parametric choice:
    ``u_0 = T⁻¹(p)`` at the first campaign and ``u_g = u_{g-1} + p_sd · √(τ_g − τ_{g-1}) · z_g``;
    forecasts widen as the square root of the time since the last campaign. No ``p_trend``.

``p`` is the typical value at ``t = 0`` (``linear``, ``loglinear``) or at the first campaign
(``walk``) and keeps the parameter's declared prior; ``p_trend ~ Normal(0, 1)`` (real: half the
prior's scale, data-scaled); ``p_sd`` has :func:`bayesfric.hierarchy.hyperprior`'s default.
A *new* campaign at ``t`` (a forecast) draws its level from the same distribution
(:func:`forecast_u`); the *typical* campaign (``scatter=False``) is the trend itself, the curve a
time-to-exceed answer follows (:mod:`bayesfric.sizing.exceed`).

Example
-------
>>> coordinates(("0", "1000", "2000"))
array([   0., 1000., 2000.])
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bayesfric.errors import UserError
from bayesfric.priors import Prior

__all__ = ["FORMS", "FLOOR", "coordinates", "span", "support", "trend_prior", "centre", "walk_levels", "paths",
           "centred_or_not",
           "sample_levels", "forecast_u", "trend_of"]

#: Trend forms (module docstring).
FORMS = ("linear", "loglinear", "walk")
#: Smallest factor ``1 + p_trend · τ`` of a positive parameter's linear trend (module docstring).
FLOOR = 1e-3
#: Prior sd of ``p_trend`` for a positive or bounded parameter: a change by a factor e (log) or
#: 100 % (linear) over the fitted span is one prior sd.
TREND_SD = 1.0


def coordinates(labels: Sequence[str]) -> np.ndarray:
    """The service coordinate of each level, from its label (a number).

    Raises
    ------
    ValueError
        A label is not a number.
    """
    try:
        return np.asarray([float(v) for v in labels], dtype=float)
    except ValueError:
        bad = next(v for v in labels if not _is_number(v))
        raise UserError(f"service coordinate {bad!r} is not a number (a trend column holds one number "
                         "per campaign: hours, cycles, distance)") from None


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def span(coords: np.ndarray) -> float:
    """``t_span``: the largest ``|t|`` of the fitted campaigns (1 if all are at 0)."""
    top = float(np.max(np.abs(coords))) if len(coords) else 0.0
    return top if top > 0 else 1.0


def support(prior: Prior):
    """The support of ``prior``'s distribution (positive, real, an interval)."""
    return Prior(prior.dist, **prior.args).to_numpyro(None).support


def trend_prior(prior: Prior, name: str) -> Prior:
    """Default prior of ``<name>_trend`` for a parameter whose prior is ``prior`` (module docstring)."""
    if support(prior) is not dist.constraints.real:
        return Prior("Normal", loc=0.0, scale=TREND_SD)
    return Prior("Normal", loc=0.0, scale=0.5 * float(prior.args.get("scale", 1.0)),
                 scaled_by=dict(prior.scaled_by))


def centre(prior: Prior, form: str, value, slope, tau):
    """The trend's unconstrained value ``T⁻¹(m(τ))`` at ``tau`` (traceable; broadcasts)."""
    kind = support(prior)
    t = dist.biject_to(kind)
    if form == "linear" and kind is dist.constraints.positive:
        return jnp.log(value) + jnp.log(jnp.maximum(1.0 + slope * tau, FLOOR))
    if form == "linear" and kind is dist.constraints.real:
        return value + slope * tau
    return t.inv(value) + slope * tau


def walk_levels(u0, sd, z, tau):
    """Unconstrained values of a random walk's levels at increasing ``tau`` (module docstring)."""
    steps = jnp.sqrt(jnp.maximum(jnp.diff(jnp.asarray(tau), prepend=jnp.asarray(tau)[:1]), 0.0))
    return u0 + sd * jnp.cumsum(steps * z, axis=-1)


def centred_or_not(site: str, mid, sd, observed=True):
    """Sample a plate of levels about ``mid`` with spread ``sd``: centred where a level is
    ``observed`` (its data pin it: the site holds its unconstrained value), non-centred where it is
    not (a level a fold holds out, pinned by nothing: the site holds a standard-normal draw, so the
    held-out level adds no funnel between ``sd`` and it). Same model either way; returns the values."""
    v = numpyro.sample(site, dist.Normal(jnp.where(observed, mid, 0.0), jnp.where(observed, sd, 1.0)))
    return jnp.where(observed, v, mid + sd * v)


def sample_levels(prior: Prior, form: str, sites: tuple[str, str, str], slope_prior: Prior | None, value, sd,
                  tau: np.ndarray, centred: bool, observed=True):
    """Inside a numpyro model: sample ``<p>_trend`` and the levels; return the levels' unconstrained values.

    ``sites``: (trend site, level site, plate name: the column); ``slope_prior`` the trend site's
    resolved prior (None for a walk); ``tau`` the levels' scaled coordinates (strictly increasing).
    A centred walk samples its increments after the first level (site ``<p>_w``, dimension
    ``<column>_step``); a non-centred one their standardised values (``<p>_z``). ``observed`` (per
    level, :func:`bayesfric.hierarchy.observed_levels`): a level without data is sampled
    non-centred even in a centred column (:func:`centred_or_not`).
    """
    trend_site, level_site, plate = sites
    if form == "walk":
        u0 = dist.biject_to(support(prior)).inv(value)
        if centred:  # increments u_g − u_{g−1} ~ Normal(0, sd √Δτ_g), g ≥ 1
            scale = sd * jnp.sqrt(jnp.maximum(jnp.diff(jnp.asarray(tau)), 1e-12))
            with numpyro.plate(f"{plate}_step", len(tau) - 1):
                steps = centred_or_not(level_site, 0.0, scale, jnp.asarray(observed)[1:] if jnp.ndim(observed)
                                       else observed)
            return jnp.concatenate([jnp.reshape(u0, (1,)), u0 + jnp.cumsum(steps)])
        with numpyro.plate(plate, len(tau)):
            z = numpyro.sample(level_site, dist.Normal(0.0, 1.0))
        return walk_levels(u0, sd, z, tau)
    slope = numpyro.sample(trend_site, slope_prior.to_numpyro())
    mid = centre(prior, form, value, slope, jnp.asarray(tau))
    with numpyro.plate(plate, len(tau)):
        if centred:
            return centred_or_not(level_site, mid, sd, observed)
        return mid + sd * numpyro.sample(level_site, dist.Normal(0.0, 1.0))


def forecast_u(prior: Prior, form: str, posterior: Mapping[str, np.ndarray], p: str, column: str,
               labels: Sequence[str], t: float, z: np.ndarray) -> np.ndarray:
    """Unconstrained values ``(S,)`` of parameter ``p`` for a new campaign at service coordinate ``t``.

    ``posterior`` holds flat draws by site (``p``, ``p_sd``, ``p_trend``, the levels ``p_<column>``);
    ``labels`` the fitted campaigns' coordinates; ``z`` one standard-normal draw per posterior draw
    (zeros: the typical campaign, the trend itself). A walk continues from the last fitted campaign
    at or before ``t`` (the first one if ``t`` precedes them all).
    """
    coords = coordinates(labels)
    tau = float(t) / span(coords)
    value, sd = np.asarray(posterior[p], dtype=float), np.asarray(posterior[f"{p}_sd"], dtype=float)
    if form != "walk":
        u = centre(prior, form, jnp.asarray(value), jnp.asarray(posterior[f"{p}_trend"]), tau)
        return np.asarray(u, dtype=float) + sd * z
    order = np.argsort(coords)
    before = [j for j in order if coords[j] <= float(t)] or [int(order[0])]
    j = before[-1]
    bijection = dist.biject_to(support(prior))
    u_last = np.asarray(bijection.inv(jnp.asarray(np.asarray(posterior[f"{p}_{column}"])[:, j])), dtype=float)
    return u_last + sd * np.sqrt(max(tau - coords[j] / span(coords), 0.0)) * z


def paths(prior: Prior, form: str, posterior: Mapping[str, np.ndarray], p: str, column: str,
          labels: Sequence[str], times: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Unconstrained values ``(S, T)`` of ``p`` over increasing service ``times`` after the fitted
    campaigns. ``z`` ``(S, T)``: standard-normal draws. A trend: a new campaign at each time,
    independently (``z = 0``: the trend itself); a walk: one path per draw from the last fitted
    campaign at or before ``times[0]``, its steps ``p_sd · √Δτ · z``.
    """
    times = np.asarray(times, dtype=float)
    if form != "walk":
        return np.stack([forecast_u(prior, form, posterior, p, column, labels, t, z[:, k])
                         for k, t in enumerate(times)], axis=1)
    coords = coordinates(labels)
    start = forecast_u(prior, form, posterior, p, column, labels, times[0], np.zeros(z.shape[0]))
    last = max([c for c in coords if c <= times[0]] or [coords.min()])
    dtau = np.diff(np.concatenate([[last], times])) / span(coords)
    sd = np.asarray(posterior[f"{p}_sd"], dtype=float)[:, None]
    return start[:, None] + sd * np.cumsum(np.sqrt(np.maximum(dtau, 0.0))[None, :] * z, axis=1)


def trend_of(law, name: str) -> tuple[str, str] | None:
    """(unit, meaning) of a trend site ``<p>_trend`` of ``law``; None for another name."""
    p = name.removesuffix("_trend")
    if not name.endswith("_trend") or p not in law.trending:
        return None
    kind = support(law.params[p].prior)
    column, form = law.trending[p], law.trend_form
    if kind is dist.constraints.real:
        return law.params[p].unit, f"change of {p} over the fitted span of {column!r} ({form} trend)"
    if form == "linear" and kind is dist.constraints.positive:
        return "1", f"relative change of {p} over the fitted span of {column!r} (linear trend)"
    return "1", f"change of {p} over the fitted span of {column!r} ({form} trend, unconstrained scale)"
