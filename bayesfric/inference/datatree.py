"""Assemble one arviz DataTree from constrained posterior draws, whatever sampler made them."""

from __future__ import annotations

import json
from functools import cache, partial
from importlib.metadata import version
from typing import Any

import arviz_base
import jax
import numpy as np
import xarray as xr
from numpyro.handlers import substitute, trace
from numpyro.infer import Predictive, log_likelihood

from bayesfric.datasets.loader import OBS_DIM
from bayesfric.exported import program_jit
from bayesfric.inference import modes, pointwise
from bayesfric.inference.diagnostics import check
from bayesfric.model import OBS_SITE, Program, program_data, program_record

__all__ = ["assemble", "provenance", "log_prior_draws", "draw_tables_jit", "tables_jit", "draw_tables_args"]

#: Prior (and prior predictive) draws stored with every fit.
N_PRIOR = 500


def _flatten(samples: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: np.asarray(v).reshape((-1,) + np.shape(v)[2:]) for k, v in samples.items()}


def _chains(flat: dict[str, Any], n_chains: int) -> dict[str, np.ndarray]:
    return {k: np.asarray(v).reshape((n_chains, -1) + np.shape(v)[1:]) for k, v in flat.items()}


@cache
def _versions() -> str:
    """The versions a fit records, read once per process (``importlib.metadata`` scans the
    installed distributions: about 2 ms a package, 10 ms a fit)."""
    return json.dumps({p: version(p) for p in ("bayesfric", "numpyro", "jax", "arviz", "emcee")})


def provenance(program: Program, ds: xr.Dataset, sampler: str, settings: dict, seed: int) -> dict:
    """Provenance attrs stored on every fit (strings and numbers only, NetCDF-safe)."""
    return {
        **program_record(program),  # what rebuilds the program (bayesfric.model.program_of_fit)
        "dataset": str(ds.attrs.get("name", "")),
        "data_provenance": str(ds.attrs.get("provenance", "")),
        "data_source": str(ds.attrs.get("source", "")),
        "data_hash": str(ds.attrs.get("data_hash", "")),
        "data_selection": str(ds.attrs.get("selection", "")),
        "sampler": sampler,
        "sampler_settings": json.dumps(settings),
        "seed": int(seed),
        "versions": _versions(),
    }


def log_prior_draws(program: Program, flat: dict[str, Any], compiled: bool = True) -> dict[str, Any]:
    """Per-draw log prior density of every sampled latent site (summed over its elements).

    ``flat`` holds constrained draws shaped (n, ...). The densities are of the constrained
    parameters, as declared (no Jacobian): what power-scaling sensitivity (``psense``) scales.
    ``compiled=False`` returns JAX arrays, for use inside a traced function.
    """
    kwargs = program.model_kwargs

    def one(params):
        tr = trace(substitute(program.model, data=params)).get_trace(**kwargs)
        return {name: site["fn"].log_prob(site["value"]).sum()
                for name, site in tr.items()
                if site["type"] == "sample" and not site["is_observed"]}

    tables = jax.vmap(one)(flat)
    return {k: np.asarray(v) for k, v in tables.items()} if compiled else tables


def _draw_tables(program: Program, n_prior: int, flat: dict, key_pp, key_prior):
    """Pointwise log-likelihood, log prior per site, posterior predictive and prior draws."""
    kwargs = program.model_kwargs
    pp_kwargs = dict(kwargs, response=None)
    ll = log_likelihood(program.model, flat, parallel=True, **kwargs)[OBS_SITE]
    log_prior = log_prior_draws(program, flat, compiled=False)
    pp = Predictive(program.model, posterior_samples=flat, return_sites=[OBS_SITE], parallel=True)(key_pp, **pp_kwargs)
    prior = Predictive(program.model, num_samples=n_prior, parallel=True)(key_prior, **pp_kwargs)
    return ll, log_prior, pp, prior


def draw_tables_jit(program: Program, n_prior: int = N_PRIOR):
    """The one compiled program of a fit's per-draw tables (see :func:`_draw_tables`)."""
    return program_jit(program, f"draw_tables n_prior={n_prior}", partial(_draw_tables, program, n_prior))


def tables_jit(program: Program, info: pointwise.Storage):
    """The compiled tables of a fit with pointwise storage ``info``: :func:`draw_tables_jit`
    (every draw) or :func:`bayesfric.inference.pointwise.thinned_tables_jit`."""
    return draw_tables_jit(program, info.n_prior) if info.full else pointwise.thinned_tables_jit(program, info)


def draw_tables_args(site_shapes: dict[str, Any], n_draws: int, seed: int) -> tuple:
    """Example arguments of :func:`draw_tables_jit` (for compiling ahead): ``n_draws`` draws of
    every site, ``site_shapes`` giving one draw's shape and dtype per site."""
    flat = {k: jax.ShapeDtypeStruct((n_draws,) + tuple(v.shape), v.dtype) for k, v in site_shapes.items()}
    key = jax.random.PRNGKey(seed + 1)
    return flat, key, key


def assemble(
    program: Program,
    ds: xr.Dataset,
    samples: dict[str, np.ndarray],
    sample_stats: dict[str, np.ndarray],
    *,
    sampler: str,
    settings: dict,
    seed: int,
    n_prior: int = N_PRIOR,
    tables: Any = None,
) -> xr.DataTree:
    """Build the fit's DataTree: posterior, sample_stats, log_likelihood, log_prior,
    posterior_predictive, prior, prior_predictive, observed_data, constant_data, with provenance
    and the gate verdict. A fit whose chains each sampled their own mode well is combined by
    stacking (:func:`bayesfric.inference.modes.resolve`): its draws are then the combined draws,
    its verdict multimodal, and the chains as sampled are kept as ``posterior_chains``.

    ``samples`` are constrained draws shaped (chain, draw, ...); every latent site of the
    program must be present. ``tables`` is the program's compiled tables for this fit's
    :func:`~bayesfric.inference.pointwise.storage` (:func:`tables_jit`), when the caller
    already has it compiling.

    What the pointwise groups (log_likelihood, posterior_predictive, prior_predictive) keep
    follows :func:`bayesfric.inference.pointwise.storage`: every draw in float64 for small fits,
    thinned draws (float32 where the numbers allow) above ``pointwise.FULL_NUMBERS``, recorded
    in ``attrs["pointwise_storage"]``.
    """
    n_chains, n_draws = next(iter(samples.values())).shape[:2]
    flat = _flatten(samples)
    info = pointwise.storage(program.n_obs, n_chains, n_draws, n_prior)
    ll, log_prior, pp, prior, prior_pred, dtypes = _tables(program, info, flat, seed, tables)
    # posterior keeps sampled + derived sites; drop nothing the sampler returned
    posterior = {k: v for k, v in samples.items()}
    for name, value in program.law.derived_values({k: flat[k] for k in program.law.params}).items():
        posterior.setdefault(name, np.asarray(value).reshape((n_chains, -1) + np.shape(value)[1:]))

    obs = np.arange(program.n_obs)
    constant = {k: np.asarray(v, dtype=float) for k, v in program.inputs.items()} | program_data(program)
    dims = {OBS_SITE: [OBS_DIM], **{k: [OBS_DIM] for k in constant}}
    dims.update(program.site_dims())
    coords: dict[str, Any] = {OBS_DIM: obs}
    coords |= {c: list(g.labels) for c, g in program.groupings.items()}  # vary_by columns' levels
    if program.noise.group is not None:
        dims.update(group_index=[OBS_DIM])
        coords["group"] = [str(g) for g in program.group_labels]
        constant["group_index"] = np.asarray(program.group_index)
    dt = arviz_base.from_dict(
        {
            "posterior": posterior,
            "sample_stats": sample_stats,
            "log_likelihood": {OBS_SITE: np.asarray(ll).reshape((n_chains, -1, program.n_obs))},
            "posterior_predictive": _chains({OBS_SITE: pp[OBS_SITE]}, n_chains),
            "prior": {k: np.asarray(v)[None] for k, v in prior.items()},
            "prior_predictive": {k: np.asarray(v)[None] for k, v in prior_pred.items()},
            "observed_data": {OBS_SITE: program.response},
            "constant_data": constant,
        },
        dims=dims,
        coords=coords,
    )
    _finish(dt, program, ds, info, log_prior, n_chains)
    dt.attrs.update(provenance(program, ds, sampler, settings, seed))
    dt.attrs["pointwise_storage"] = info.to_json(dtypes)
    # chains that each sampled their own mode well are combined by stacking, not failed (modes)
    verdict = check(dt)
    if not verdict.passed:
        dt, verdict = modes.resolve(dt, verdict, seed)
    dt.attrs["diagnostics"] = verdict.to_json()
    return dt


def _tables(program: Program, info, flat: dict, seed: int, tables: Any) -> tuple:
    """The per-draw tables of a fit: log-likelihood, log prior, posterior predictive, prior draws,
    prior predictive and the dtypes kept (whole, or thinned in chunks: :mod:`.pointwise`)."""
    key_pp, key_prior = jax.random.split(jax.random.PRNGKey(seed + 1))
    tables = tables_jit(program, info) if tables is None else tables
    if info.full:  # one compiled program for every per-draw table (it used to be three scans, compiled apart)
        ll, log_prior, pp, prior = tables(flat, key_pp, key_prior)
        prior_pred = {OBS_SITE: prior.pop(OBS_SITE)}
        return ll, log_prior, pp, prior, prior_pred, dict.fromkeys(pointwise.GROUPS, "float64")
    # thinned, in chunks: memory bounded whatever draws × rows
    (ll, log_prior, pp, prior, prior_pp), dtypes = pointwise.thinned_tables(program, info, flat, key_pp,
                                                                            key_prior, tables)
    return ll, log_prior, {OBS_SITE: pp}, prior, {OBS_SITE: prior_pp}, dtypes


def _finish(dt: xr.DataTree, program: Program, ds: xr.Dataset, info, log_prior: dict, n_chains: int) -> None:
    """Thinned groups' draw indices, the log prior per site, the data's group coordinates and the
    response's quantity and units, set on ``dt`` in place."""
    if not info.full:  # the kept draws keep their own indices: the groups line up with the posterior
        for group in ("log_likelihood", "posterior_predictive"):
            dt[group] = dt[group].to_dataset().assign_coords(draw=info.draw_index())
    # one log density per site and draw: built without the site dims of vector-valued parameters
    dt["log_prior"] = arviz_base.from_dict({"log_prior": _chains(log_prior, n_chains)})["log_prior"]
    # group coordinates of the data (series, run ...) travel with the observations
    for name, coord in ds.coords.items():
        if coord.attrs.get("role") == "group":
            units = {"units": coord.attrs["units"]} if "units" in coord.attrs else {}  # a service time's (h)
            dt["observed_data"] = dt["observed_data"].to_dataset().assign_coords(
                {name: (OBS_DIM, np.asarray(coord.values).astype(str), units)}
            )
    dt["observed_data"].attrs.update(
        {"quantity": ds.attrs.get("response", ""), "units": ds[ds.attrs["response"]].attrs.get("units", "")}
    )
