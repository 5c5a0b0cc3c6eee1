"""Public API, first half: data, laws, one fit, and a score table over fits.

Each function checks what it is given where it is given: a bad argument is a
:class:`~bayesfric.errors.UserError` (or the :class:`~bayesfric.datasets.DataError` of a data
file) of one line naming the argument (``draws: must be ≥ 1 ...``, ``priors.T_C: ...``). The
command line (``bayesfric fit``) runs the same checks (:func:`sampler_options`,
:func:`checked_program`) with its option names.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.inference.config import SamplerConfig
from bayesfric.laws.base import Law
from bayesfric.priors import Prior, PriorError

__all__ = ["load_data", "law", "fit", "compare_laws", "sampler_options", "checked_program"]


def load_data(data: str | Path | xr.Dataset, *, select: Mapping[str, Any] | None = None) -> xr.Dataset:
    """Load a data set: a built-in name (``bayesfric data list``) or a CSV file with its TOML sidecar.

    Parameters
    ----------
    data : str, Path or xarray.Dataset
        Built-in name, CSV path, or a data set already loaded (returned as it is).
    select : mapping, optional
        Keep only rows whose coordinate has this value (or one of these values), e.g. ``{"series": 1}``.

    Returns
    -------
    xarray.Dataset
        SI units, dimension ``obs``, inputs as coordinates, the response a data variable,
        provenance in ``attrs``.

    Raises
    ------
    DataError
        Unknown name, unreadable or invalid file, a selection that the data cannot satisfy.

    Examples
    --------
    >>> import bayesfric
    >>> ds = bayesfric.load_data("robot_joint")
    >>> ds.attrs["response"], ds.sizes["obs"]
    ('torque', 111)
    >>> bayesfric.load_data("robot_joint", select={"series": 1}).sizes["obs"]
    37
    """
    from bayesfric.datasets import DataError, load_dataset, resolve
    from bayesfric.datasets import select as pick

    if isinstance(data, xr.Dataset):
        if "response" not in data.attrs:
            raise UserError("data: not a bayesfric data set (no 'response' attribute): load it with "
                            "bayesfric.load_data")
        ds = data
    elif isinstance(data, str | Path):
        ds = load_dataset(resolve(data))
    else:
        raise UserError(f"data: expected a built-in data set name, a CSV path or an xarray.Dataset, "
                        f"got {type(data).__name__}")
    if not select:
        return ds
    try:
        return pick(ds, dict(select))
    except DataError as exc:
        raise DataError(f"select: {exc}") from None


def law(law: str | Law | Callable[..., Any], /, *, units: Mapping[str, str] | None = None,
        priors: Mapping[str, Prior | Mapping[str, Any]] | None = None, response: str = "torque",
        register: bool = False, **options: Any) -> Law:
    """A friction law: a registered name, a :class:`~bayesfric.laws.Law`, or a plain function.

    A function is declared through :func:`bayesfric.laws.simple_law`: arguments named after an
    operating quantity (``velocity``, ``temperature`` ...) are its inputs, other arguments without
    a default its parameters (each needs a unit), arguments with a default its constants.

    Parameters
    ----------
    law : str, Law or callable
        Registered name (``bayesfric laws --names``), a law, or the law's mean function in ``jax.numpy``.
    units : mapping, optional
        For a function: SI unit (pint syntax) of every parameter.
    priors : mapping, optional
        For a function: prior of a parameter (:class:`~bayesfric.priors.Prior` or its dict form);
        the others get data-scaled defaults.
    response : str
        For a function: ``"torque"`` or ``"force"``.
    register : bool
        For a function: register it under its name (listed with the package's laws; a name is
        registered once per process). Unregistered, it is still found by its name in this
        process, and elsewhere through the file that declares it, so a :class:`~bayesfric.Study`
        can take it as an object and a fit of it can be sized or read back
        (:func:`bayesfric.load_fit`).
    **options
        For a function: further keywords of :func:`~bayesfric.laws.simple_law`.

    Returns
    -------
    Law

    Raises
    ------
    UserError
        Unknown name, a function without ``units``, options given with a name or a law.
    LawDeclarationError
        A function that cannot be declared (a parameter without a unit, ...).

    Examples
    --------
    >>> import bayesfric, jax.numpy as jnp
    >>> bayesfric.law("stribeck").inputs
    ('velocity',)
    >>> def smooth_coulomb(velocity, T_C, v_eps=0.01):
    ...     return T_C * jnp.tanh(velocity / v_eps)
    >>> mine = bayesfric.law(smooth_coulomb, units={"T_C": "N*m", "v_eps": "rad/s"})
    >>> list(mine.params), mine.constants["v_eps"].value
    (['T_C'], 0.01)
    """
    from bayesfric.laws import REGISTRY, get_law, simple_law

    if isinstance(law, str | Law):
        given = [k for k, v in (("units", units), ("priors", priors), ("register", register or None)) if v]
        if given or options:
            raise UserError(f"{(given + list(options))[0]}: applies only to a law given as a function")
        if isinstance(law, Law):
            return law
        try:
            return get_law(law)
        except KeyError as exc:
            raise UserError(f"law: {exc.args[0]}") from None
    if not callable(law):
        raise UserError(f"law: expected a law name, a Law or a function, got {type(law).__name__}")
    if units is None:
        raise UserError("units: a law given as a function needs the SI unit of every parameter, "
                        "e.g. units={'T_C': 'N*m'}")
    name = options.get("name") or getattr(law, "__name__", "")
    if not register and name in REGISTRY:  # a fit of it would be read back as the registered law
        raise UserError(f"name: {name!r} is a registered law's name: give yours another (name=...)")
    return simple_law(law, units=units, priors=priors, response=response, register=register, **options)


def _as_law(given: str | Law) -> Law:
    return law(given)  # the module's law(): inside fit() the name is its argument


def sampler_options(sampler: str, seed: int, options: Mapping[str, Any],
                    key: Callable[[str], str] = str) -> SamplerConfig:
    """The sampler configuration of a fit's options: :meth:`SamplerConfig.from_table` over the
    backend, the seed and ``options`` (None: not given, the backend's default), checked as a study's
    ``[sampler]`` table is (ranges, which settings belong to which sampler). ``key`` names a
    setting in errors (``--draws`` on the command line).

    Examples
    --------
    >>> config = sampler_options("nuts", 1, {"draws": 200, "chains": None})
    >>> config.draws, config.chains, config.seed
    (200, 4, 1)
    """
    return SamplerConfig.from_table({"name": sampler, "seed": seed} | dict(options), key)


def checked_program(law: Law, ds: xr.Dataset, priors: dict[str, Prior], noise, config: SamplerConfig,
                    key: Callable[[str], str] = str, prior_key: Callable[[str], str] = "priors.{}".format):
    """Build the fit's program (data-scaled priors resolved) and check its walkers and the memory
    its settings imply (:mod:`bayesfric.limits`), before anything is sampled; return it.
    ``key`` names a sampler setting in errors, ``prior_key`` a prior given by the user."""
    from bayesfric.limits import program_size, sampler_problem
    from bayesfric.model import build_program
    from bayesfric.study.config import walkers_problem

    try:
        program = build_program(law, ds, priors=priors, noise=noise)  # data-scaled priors resolve here
    except PriorError as exc:  # exc.key: priors.<parameter>.<key in its spec>
        name, _, sub = exc.key.removeprefix("priors.").partition(".")
        where = prior_key(name) if name in priors else f"law {law.name!r}: prior of {name}"
        raise UserError(f"{where}{': ' + sub if sub else ''}: {exc.problem}") from None
    if config.name == "emcee" and (problem := walkers_problem(program, config.walkers)):
        raise UserError(f"{key('walkers')}: {problem}")
    if found := sampler_problem(config.name, config.settings(), *program_size(program)):
        raise UserError(f"{key(found[0])}: {found[1]}")
    return program


def _noise(noise: Any, ds: xr.Dataset):
    from bayesfric.model import Noise

    if isinstance(noise, Noise):
        out = noise
    else:
        try:
            out = Noise() if noise is None else Noise(kind=noise) if isinstance(noise, str) else Noise(**noise)
        except (TypeError, ValueError) as exc:
            raise UserError(f"noise: {exc} (a kind such as 'normal', a dict of Noise's fields or a Noise)") from None
    if out.group is not None and out.group not in ds.coords:
        raise UserError(f"noise: group {out.group!r} is not a coordinate of the data ({', '.join(ds.coords)})")
    return out


def _priors(priors: Mapping[str, Prior | Mapping[str, Any]] | None, known: list[str], name: str) -> dict[str, Prior]:
    out = {}
    for pname, spec in (priors or {}).items():
        if pname not in known:
            raise UserError(f"priors.{pname}: law {name!r} has no parameter {pname!r} (parameters: {', '.join(known)})")
        try:
            out[pname] = spec if isinstance(spec, Prior) else Prior.from_dict(spec)
        except PriorError as exc:
            raise UserError(f"priors.{pname}: {exc}") from None
    return out


def fit(law: str | Law, data: str | Path | xr.Dataset, *, priors: Mapping[str, Prior | Mapping[str, Any]] | None = None,
        noise: Any = None, sampler: str = "nuts", draws: int | None = None, tune: int | None = None,
        chains: int | None = None, seed: int = 0, progress: bool = False, **settings: Any) -> xr.DataTree:
    """Fit one law to one data set (NUTS by default) and return the fit as an arviz DataTree.

    Every argument is checked before anything is sampled (the checks of ``bayesfric fit``).

    Parameters
    ----------
    law : str or Law
        Registered name or a law (:func:`law`); run as it runs on the data (its motion kind).
    data : str, Path or xarray.Dataset
        What :func:`load_data` takes.
    priors : mapping, optional
        Parameter -> prior (:class:`~bayesfric.priors.Prior` or its dict form), over the law's own.
    noise : str, mapping or Noise, optional
        ``"normal"`` (default), ``"student_t"``, ``"proportional"``, ``"ar1"``, or
        ``{"kind": ..., "group": "series"}`` (a :class:`~bayesfric.model.Noise`).
    sampler : {"nuts", "emcee"}
    draws, tune, chains : int, optional
        Draws and warm-up per chain, chains (None: the sampler's defaults, 1000, 1000, 4).
    seed : int
        Seed of every random draw.
    progress : bool
        Show a progress bar.
    **settings
        Further sampler settings of a study's ``[sampler]`` table (``target_accept``, ``metric``, ...).

    Returns
    -------
    xarray.DataTree
        posterior, log_likelihood, posterior_predictive, observed_data, constant_data ... with
        provenance attrs; its diagnostics verdict as a dict from :func:`bayesfric.diagnostics`.

    Raises
    ------
    UserError
        An argument out of range or unknown, naming it (``draws: ...``, ``priors.T_C: ...``).

    Examples
    --------
    >>> import bayesfric
    >>> f = bayesfric.fit("coulomb_viscous", "robot_joint", draws=100, tune=100, chains=2)
    >>> sorted(f.posterior.data_vars)
    ['T_C', 'c_v', 'sigma']
    """
    from bayesfric.inference import fit as sample
    from bayesfric.laws.variants import for_data

    config = sampler_options(sampler, seed, {"draws": draws, "tune": tune, "chains": chains, "progress": progress}
                             | settings)
    ds = load_data(data)
    chosen = for_data(_as_law(law), ds)
    noise = _noise(noise, ds)
    given = _priors(priors, list(chosen.params) + list(noise.sites()), chosen.name)
    checked_program(chosen, ds, given, noise, config)
    out = sample(chosen, ds, priors=given, noise=noise, config=config)
    _warn_verdict(out, chosen.name)
    return out


def _warn_verdict(fit: xr.DataTree, name: str) -> None:
    """A :class:`~bayesfric.errors.FitWarning` with the verdict where the fit failed the gate or is
    used only as multimodal or unidentified (the study report says the same)."""
    import warnings

    from bayesfric.errors import FitWarning
    from bayesfric.inference import verdict_of

    if "diagnostics" not in fit.attrs:
        return
    verdict = verdict_of(fit)
    if not verdict.passed:
        what = "FAILED the diagnostics gate: its draws are not a posterior to act on (more draws, priors, or " \
               "a reparametrised law)"
    elif verdict.multimodal or verdict.unidentified:
        what = "is used only under the multimodal or unidentified rule: read its parameters with care"
    else:
        return
    warnings.warn(f"fit of {name} {what}; {verdict}", FitWarning, stacklevel=3)


def compare_laws(fits: Mapping[str, xr.DataTree] | list[xr.DataTree], data: str | Path | xr.Dataset | None = None,
                 *, seed: int = 0) -> pd.DataFrame:
    """Rank fits of the same data by PSIS-LOO, with stacking weights (arviz-stats).

    (``bayesfric.compare`` is the comparison package, hence the name.) A study
    (:func:`bayesfric.run`) adds cross-validation blocked along the operating envelope and
    two evidence estimators; ``result.scores`` holds them all.

    Parameters
    ----------
    fits : mapping or list of xarray.DataTree
        Label -> fit, or fits (labelled by their law).
    data : str, Path or xarray.Dataset, optional
        The data of the fits: points with a high Pareto k̂ are then refitted exactly; without
        it they keep their PSIS value and the law's row says so (``reliable`` False).
    seed : int
        Seed of those refits.

    Returns
    -------
    pandas.DataFrame
        One row per law, the reliable ones first (a fit that passed the gate, with a reliable
        PSIS-LOO), each part best first: ``elpd_loo``, ``se``, ``elpd_diff`` (to the first row),
        ``subsampling_se`` (the extra error of a subsampled PSIS-LOO above
        :data:`~bayesfric.limits.LOO_SUBSAMPLE_ROWS` rows, arviz-stats' ``loo_subsample``; NaN
        when every row is scored), ``p_loo``,
        ``high_k``, ``weight`` (stacking; NaN for a law left out), ``reliable`` and ``reason``
        (why a law is unreliable or has no weight: a fit that failed the diagnostics gate, ...).
        The best law to act on is ``table[table.reliable].index[0]``.

    Examples
    --------
    >>> import bayesfric
    >>> fits = {name: bayesfric.fit(name, "robot_joint", draws=100, tune=100, chains=2)
    ...         for name in ("coulomb_viscous", "stribeck")}
    >>> table = bayesfric.compare_laws(fits, "robot_joint")
    >>> reliable = table[table.reliable]
    >>> list(reliable.index) == sorted(reliable.index, key=lambda k: -table.loc[k, "elpd_loo"])
    True
    """
    from bayesfric.compare import model_weights, psis_loo
    from bayesfric.inference import verdict_of

    named = dict(fits) if isinstance(fits, Mapping) else {str(f.attrs.get("law", i)): f for i, f in enumerate(fits)}
    if not named:
        raise UserError("fits: give at least one fit")
    for label, f in named.items():
        if not isinstance(f, xr.DataTree) or "log_likelihood" not in f.children:
            raise UserError(f"fits[{label!r}]: not a fit with pointwise log-likelihood (from bayesfric.fit)")
    ds = load_data(data) if data is not None else None
    loo = {label: psis_loo(f, ds, seed=seed) for label, f in named.items()}
    try:
        weights = model_weights(loo, fits=named)
        kept, left_out = weights.weights, weights.excluded
    except ValueError:  # every law unreliable: no weights at all; each row says why below
        kept, left_out = {}, {}
    rows = []
    for label, r in loo.items():
        failed = not verdict_of(named[label]).passed
        reason = left_out.get(label) or ("fit failed the diagnostics gate" if failed
                                         else "" if r.reliable else r.handling)
        sub_se = r.subsampling_se if r.subsample is not None else float("nan")
        rows.append({"law": label, "elpd_loo": r.elpd, "se": r.se, "subsampling_se": sub_se, "p_loo": r.p_loo,
                     "high_k": r.n_high_k,
                     "weight": kept.get(label, float("nan")), "reliable": r.reliable and not failed,
                     "reason": reason})
    table = pd.DataFrame(rows).set_index("law")
    table = table.iloc[np.lexsort((-table["elpd_loo"].to_numpy(), ~table["reliable"].to_numpy(dtype=bool)))]
    table.insert(2, "elpd_diff", table["elpd_loo"] - table["elpd_loo"].iloc[0])
    return table
