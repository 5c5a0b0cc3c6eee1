"""Group terms: law parameters that vary between runs, series or units, with partial pooling.

A law made with :meth:`Law.vary_by <bayesfric.laws.base.Law.vary_by>` (study file:
``vary_by = { run = ["T_C", "c_v"] }``) keeps one value of each named parameter ``p`` per level
``g`` of a data column, as brms's ``(1 + ... | run)`` does. The program samples, non-centred:

* ``p``: the *typical* value, with the parameter's declared prior (the median over groups);
* ``p_sd``: the between-group spread on the parameter's unconstrained scale (:func:`hyperprior`);
* one unconstrained value per level of the column, and records ``p_<column>[g] = T(u_g)`` with
  ``u_g ~ Normal(T⁻¹(p), p_sd)`` as a deterministic site,

where ``T`` is numpyro's bijection onto the support of ``p``'s prior: ``exp`` for a positive parameter (so the
levels scatter by a *factor* and stay positive), the identity for a real one (an offset, a
gravity coefficient), a scaled logistic for a bounded one. Each data row then reads its own
level's values. A steady law evaluates elementwise, so the values are gathered per row; a
trajectory (stateful) law integrates along its rows, so it is evaluated once per level (with that
level's values throughout) and each row keeps its level's result: a cost of one law evaluation per
level.

Parametrisation. With few rows per level (or noisy ones) the levels are weakly identified and the
centred form above has a funnel between ``p_sd`` and the levels; the *non-centred* form samples
``p_z[g] ~ Normal(0, 1)`` and sets ``u_g = T⁻¹(p) + p_sd · p_z[g]``. With many rows per level the
opposite holds: each level is pinned by its data, and the non-centred coordinates lie on a curved
ridge (measured on six simulated runs of 20 rows at noise 0.05 N·m: 531 leapfrog steps per draw
and two retries non-centred, 11 centred, the same posterior). A column is sampled non-centred
(site ``p_z``) when its smallest level has fewer than :data:`CENTRED_ROWS` rows, centred (site
``p_u``, the level's unconstrained value) otherwise; the model is the same either way.

Answers for a **new** level (the next run, an unseen unit) draw one ``p_z ~ Normal(0, 1)`` per
posterior draw (:func:`level_values`); answers for a named level use its posterior values. A fold
that holds a whole level out (leave-one-group-out) leaves that level's ``p_z`` at its prior, so the
fold's predictive at those rows is already the new-level predictive.

Example
-------
>>> from bayesfric.laws import get_law
>>> law = get_law("coulomb_viscous").vary_by("run", "T_C")
>>> site_names(law, {"run": Grouping(("a", "b"), np.repeat([0, 1], 3))})
{'T_C': ('T_C_sd', 'T_C_z', 'T_C_run')}
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bayesfric.exported import program_options
from bayesfric.laws.base import Law
from bayesfric.priors import Prior, PriorError
from bayesfric.trend import centred_or_not, coordinates, forecast_u, sample_levels, span

__all__ = ["Grouping", "NEW_LEVEL", "SPREAD", "SPREAD_WIDTH", "TREND_SPREAD", "CENTRED_ROWS", "REAL_SPREAD",
           "hyperprior", "site_names",
           "group_sites", "observed_levels", "centred_or_not", "law_mean", "elementwise", "spread_of", "level_values",
           "mean_draws", "groupings_of", "levels_of"]

#: Label of the one level of a program moved to new points (:meth:`bayesfric.model.Program.at`).
NEW_LEVEL = "new"
#: Prior median of a between-group spread on an unconstrained, dimensionless scale (log or logit):
#: levels that differ from the typical value by about 20 % (:func:`hyperprior`).
SPREAD = 0.2
#: Log-scale sd of the spread's LogNormal prior: 90 % of its mass between SPREAD·e^(∓1.645·0.7),
#: about 6 % and 63 % (:func:`hyperprior`).
SPREAD_WIDTH = 0.7
#: Prior sd of the campaigns' scatter about a trend, on the unconstrained scale (:func:`hyperprior`).
TREND_SPREAD = 0.3
#: Rows of the smallest level from which a column is sampled centred (module docstring).
CENTRED_ROWS = 10
#: Prior median of the spread of a real-valued parameter, as a fraction of its own prior's scale.
REAL_SPREAD = 0.25


@dataclass(frozen=True)
class Grouping:
    """The levels of one group column in a program's data: labels, each row's level, and whether
    the column is sampled centred (module docstring; by default from the rows per level)."""

    labels: tuple[str, ...]
    index: np.ndarray  # (n_obs,) int
    centred: bool | None = None

    def __post_init__(self):
        if self.centred is None:
            counts = np.bincount(np.asarray(self.index, dtype=int), minlength=len(self.labels))
            object.__setattr__(self, "centred", bool(counts.size and counts.min() >= CENTRED_ROWS))

    @property
    def size(self) -> int:
        return len(self.labels)


def groupings_of(law: Law, ds) -> dict[str, Grouping]:
    """The :class:`Grouping` of every column ``law`` varies by, read from the data set ``ds``.

    Raises
    ------
    bayesfric.errors.DataError
        A column is not a coordinate of ``ds``, or not a group column (an input, or levels that
        do not repeat: :func:`bayesfric.datasets.rows.group_problem`).
    """
    from bayesfric.datasets.rows import group_problem
    from bayesfric.errors import DataError

    out = {}
    for column in dict.fromkeys(law.varying.values()):
        if column not in ds.coords:
            raise DataError(f"law {law.name!r} varies by {column!r}, which is not a column of data set "
                            f"{ds.attrs.get('name', '?')!r}", column)
        if problem := group_problem(ds, column):
            raise DataError(f"law {law.name!r} varies by {problem}", column)
        labels, index = levels_of(np.asarray(ds[column].values))
        if column in law.trending.values():
            try:
                coordinates(labels)
            except ValueError as exc:
                raise DataError(f"law {law.name!r} follows a trend over {column!r}: {exc}", column) from None
        out[column] = Grouping(labels, index)
    return out


def levels_of(values: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """Level labels and each row's level: in numeric order where every label is a number (campaigns
    at 500 h before 1000 h), else in text order.

    >>> levels_of(np.array(["b", "a", "b"]))
    (('a', 'b'), array([1, 0, 1]))
    """
    labels, inverse = np.unique(values.astype(str), return_inverse=True)
    try:
        order = np.argsort([float(v) for v in labels], kind="stable")
    except ValueError:
        order = np.arange(labels.size)
    rank = np.empty(labels.size, dtype=int)
    rank[order] = np.arange(labels.size)
    labels, index = labels[order], rank[np.asarray(inverse).reshape(-1)]
    return tuple(str(v) for v in labels), np.asarray(index, dtype=int).reshape(-1)


def spread_of(law: Law, name: str) -> tuple[str, str] | None:
    """(unit, meaning) of a between-group spread site ``<p>_sd`` of ``law``; None for another name.

    On the log (or logit) scale for a positive (or bounded) parameter, so dimensionless; in the
    parameter's own unit for a real-valued one.
    """
    p = name.removesuffix("_sd")
    if not name.endswith("_sd") or p not in law.varying:
        return None
    real = _support(law.params[p].prior) is dist.constraints.real
    scale = "" if real else (" (log scale)" if _support(law.params[p].prior) is dist.constraints.positive
                             else " (logit scale)")
    return (law.params[p].unit if real else "1"), f"spread of {p} between the levels of {law.varying[p]!r}{scale}"


def site_names(law: Law, groupings: Mapping[str, Grouping]) -> dict[str, tuple[str, str, str]]:
    """Parameter -> (spread site, level site: ``p_u`` centred or ``p_z`` non-centred, per-level
    deterministic site ``p_<column>``)."""
    return {p: (f"{p}_sd", f"{p}_{_level_kind(law, p, groupings)}", f"{p}_{col}") for p, col in law.varying.items()}


def _level_kind(law: Law, p: str, groupings: Mapping[str, Grouping]) -> str:
    """``u`` (centred), ``z`` (non-centred) or ``w`` (a centred walk's later levels, :mod:`bayesfric.trend`)."""
    if not groupings[law.varying[p]].centred:
        return "z"
    return "w" if p in law.trending and law.trend_form == "walk" else "u"


def _centred(law: Law, p: str, groupings: Mapping[str, Grouping]) -> bool:
    return _level_kind(law, p, groupings) != "z"


def hyperprior(prior: Prior, name: str, trend: bool = False) -> Prior:
    """Default prior of the between-group spread of a parameter whose prior is ``prior``.

    With ``trend`` (the campaigns' scatter about a trend over service time,
    :mod:`bayesfric.trend`): ``HalfNormal(`` :data:`TREND_SPREAD` ``)`` on the unconstrained scale
    (half a real parameter's prior scale): campaigns of one machine scatter by a few per cent
    about its wear trend, seven or more campaigns inform that scatter, and the forecasts of the
    next campaign and of the time to exceed are calibrated with this prior (``docs/sizing.md``).
    Otherwise (runs, series, units), on a dimensionless unconstrained scale (positive or bounded
    parameters): ``LogNormal(log 0.2, 0.7)``, a median spread of 20 % between runs, 90 % of the
    prior between about 6 % and 63 %; a real-valued parameter (an offset, a gravity coefficient)
    scatters in its own unit: the same shape, median a quarter of its prior's scale, data-scaled.

    Why a prior whose density vanishes at zero spread, not a half-normal or half-Cauchy peaked
    there (Gelman 2006; brms): with two or three levels the data hold one or two degrees of
    freedom about the spread, so its posterior is mostly its prior; peaked at zero, it lets two
    runs that happen to agree collapse the next run's band, and the centred levels form a funnel
    NUTS cannot cross. Measured and argued in ``docs/laws.md`` (group terms) and ``docs/sizing.md``
    (a new run); boundary-avoiding scale priors: Chung et al. 2013.

    Raises
    ------
    PriorError
        A real-valued parameter whose prior has no ``scale`` to size the spread by (give a prior
        for ``<p>_sd``).

    Examples
    --------
    >>> hyperprior(Prior("HalfNormal", scale=2.0), "T_C")
    LogNormal(loc=-1.609, scale=0.7)
    """
    if trend and _support(prior) is not dist.constraints.real:
        return Prior("HalfNormal", scale=TREND_SPREAD)
    if _support(prior) is not dist.constraints.real:
        return Prior("LogNormal", loc=round(math.log(SPREAD), 3), scale=SPREAD_WIDTH)
    if "scale" not in prior.args:
        raise PriorError(f"parameter {name!r} is real-valued with prior {prior}: give a prior for {name}_sd "
                         "(its between-group spread, in its unit)", f"priors.{name}_sd")
    if trend:
        return Prior("HalfNormal", scale=0.5 * float(prior.args["scale"]), scaled_by=dict(prior.scaled_by))
    return Prior("LogNormal", loc=round(math.log(REAL_SPREAD * float(prior.args["scale"])), 6), scale=SPREAD_WIDTH,
                 scaled_by=dict(prior.scaled_by))


def _support(prior: Prior):
    return Prior(prior.dist, **prior.args).to_numpyro(None).support


def _bijection(prior: Prior):
    return dist.biject_to(_support(prior))


def observed_levels(groupings: Mapping[str, Grouping], mask) -> dict[str, Any]:
    """Per column, whether each level has a row in the likelihood ``mask`` (None: every level has)."""
    if mask is None:
        return {}
    rows = jnp.asarray(mask, dtype=jnp.int32)
    return {c: jax.ops.segment_max(rows, jnp.asarray(g.index), num_segments=g.size) > 0 for c, g in groupings.items()}


def group_sites(law: Law, resolved: Mapping[str, Prior], groupings: Mapping[str, Grouping],
                params: Mapping[str, Any], observed: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Inside a numpyro model: sample each varying parameter's spread and levels and return
    ``params`` with every varying parameter replaced by its per-level values ``(G,)``.

    ``observed`` (:func:`observed_levels` of the likelihood mask) makes a centred column's levels
    without data non-centred (:func:`centred_or_not`): a fold that holds a whole level out."""
    out = dict(params)
    for p, (sd_site, level, values_site) in site_names(law, groupings).items():
        column = law.varying[p]
        seen = (observed or {}).get(column, True)
        sd = numpyro.sample(sd_site, resolved[sd_site].to_numpyro())
        t = _bijection(resolved[p])
        if p in law.trending:
            tau = coordinates(groupings[column].labels) / span(coordinates(groupings[column].labels))
            u = sample_levels(resolved[p], law.trend_form, (f"{p}_trend", level, column),
                              resolved.get(f"{p}_trend"), params[p], sd, tau, _centred(law, p, groupings), seen)
            out[p] = numpyro.deterministic(values_site, t(u))
            continue
        with numpyro.plate(column, groupings[column].size):
            if groupings[column].centred:
                u = centred_or_not(level, t.inv(params[p]), sd, seen)
            else:
                u = t.inv(params[p]) + sd * numpyro.sample(level, dist.Normal(0.0, 1.0))
        out[p] = numpyro.deterministic(values_site, t(u))
    return out


def elementwise(law: Law) -> bool:
    """Whether the law's mean at a row reads only that row and scalar parameters (a steady law
    without vector parameters): its varying parameters can then be given per row."""
    return not law.trajectory and not any(p.shape for p in law.params.values())


def law_mean(law: Law, inputs: Mapping[str, Any], params: Mapping[str, Any], constants: Mapping[str, float],
             index: Mapping[str, Any]):
    """The law's mean at every row, each row with its level's values of the varying parameters.

    ``params`` holds per-level values ``(G,)`` of the varying parameters (:func:`group_sites`) and
    scalars of the others; ``index`` maps each column to the rows' levels. One draw, traceable.
    """
    if not law.varying:
        return law.mean(inputs, params, constants)
    if elementwise(law):  # each row reads its level's values
        rows = {p: (jnp.asarray(v)[index[law.varying[p]]] if p in law.varying else v) for p, v in params.items()}
        return law.mean(inputs, rows, constants)
    (column,) = set(law.varying.values())
    level = jnp.asarray(index[column])
    per_level = jax.vmap(lambda values: law.mean(inputs, {**params, **values}, constants))(
        {p: jnp.asarray(params[p]) for p in law.varying})
    per_level = jnp.broadcast_to(per_level, (per_level.shape[0], level.shape[0]))
    return jnp.take_along_axis(per_level, level[None, :], axis=0)[0]


def level_values(law: Law, resolved: Mapping[str, Prior], posterior: Mapping[str, np.ndarray],
                 group: str | None, labels: Mapping[str, tuple[str, ...]], rng: np.random.Generator,
                 service: Mapping[str, float] | None = None, scatter: bool = True) -> dict[str, np.ndarray]:
    """Flat draws ``(S,)`` of every law parameter for one level: a new one (``group=None``: one
    standard-normal draw per posterior draw and parameter) or the named existing level.

    ``posterior`` maps site names to flat draws ``(S, ...)``; ``labels`` each column's level labels.
    A parameter with a trend (:mod:`bayesfric.trend`) is forecast for a new campaign at
    ``service[column]`` (default: the last fitted campaign's coordinate); ``scatter=False`` gives
    the typical campaign there (the trend itself, no campaign-to-campaign scatter).

    Raises
    ------
    KeyError
        ``group`` is not a level of a column the law varies by.
    """
    out = {p: np.asarray(posterior[p], dtype=float) for p in law.params}
    for p in law.varying:
        sd_site, level_site = f"{p}_sd", f"{p}_{law.varying[p]}"
        if group is None and p in law.trending:
            column, t = law.trending[p], _bijection(resolved[p])
            at = (service or {}).get(column, max(coordinates(labels[column])))
            z = rng.normal(size=out[p].shape) if scatter else np.zeros(out[p].shape)
            u = forecast_u(resolved[p], law.trend_form, {**posterior, p: out[p]}, p, column, labels[column], at, z)
            out[p] = np.asarray(t(jnp.asarray(u)), dtype=float)
            continue
        if group is None:
            t = _bijection(resolved[p])
            z = rng.normal(size=out[p].shape) if scatter else np.zeros(out[p].shape)
            out[p] = np.asarray(t(t.inv(jnp.asarray(out[p])) + jnp.asarray(posterior[sd_site]) * z), dtype=float)
            continue
        known = labels[law.varying[p]]
        if group not in known:
            raise KeyError(f"{group!r} is not a level of {law.varying[p]!r}; levels: {', '.join(known)}")
        out[p] = np.asarray(posterior[level_site], dtype=float)[:, known.index(group)]
    return out


def mean_draws(program, posterior, group: str | None = None, seed: int = 0, chunk: int | None = None,
               service: Mapping[str, float] | None = None, scatter: bool = True) -> np.ndarray:
    """The law's mean function at ``program``'s rows for every posterior draw, ``(S, n)``.

    Parameters
    ----------
    program : bayesfric.model.Program
        The fit's program on the rows to predict (:meth:`~bayesfric.model.Program.at`, or
        :func:`~bayesfric.model.program_from_fit` on a new log, whose trajectories a stateful law
        integrates along).
    posterior : xarray.Dataset or mapping
        The fit's posterior (``chain``, ``draw`` first) or flat draws ``(S, ...)`` by site.
    group : str, optional
        Answer for this existing level (run, unit) of the fit's group columns; default a new level:
        varying parameters drawn from the group distribution, and with ``[noise] group`` offsets
        one new multiplicative offset ``exp(N(0, group_sd))`` per draw.
    seed : int
        Seed of the new level's draws.
    chunk : int, optional
        Draws evaluated together (default: at most ``limits.CHUNK_NUMBERS`` draws × rows).
    service : mapping of str to float, optional
        For a law with a trend: the new campaign's service coordinate by column (default: the
        last fitted campaign's).
    scatter : bool
        False: the typical new level (no between-level scatter: the trend itself, or the
        typical value of a group term).

    Examples
    --------
    >>> mu = mean_draws(fit_program.at({"velocity": v}), fit["posterior"])   # doctest: +SKIP
    """
    from bayesfric.limits import CHUNK_NUMBERS

    flat, labels = _flat(posterior), _labels(posterior)
    law, rng = program.law, np.random.default_rng(seed)
    values = level_values(law, program.resolved, flat, group, labels, rng, service, scatter)
    inputs = {k: jnp.asarray(v) for k, v in program.inputs.items()}
    n, s = program.n_obs, len(next(iter(values.values())))
    size = chunk or max(1, CHUNK_NUMBERS // max(1, n))
    mean = jax.jit(jax.vmap(lambda p: law.mean(inputs, p, program.constants)),
                   compiler_options=program_options(n, optimised=False))
    parts = [np.broadcast_to(np.asarray(mean({k: jnp.asarray(v[a:a + size]) for k, v in values.items()}),
                                        dtype=float), (min(size, s - a), n)) for a in range(0, s, size)]
    mu = np.concatenate(parts) if len(parts) > 1 else parts[0].copy()
    if program.noise.group is not None:
        mu = mu * np.exp(_noise_offset(flat, group, labels.get("group", ()), rng))[:, None]
    return mu


def _noise_offset(flat: Mapping[str, np.ndarray], group: str | None, known: tuple[str, ...], rng) -> np.ndarray:
    """Log multiplicative ``[noise] group`` offset per draw: a new level's (from ``group_sd``) or
    the named level's; a level of a ``vary_by`` column only gets a new offset."""
    if group is not None and group in known:
        return np.asarray(flat["group_offset"])[:, known.index(group)]
    return rng.normal(size=len(flat["group_sd"])) * flat["group_sd"]


def _labels(posterior) -> dict[str, tuple[str, ...]]:
    """Each group dimension's level labels, from the posterior's coordinates (none for flat draws)."""
    coords = getattr(posterior, "coords", {})
    return {str(k): tuple(str(v) for v in np.asarray(c.values)) for k, c in coords.items()
            if k not in ("chain", "draw") and not str(k).endswith(("_step",) + tuple(f"_dim_{i}" for i in range(8)))}


def _flat(posterior) -> dict[str, np.ndarray]:
    if hasattr(posterior, "sizes") and "chain" in posterior.sizes:
        s = posterior.sizes["chain"] * posterior.sizes["draw"]
        return {k: np.asarray(v.values).reshape((s,) + v.shape[2:]) for k, v in posterior.data_vars.items()}
    return {k: np.asarray(v) for k, v in posterior.items()}
