"""Law + noise model + priors + dataset -> one numpyro program.

Every law becomes the same program shape, so fits compare across laws:

* one sample site per law parameter (named as declared), derived quantities as deterministics;
* noise parameters ``sigma`` (normal, student_t), ``nu`` (student_t), ``sigma_rel`` and
  ``sigma_floor`` (proportional), or ``sigma`` (innovation sd) and ``rho`` (ar1: AR(1) residuals
  along each trajectory, :mod:`bayesfric.noise`);
* optional per-group multiplicative offsets ``group_offset`` with scale ``group_sd`` (partial
  pooling, non-centred): ``mu_i = law(x_i) * exp(b_g[i])``, ``b_g ~ Normal(0, group_sd)``. A
  multiplicative offset keeps odd symmetry and the sign of friction, and reads as "this series
  runs a few per cent high";
* group terms of a law made with ``vary_by`` (:mod:`bayesfric.hierarchy`): per varying parameter
  ``p`` a spread ``p_sd``, standard-normal levels ``p_z`` and the levels' values ``p_<column>``;
* the observation site is always ``response`` over the plate/dimension ``obs``.

Data with a standard error per row (a reduced data set: segment means of a raw log,
:mod:`bayesfric.datasets.reduce`, whose ``se`` column is :attr:`Program.response_se`): the
likelihood of row i adds the measured ``se_i`` to the noise model in quadrature, e.g.
``y_i ~ Normal(mu_i, sqrt(sigma^2 + se_i^2))`` (student_t: the same scale; proportional:
``(sigma_rel mu_i)^2 + sigma_floor^2 + se_i^2``). ``se_i`` is how well the segment pinned its own
mean (within-segment noise, autocorrelation included); ``sigma`` keeps its prior and now reads as
the scatter of the segment means about the law -- the law's misfit and what changes from segment
to segment -- which within-segment noise cannot measure, so it is *not* divided by the count.
Predictions at new operating points (sizing, held-out summaries) use the noise model alone.
Noise ``ar1`` is refused on such data (its rows are independent means, not a trajectory).

The likelihood may be masked by a 0/1 ``mask`` *passed as data*, so cross-validation folds reuse
one compiled program (see :mod:`bayesfric.compare`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
import xarray as xr

from bayesfric.datasets.loader import OBS_DIM, DataError
from bayesfric.datasets.views import data_scale, law_inputs, response_se, response_values, trajectory_starts
from bayesfric.density import OBS_SITE, Density, build_density
from bayesfric.errors import UserError
from bayesfric.hierarchy import (
    NEW_LEVEL,
    Grouping,
    group_sites,
    groupings_of,
    hyperprior,
    law_mean,
    observed_levels,
    site_names,
)
from bayesfric.laws.base import TRAJECTORY_START, Law, SampledAs
from bayesfric.laws.plugins import law_files
from bayesfric.laws.variants import for_data, law_of_fit
from bayesfric.noise import AR1Residuals
from bayesfric.priors import DataScale, Prior, PriorError, rescaled, resolve_all
from bayesfric.runtime import configure
from bayesfric.studentt import StudentT
from bayesfric.trend import trend_prior

__all__ = ["Noise", "Program", "build_program", "program_from_fit", "program_of_fit", "program_record", "OBS_SITE",
           "NOISE_PRIORS"]


#: Default priors of the noise-model parameters (data-scaled where they carry the response unit).
NOISE_PRIORS: dict[str, Prior] = {
    "sigma": Prior("HalfNormal", scale=0.1, scaled_by={"response": 1}),
    "nu": Prior("Gamma", concentration=2.0, rate=0.1),  # Juárez & Steel (2010) prior on t dof
    "sigma_rel": Prior("HalfNormal", scale=0.1),  # relative scatter, dimensionless
    "sigma_floor": Prior("HalfNormal", scale=0.01, scaled_by={"response": 1}),
    "group_sd": Prior("HalfNormal", scale=0.1),  # relative spread between groups
    "rho": Prior("Uniform", low=-1.0, high=1.0),  # AR(1) lag-one correlation: whole stationary range
}
_NOISE_SITES = {
    "normal": ("sigma",),
    "student_t": ("sigma", "nu"),
    "proportional": ("sigma_rel", "sigma_floor"),
    "ar1": ("sigma", "rho"),
}


@dataclass(frozen=True)
class Noise:
    """Observation noise model.

    Parameters
    ----------
    kind : {"normal", "student_t", "proportional", "ar1"}
        ``proportional`` uses ``sd_i = sqrt((sigma_rel * mu_i)^2 + sigma_floor^2)``; the floor
        keeps the density finite where the mean crosses zero. ``ar1``: Gaussian residuals with
        lag-one correlation ``rho`` along each ordered trajectory of the data (stationary start,
        innovation sd ``sigma``); its pointwise log-likelihood is the conditional
        ``log p(y_t | y_<t)`` (:mod:`bayesfric.noise`).
    group : str, optional
        Name of a group coordinate for hierarchical multiplicative offsets.
    sigma : float, optional
        Known noise standard deviation in SI units (e.g. from a sensor datasheet) for
        ``kind="normal"``; then ``sigma`` is a constant, not a sampled site.
    """

    kind: Literal["normal", "student_t", "proportional", "ar1"] = "normal"
    group: str | None = None
    sigma: float | None = None

    def __post_init__(self):
        if self.kind not in _NOISE_SITES:
            raise UserError(f"noise kind {self.kind!r} not one of {tuple(_NOISE_SITES)}")
        if self.sigma is not None and (self.kind != "normal" or not self.sigma > 0):
            raise UserError("a known sigma needs kind='normal' and sigma > 0")

    def sites(self) -> tuple[str, ...]:
        base = () if self.sigma is not None else _NOISE_SITES[self.kind]
        return base + (("group_sd",) if self.group else ())


@dataclass(frozen=True)
class Program:
    """A law bound to a dataset: the numpyro model plus the arrays it runs on.

    ``model(**model_kwargs)`` is the full-data program; pass ``mask=`` to train on a subset and
    ``response=None`` to sample predictions. Frozen: a program on other data or points is a new
    one (``dataclasses.replace(program, response=...)``, :meth:`at`), never this one changed, so a
    compiled function or density that closes over a program stays true to it.
    """

    law: Law
    noise: Noise
    priors: dict[str, Prior]  # as declared after overrides (may be data-scaled)
    resolved: dict[str, Prior]  # absolute numbers used
    constants: dict[str, float]
    scale: DataScale
    inputs: dict[str, np.ndarray]
    response: np.ndarray
    group_index: np.ndarray | None
    group_labels: list[Any] = field(default_factory=list)
    chain_start: np.ndarray | None = None  # ar1 noise: True where a trajectory starts (data order)
    response_se: np.ndarray | None = None  # the response's measured standard error per row (reduced data)
    groupings: Mapping[str, Grouping] = field(default_factory=dict)  # each vary_by column's levels per row
    # init=False: dataclasses.replace(program, response=...) starts a fresh cache, never the old data's density
    _densities: dict[int, Density] = field(default_factory=dict, init=False, repr=False, compare=False)

    def density(self, seed: int = 0) -> Density:
        """The program's one log density (:mod:`bayesfric.density`), built once per seed.

        ``seed`` only sets the prior draws behind the prior-median starting point ``x0``.
        """
        if seed not in self._densities:
            self._densities[seed] = build_density(self, seed)
        return self._densities[seed]

    @property
    def n_obs(self) -> int:
        return int(self.response.shape[0])

    @property
    def model_kwargs(self) -> dict[str, Any]:
        return {"inputs": self.inputs, "group_index": self.group_index, "response": self.response}

    def site_dims(self) -> dict[str, list[str]]:
        """Extra dimensions of vector-valued parameter sites (``<name>_dim_<k>``)."""
        dims = {}
        for name, p in self.law.params.items():
            if p.shape:
                dims[name] = [f"{name}_dim_{k}" for k in range(len(p.shape))]
        for name, (_, z_site, level_site) in site_names(self.law, self.groupings).items():
            dims[z_site] = dims[level_site] = [self.law.varying[name]]
            if z_site.endswith("_w"):  # a centred walk: the levels after the first (bayesfric.trend)
                dims[z_site] = [f"{self.law.varying[name]}_step"]
        if self.noise.group is not None:
            dims.update(group_z=["group"], group_offset=["group"])
        return dims

    def model(self, inputs, group_index=None, response=None, mask=None, seen=None):
        """The numpyro program (see the module docstring for its sites).

        ``mask`` keeps observations in the likelihood; ``seen`` (a fold's training mask) marks
        the rows whose group levels are sampled centred: a level without such rows, one the fold
        holds out, is sampled non-centred (:func:`bayesfric.trend.centred_or_not`). A separate
        argument, so that the prior, the constrained draws and the pointwise likelihood of a
        fold's draws read them as its sampler did; None: every level as its column says."""
        law = self.law
        params = self._sample_params()
        for name, value in law.derived_values(params).items():
            numpyro.deterministic(name, value)
        # Data arrays stay concrete inside the sampler's trace, so input-only computations of a
        # law (e.g. ball-load equilibria) can be evaluated once at trace time, not every step.
        with jax.ensure_compile_time_eval():
            arrays = {k: jnp.asarray(v) for k, v in inputs.items()}
        if law.varying:  # group terms: each row reads its level's values (bayesfric.hierarchy)
            params = group_sites(law, self.resolved, self.groupings, params, observed_levels(self.groupings, seen))
        mu = law_mean(law, arrays, params, self.constants, {c: g.index for c, g in self.groupings.items()})
        if self.noise.group is not None:
            n_groups = len(self.group_labels)
            group_sd = numpyro.sample("group_sd", self.resolved["group_sd"].to_numpyro())
            with numpyro.plate("group", n_groups):
                z = numpyro.sample("group_z", dist.Normal(0.0, 1.0))
            offset = numpyro.deterministic("group_offset", group_sd * z)
            mu = mu * jnp.exp(offset[group_index])
        likelihood = self._likelihood(mu, mask, response)
        with numpyro.plate(OBS_DIM, mu.shape[0]):
            with numpyro.handlers.mask(mask=True if mask is None else mask):
                numpyro.sample(OBS_SITE, likelihood, obs=response)

    def _sample_params(self) -> dict[str, Any]:
        """Sample the law's parameters from their priors; one with a usable
        :class:`~bayesfric.laws.base.SampledAs` after those it reads, on its declared coordinate."""
        law, params = self.law, {}
        recoordinated = sampled_as(law, self.constants)
        for name in sorted(law.params, key=lambda n: n in recoordinated):  # stable: declared order otherwise
            declared = law.params[name]
            prior = self.resolved[name].to_numpyro()
            if declared.shape:
                prior = prior.expand(declared.shape).to_event(len(declared.shape))
            if name in recoordinated:
                how = recoordinated[name]
                values = {k: params[k] if k in params else self.constants[k] for k in how.reads}
                prior = rescaled(prior, how.fn(self.scale.factor(how.scaled_by), **values))
            params[name] = numpyro.sample(name, prior)
        return params

    def _likelihood(self, mu, mask=None, response=None):
        r = self.resolved
        values = {name: numpyro.sample(name, r[name].to_numpyro()) for name in _NOISE_SITES[self.noise.kind]
                  if not (name == "sigma" and self.noise.sigma is not None)}
        if self.noise.kind == "ar1":  # the mask is integrated out exactly (bayesfric.noise)
            # predictive draws: one step ahead given the observed data (what the likelihood scores)
            past = self.response if response is None else None
            return AR1Residuals(mu, values["sigma"], values["rho"], self.chain_start, mask, past)
        return self.observation(mu, values, self.response_se)

    def observation(self, mu, values: Mapping[str, Any], se=None) -> dist.Distribution:
        """The distribution of one observation with mean ``mu`` given noise-parameter ``values``.

        The likelihood uses exactly this distribution (normal, student_t, proportional); for
        ``ar1`` it is the stationary marginal ``N(mu, σ² / (1 − ρ²))`` of a point, the predictive
        of a new operating point with no observed predecessor. Sizing and the held-out predictive
        summaries of cross-validation draw their noise from here, so there is one noise model.

        Parameters
        ----------
        mu : array
            Mean function values (any shape broadcasting with the parameter values).
        values : mapping of str to array
            Noise-parameter draws by site name (:meth:`Noise.sites`, without ``group_sd``).
        se : array, optional
            Measured standard errors of the observations (broadcasting with ``mu``), added to the
            noise in quadrature (module docstring); the likelihood passes :attr:`response_se`.
        """
        kind = self.noise.kind
        extra = 0.0 if se is None else jnp.square(jnp.asarray(se))
        if kind == "normal":
            sigma = self.noise.sigma if self.noise.sigma is not None else values["sigma"]
            return dist.Normal(mu, sigma if se is None else jnp.sqrt(jnp.square(sigma) + extra))
        if kind == "student_t":
            sigma = values["sigma"]
            return StudentT(values["nu"], mu, sigma if se is None else jnp.sqrt(jnp.square(sigma) + extra))
        if kind == "ar1":
            rho = values["rho"]
            return dist.Normal(mu, values["sigma"] / jnp.sqrt(1.0 - rho**2))
        return dist.Normal(mu, jnp.sqrt((values["sigma_rel"] * mu) ** 2 + values["sigma_floor"] ** 2 + extra))

    def at(self, points: Mapping[str, Any]) -> Program:
        """This program (law, priors, constants, noise model) at new operating points, without data.

        The response is zeros; with partial-pooled groups (``[noise] group``, ``vary_by``) every
        point belongs to one new group (``"new unit"``, :data:`~bayesfric.hierarchy.NEW_LEVEL`);
        with ``ar1`` noise every point starts its own trajectory (the stationary marginal).

        Parameters
        ----------
        points : mapping of str to array
            Every input the law reads, by name, as SI values of the same length.
        """
        n = len(next(iter(points.values())))
        grouped = self.noise.group is not None
        return dataclasses.replace(
            self, inputs={k: np.asarray(points[k], dtype=float) for k in self.law.inputs}, response=np.zeros(n),
            group_index=np.zeros(n, dtype=int) if grouped else None, group_labels=["new unit"] if grouped else [],
            chain_start=np.ones(n, dtype=bool) if self.noise.kind == "ar1" else None, response_se=None,
            groupings={c: Grouping((NEW_LEVEL,), np.zeros(n, dtype=int), g.centred) for c, g in self.groupings.items()})

    def parameter_names(self) -> list[str]:
        """Law parameters, derived quantities, between-group spreads, then noise parameters (report order)."""
        spreads = [f"{p}_sd" for p in self.law.varying]
        if self.law.trend_form != "walk":
            spreads += [f"{p}_trend" for p in self.law.trending]
        return list(self.law.params) + list(self.law.derived) + spreads + list(self.noise.sites())


def build_program(
    law: Law,
    ds: xr.Dataset,
    *,
    priors: Mapping[str, Prior | Mapping[str, Any]] | None = None,
    noise: Noise | None = None,
    constants: Mapping[str, float] | None = None,
    scale: DataScale | None = None,
) -> Program:
    """Bind ``law`` to ``ds`` with optional prior overrides by parameter name.

    The program's law is ``law`` as it runs on ``ds`` (:func:`bayesfric.laws.variants.for_data`):
    its translational form on force data, without the optional inputs the data lack.

    Parameters
    ----------
    law : Law
        A registered law or a variant.
    ds : xarray.Dataset
        Data from :func:`bayesfric.datasets.load_dataset`.
    priors : mapping, optional
        Overrides by parameter name (law or noise parameter): :class:`Prior` or its dict form.
    noise : Noise, optional
        Default: Normal noise without groups.
    constants : mapping, optional
        Overrides of the law's declared constants.
    scale : DataScale, optional
        Data scale for data-scaled priors; default computed from ``ds``. Cross-validation passes
        the full data's scale so every fold uses identical priors.

    Raises
    ------
    PriorError
        An override names a parameter that neither the law nor the noise model has.
    DataError
        The dataset lacks an input the law reads, or the group coordinate.
    """
    configure()  # x64 and the persistent compilation cache, on first use
    law = for_data(law, ds)  # the data's motion kind; optional inputs it lacks (laws.variants)
    noise = noise or Noise()
    chain_start = _chain_starts(law, noise, ds)  # rows that are no trajectory, before a missing input
    inputs, response = law_inputs(ds, law), response_values(ds, law)  # a missing input, before priors
    declared = law.default_priors() | _spread_priors(law, law.default_priors(), {}, strict=False) | {
        k: NOISE_PRIORS[k] for k in noise.sites()}
    for name, spec in (priors or {}).items():
        if name not in declared:
            raise PriorError(
                f"prior override for unknown parameter {name!r} of law {law.name!r}; "
                f"parameters: {', '.join(declared)}"
            )
        declared[name] = spec if isinstance(spec, Prior) else Prior.from_dict(spec)
    declared |= _spread_priors(law, declared, priors or {})  # a spread follows its parameter's override
    scale = scale or data_scale(ds)
    resolved = resolve_all(declared, scale)  # an error names priors.<parameter>.<key>
    consts = {k: c.value for k, c in law.constants.items()}
    for k, v in (constants or {}).items():
        if k not in consts:
            raise PriorError(f"law {law.name!r} has no constant {k!r}; constants: {', '.join(consts) or 'none'}")
        consts[k] = float(v)
    group_index, labels = None, []
    if noise.group is not None:
        if noise.group not in ds.coords:
            raise DataError(f"noise group {noise.group!r} is not a coordinate of the dataset")
        labels_arr, group_index = np.unique(np.asarray(ds[noise.group].values), return_inverse=True)
        labels = labels_arr.tolist()
    return Program(
        law=law,
        noise=noise,
        priors=declared,
        resolved=resolved,
        constants=consts,
        scale=scale,
        inputs=inputs,
        response=response,
        group_index=group_index,
        group_labels=labels,
        chain_start=chain_start,
        response_se=response_se(ds),
        groupings=groupings_of(law, ds),
    )


def sampled_as(law: Law, constants: Mapping[str, Any]) -> dict[str, SampledAs]:
    """Parameter -> its :class:`~bayesfric.laws.base.SampledAs`, where the law has everything it
    reads (other scalar parameters that read none themselves, or constants) and the parameter is a
    scalar that varies between no groups; the others are sampled on their own scale."""
    found = {}
    for name, p in law.params.items():
        how = p.sampled_as
        if how is None or p.shape or name in law.varying:
            continue
        if all((k in constants or (k in law.params and k != name and law.params[k].sampled_as is None
                                   and not law.params[k].shape)) for k in how.reads):
            found[name] = how
    return found


def _chain_starts(law: Law, noise: Noise, ds: xr.Dataset) -> np.ndarray | None:
    """Each trajectory's first row where the noise model needs it (``ar1``), else None.

    Raises
    ------
    DataError
        A trajectory law or ``ar1`` noise on rows that are no trajectory: segment means of a
        steady-state reduction (rows with standard errors), or, for ``ar1``, data naming no
        trajectory group.
    """
    name = ds.attrs.get("name", "?")
    reduced = bool(ds.attrs.get("reduced_from")) or response_se(ds) is not None
    if law.trajectory and reduced:
        raise DataError(f"law {law.name!r} is a trajectory (stateful) law, but data set {name!r} holds segment "
                        "means of a steady-state reduction, not a trajectory: fit it on the raw log")
    if noise.kind != "ar1":
        return None
    if reduced:
        raise DataError(f"noise kind 'ar1' does not apply to data set {name!r}: its rows carry standard errors "
                        "(segment means of a reduction), independent, not a trajectory")
    if not ds.attrs.get("trajectory"):
        raise DataError(f"noise kind 'ar1' needs ordered trajectories, but data set {name!r} names no trajectory "
                        "group")
    return trajectory_starts(ds)


def _spread_priors(law: Law, declared: Mapping[str, Prior], given: Mapping[str, Any],
                   strict: bool = True) -> dict[str, Prior]:
    """Default priors of the between-group spreads (:func:`bayesfric.hierarchy.hyperprior`) of the
    parameters ``law`` varies by a column, except those ``given`` by name; ``strict=False`` skips
    a spread that has no default (named as an override target before the overrides are read)."""
    out = {}
    for p in law.varying:
        sd = f"{p}_sd"
        if sd in given:
            continue
        try:
            out[sd] = hyperprior(declared[p], p, trend=p in law.trending)
        except PriorError:
            if strict:
                raise
            out[sd] = Prior("HalfNormal", scale=1.0)  # a placeholder name only: replaced or refused below
    if law.trend_form != "walk":  # a trend's slope (bayesfric.trend)
        out |= {f"{p}_trend": trend_prior(declared[p], p) for p in law.trending if f"{p}_trend" not in given}
    return out


def program_record(program: Program) -> dict[str, str]:
    """What a fit records of its program (NetCDF-safe strings), enough to rebuild it exactly
    (:func:`program_of_fit`): the law's name and variant recipe, the files of the user's law code
    (:func:`bayesfric.laws.plugins.law_files`), the noise model, the declared and resolved
    priors, the constants and the data scale the priors were resolved on."""
    law = program.law
    return {
        "law": law.name,
        "law_recipe": json.dumps(dict(law.recipe)) if law.recipe else "",  # laws.variants
        "law_source": law.source,
        "law_family": law.family,
        "law_files": json.dumps(list(law_files(law))),
        "noise": json.dumps({"kind": program.noise.kind, "group": program.noise.group, "sigma": program.noise.sigma}),
        "priors": json.dumps({k: p.to_dict() for k, p in program.priors.items()}),
        "priors_resolved": json.dumps({k: str(p) for k, p in program.resolved.items()}),
        "constants": json.dumps(program.constants),
        "data_scale": json.dumps({"response": program.scale.response, "inputs": dict(program.scale.inputs)}),
    }


def program_data(program: Program) -> dict[str, np.ndarray]:
    """The per-row arrays besides inputs and response that a fit keeps in ``constant_data`` so
    its program can be rebuilt (:func:`program_of_fit`): ``chain_start`` (ar1 noise) and
    ``response_se`` (reduced data), where the program has them."""
    out = {"chain_start": program.chain_start, "response_se": program.response_se}
    out |= {f"{c}_level": g.index for c, g in program.groupings.items()}
    return {k: np.asarray(v) for k, v in out.items() if v is not None}


def _noise_of(attrs: Mapping[str, Any]) -> Noise:
    noise, priors = json.loads(attrs["noise"]), json.loads(attrs["priors"])
    sigma = noise.get("sigma")
    if noise["kind"] == "normal" and "sigma" not in priors and sigma is None:
        raise UserError(f"fit of {attrs['law']!r} used a known noise sigma, which its attrs "
                         "do not record; pass the fit's program (or engine) explicitly")
    return Noise(kind=noise["kind"], group=noise.get("group"), sigma=sigma)


def program_of_fit(fit: xr.DataTree) -> Program:
    """The program that produced ``fit``, rebuilt from the fit alone (:func:`program_record`).

    The law is rebuilt from its name and recipe (variants included), after loading the user's
    law files the fit names; priors, noise model and constants are the recorded ones, resolved
    on the recorded data scale; inputs, response, groups, trajectory starts and standard errors
    are the fit's ``constant_data`` and ``observed_data``. Group labels come back as text.

    Raises
    ------
    KeyError
        The law is no longer known (not registered, not in a recorded law file).
    bayesfric.laws.plugins.LawModuleError
        A recorded law file is gone or no longer loads.
    ValueError
        A fit of an older version that used a known noise sigma without recording it.
    """
    # x64 before any of the program runs: a fit read from its file in a fresh process would
    # otherwise be evaluated in float32 and answer differently from the same fit in memory
    configure()
    attrs = fit.attrs
    law, noise = law_of_fit(attrs), _noise_of(attrs)
    declared = {k: Prior.from_dict(v) for k, v in json.loads(attrs["priors"]).items()}
    # all of them in a fit; a fit made by hand (posterior and attrs only) may lack its data
    data = fit["constant_data"].to_dataset() if "constant_data" in fit.children else xr.Dataset()
    inputs = {k: np.asarray(data[k].values, dtype=bool if k == TRAJECTORY_START else float)
              for k in law.inputs if k in data}
    response = (np.asarray(fit["observed_data"][OBS_SITE].values, dtype=float) if "observed_data" in fit.children
                else np.zeros(0))
    if "data_scale" in attrs:
        recorded = json.loads(attrs["data_scale"])
        scale = DataScale(float(recorded["response"]), {k: float(v) for k, v in recorded["inputs"].items()})
    else:  # fits before the scale was recorded: the law's inputs give every scale its priors read
        scale = DataScale.of(response, {k: v for k, v in inputs.items() if k != TRAJECTORY_START})
    group_index, labels = None, []
    if noise.group is not None and "group_index" in data:  # (a fit made by hand may lack them)
        group_index = np.asarray(data["group_index"].values, dtype=int)
        labels = [str(g) for g in fit["posterior"]["group"].values]
    kept = {k: np.asarray(data[k].values) for k in ("chain_start", "response_se") if k in data}
    groupings = {c: Grouping(tuple(str(v) for v in fit["posterior"][c].values),
                             np.asarray(data[f"{c}_level"].values, dtype=int))
                 for c in dict.fromkeys(law.varying.values()) if f"{c}_level" in data}
    return Program(groupings=groupings,
                   law=law, noise=noise, priors=declared, resolved=resolve_all(declared, scale),
                   constants={k: float(v) for k, v in json.loads(attrs["constants"]).items()}, scale=scale,
                   inputs=inputs, response=response, group_index=group_index, group_labels=labels,
                   chain_start=kept["chain_start"].astype(bool) if "chain_start" in kept else None,
                   response_se=kept["response_se"].astype(float) if "response_se" in kept else None)


def program_from_fit(fit: xr.DataTree, ds: xr.Dataset) -> Program:
    """Rebuild the program of a fit on the data set ``ds`` (the fit's own, or another with the
    same inputs) from its provenance attrs (law, priors, noise, constants); the priors are
    resolved on ``ds``. :func:`program_of_fit` rebuilds it from the fit alone.

    Fits saved before the known noise sigma was recorded in the ``noise`` attr cannot be rebuilt
    when they used one; pass the fit's program explicitly for those.
    """
    return build_program(law_of_fit(fit.attrs), ds, priors=json.loads(fit.attrs["priors"]), noise=_noise_of(fit.attrs),
                         constants=json.loads(fit.attrs["constants"]))
