"""A law's work in a study, split into units with explicit inputs and plain serialisable outputs.

Units of one law (:func:`plan_law`): ``fit`` (the full fit), then — all reading the fit —
``loo`` (PSIS-LOO with exact refits of high-k points), one ``cv`` unit per cross-validation scheme,
``bridge`` and ``importance`` evidence estimates, ``smc`` (opt-in) and ``checks`` (prior
predictive, LOO-PIT, power-scaling sensitivity, residual structure). Every unit runs through
:func:`compute`, a pure function of a :class:`LawJob` (the law, its priors and constants, noise,
selected data, the sampler's :class:`~bayesfric.inference.config.SamplerConfig` with its seed), the
:class:`Unit` and the fit; it returns the fit (a DataTree) or the unit's
``xarray.Dataset`` (its scorer's result: :func:`loo_dataset`, :func:`cv_dataset`,
:func:`evidence_dataset`, :func:`checks_dataset`), which the run store writes as NetCDF and reads
back (:mod:`bayesfric.study.store`) and a Dask worker sends as it is; in one process the units hand
each other the objects, never their bytes. Each unit gets the study seed explicitly (no random
stream is shared between units), so the order in which units run — serially or on any number of
workers — does not change a number. :func:`bayesfric.study.rebuild.rebuild` turns a law's
Datasets into the compare layer's result objects (fresh and stored alike), which the runner weighs
and flattens into the law's result (:mod:`bayesfric.study.lawresult`).

A law's full fit and its fold refits share one compiled engine: the caller that runs the units
keeps it in an :class:`Engines` (the serial executor one per run, a Dask worker one per worker
process) and passes it to :func:`compute`; nothing is kept in this module.

The fit's verdict decides the rest: under ``[compare] failed_fits = "skip"`` (the default) a law
whose full fit failed the diagnostics gate gets no CV refits and no evidence (the costly stages);
its result lists them in ``skipped`` and its flags say why. Its ``loo`` unit still runs, PSIS
only: no high-k point is refitted exactly (:data:`NO_REFIT`; the unit's key carries
``failed_fits = "run"`` where the study asks for the refits). That is why every unit of a law waits
for its fit, even those that could start without it (blocked CV, importance sampling). A
multimodal fit (:mod:`bayesfric.inference.modes`) passes: every unit runs, on its combined draws
(bridge sampling per mode, importance sampling marked approximate).
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr

from bayesfric import compare
from bayesfric.compare.newgroup import MIN_GROUPS
from bayesfric.errors import InternalError
from bayesfric.fingerprint import data_fingerprint, law_fingerprint, unit_key
from bayesfric.inference import MAPPINGS_BUDGET, SAMPLERS, release_compiled_code
from bayesfric.inference.config import SamplerConfig
from bayesfric.inference.engine import NutsEngine, build
from bayesfric.inference.modes import single_mode_note
from bayesfric.model import Noise, build_program
from bayesfric.study.store import Result

if TYPE_CHECKING:
    from bayesfric.compare.structure import StructureCheck

__all__ = ["LawJob", "Unit", "Engines", "make_job", "plan_law", "compute", "compute_seconds", "COSTLY",
           "loo_dataset", "cv_dataset", "evidence_dataset", "checks_dataset"]

#: Stages skipped for a law whose full fit failed the gate under ``failed_fits = "skip"``.
COSTLY = ("cv", "bridge", "importance", "smc")
#: Why a failed fit's LOO refits no point under ``failed_fits = "skip"`` (its LOO is PSIS only).
NO_REFIT = 'the fit failed the gate ([compare] failed_fits = "skip": PSIS only, no exact refit)'


@dataclass(frozen=True)
class LawJob:
    """Everything the units of one law depend on (picklable: sent to Dask workers as is)."""

    spec: Any  # bayesfric.study.config.LawSpec
    noise: Noise
    ds: xr.Dataset
    config: SamplerConfig
    key: str  # hash of all of the above (with the law's and the package's code)

    @property
    def sampler(self) -> str:
        """The backend of the law's fit."""
        return self.config.name

    @property
    def settings(self) -> dict[str, Any]:
        """The backend's settings, as hashed into the key (:meth:`SamplerConfig.settings`)."""
        return self.config.settings()

    @property
    def seed(self) -> int:
        """The study's seed: every unit gets it explicitly."""
        return self.config.seed


@dataclass(frozen=True)
class Unit:
    """One unit of work of a law: ``stage`` in fit, loo, cv, bridge, importance, smc, checks."""

    law: str
    stage: str
    label: str  # display and result name: "fit", "loo", the CV scheme label, "bridge" ...
    key: str
    params: dict = field(default_factory=dict, compare=False, hash=False)

    @property
    def kind(self) -> str:
        """Store file kind: ``"nc"`` for the fit, ``"unit.nc"`` (the unit's Dataset) otherwise."""
        return "nc" if self.stage == "fit" else "unit.nc"

    @property
    def title(self) -> str:
        return f"{self.law} {self.label if self.stage != 'cv' else 'cv ' + self.label}"


def make_job(spec, noise: Noise, ds: xr.Dataset, config: SamplerConfig) -> LawJob:
    """The :class:`LawJob` of a study's law, keyed by everything the law's results depend on
    (of the sampler: its backend, :meth:`SamplerConfig.settings` and seed)."""
    program = build_program(spec.build(), ds, priors=spec.priors, noise=noise)
    law = program.law  # the entry's variant as it runs on this data, named by the entry's label
    key = unit_key(law=law.name, law_code=law_fingerprint(law), priors=dict(program.priors),
                   resolved=dict(program.resolved), noise=noise, constants=dict(program.constants),
                   data=data_fingerprint(ds), sampler=config.name, settings=config.settings(), seed=config.seed)
    return LawJob(spec, noise, ds, config, key)


def plan_law(job: LawJob, study, schemes: list[tuple[str, Any, str]]) -> tuple[Unit, list[Unit]]:
    """The fit unit of a law and the units that follow it (before any skip decision)."""
    name = job.spec.name

    def unit(stage: str, label: str, **params) -> Unit:
        return Unit(name, stage, label, unit_key(law=job.key, stage=stage, params=params), params)

    rest = []
    if study.loo:  # refits of high-k points on a fit that failed the gate only under failed_fits = "run"
        rest.append(unit("loo", "loo", **({"failed_fits": "run"} if study.failed_fits == "run" else {})))
    new = _new_groups(job, study)
    for label, folds, kind in schemes:
        extra = {"new_groups": new} if new is not None and kind == "blocked" else {}
        rest.append(unit("cv", label, kind=kind, train=folds.train, heldout=folds.heldout,
                         scheme=folds.scheme, labels=list(folds.labels), **extra))
    if study.evidence:
        rest += [unit("bridge", "bridge"), unit("importance", "importance")]
        if study.smc:
            rest.append(unit("smc", "SMC", particles=study.smc_particles, runs=study.smc_runs))
    rest.append(unit("checks", "checks"))
    return unit("fit", "fit"), rest


def _new_groups(job: LawJob, study) -> tuple[str, list[int]] | None:
    """The study's group column and each row's level (:func:`bayesfric.hierarchy.groupings_of`'s
    order): its blocked folds are also scored for a new level (:mod:`bayesfric.compare.newgroup`)."""
    column = getattr(study, "grouped", None)
    if not column or column not in job.ds.coords:
        return None
    from bayesfric.hierarchy import levels_of

    return column, [int(i) for i in levels_of(np.asarray(job.ds[column].values))[1]]


# -- computing ------------------------------------------------------------------------------------
def _program(job: LawJob):
    return build_program(job.spec.build(), job.ds, priors=job.spec.priors, noise=job.noise)


class Engines:
    """The compiled NUTS engine of the law whose units run now: its full fit and every fold
    refit share one compilation. Owned by whoever runs the units (:func:`compute`'s caller);
    holds one law's engine at a time and releases the previous law's compiled code when the
    next law's first unit asks (:func:`bayesfric.inference.release_compiled_code`).

    Examples
    --------
    >>> engines = Engines()
    >>> fit, _ = compute(job, fit_unit, engines=engines)              # doctest: +SKIP
    >>> loo, _ = compute(job, loo_unit, fit, engines=engines)         # the same compiled sampler  # doctest: +SKIP
    """

    def __init__(self):
        self._key: str | None = None
        self._engine: NutsEngine | None = None

    def of(self, job: LawJob) -> NutsEngine:
        """The law's engine (see :func:`_base_engine`), compiled on its first unit in this process."""
        if self._key != job.key:
            if self._key is not None:  # the previous law's samplers are not reused
                self._key, self._engine = None, None
                release_compiled_code(when_mapped_above=MAPPINGS_BUDGET)
            self._engine, self._key = _base_engine(job), job.key
        return self._engine


def _base_engine(job: LawJob) -> NutsEngine:
    """The law's compiled NUTS engine: its full fit and every fold refit.

    The engine's compiled warm-up is the study's ``tune``; the full fit uses all of it. Folds
    that remove a region or series start cold with a Stan warm-up of at most 500 steps, folds
    that drop a few points start from the full fit (:func:`_engine`); both run inside the same
    compiled sampler. An emcee study's folds are refitted with NUTS at the NUTS defaults' length.
    """
    config = job.config if job.sampler == "nuts" else SamplerConfig(draws=1000, tune=500, chains=4, seed=job.seed)
    return build(_program(job), config)


def _engine(job: LawJob, fit: xr.DataTree, warm: bool, engines: Engines):
    """The law's engine, warm-started from ``fit`` (a 250-step warm-up) or cold (≤ 500 steps)."""
    base = engines.of(job)
    warm_tune = min(250, base.tune)  # a warm start needs ≥ 120 warm-up steps within the engine's
    if warm and warm_tune >= 120:
        return base.warm_started(fit, warm_tune)
    cold_tune = min(500, base.tune)
    return base.cold_started(cold_tune) if cold_tune >= 120 else base


def _json_default(value: Any) -> Any:
    return value.tolist() if hasattr(value, "tolist") else str(value)


def _text(value: Any) -> str:
    """A free-form value (an estimator's diagnostics, a sampler's settings, the folds' verdicts) as
    one JSON attribute of the unit's Dataset: its keys differ by estimator, sampler and gate."""
    return json.dumps(value, default=_json_default)


# A unit's scalars are attributes of its Dataset, its arrays variables: writing NetCDF costs
# ~7 ms per variable or dimension (h5netcdf's dimension scales) against ~0.3 ms per attribute.
def evidence_dataset(result: compare.Evidence) -> xr.Dataset:
    """An evidence estimate as its unit's Dataset: attrs ``log_z``, ``error``, ``method``,
    ``diagnostics``."""
    return xr.Dataset(attrs={"log_z": float(result.log_z), "error": float(result.error), "method": result.method,
                             "diagnostics": _text(result.diagnostics)})


def loo_dataset(loo: compare.LooResult) -> xr.Dataset:
    """The LOO unit's Dataset: the pointwise elpd (exact refit values in place) and how the high-k
    points were handled; the Pareto-smoothed part is recomputed from the fit
    (:func:`bayesfric.study.rebuild.rebuild`)."""
    return xr.Dataset({"elpd_i": ("obs", np.asarray(loo.elpd_i, dtype=float)),
                       "refit_failed": ("refit_failed_row", np.asarray(loo.refit_failed, dtype=np.int64))},
                      attrs={"handling": loo.handling, "refitted": int(loo.refitted)})


def cv_dataset(cv: compare.CVResult) -> xr.Dataset:
    """A cross-validation unit's Dataset: the estimate, the pointwise elpd, the rows held out, the
    folds' verdicts (JSON, as a fit keeps its own) and the held-out predictive where kept."""
    kept = cv.predictive
    ds = xr.Dataset({"elpd_i": ("obs", np.asarray(cv.elpd_i, dtype=float)),
                     "heldout": ("obs", np.asarray(cv.heldout, dtype=bool))},
                    attrs={"elpd": float(cv.elpd), "se": float(cv.se), "seconds": float(cv.seconds), "law": cv.law,
                           "scheme": cv.scheme, "verdicts": _text([asdict(v) for v in cv.verdicts]),
                           "coverage": _text(cv.coverage),
                           "elpd_fold": _text(None if cv.elpd_fold is None else [float(v) for v in cv.elpd_fold]),
                           "elpd_new_group": _text(None if cv.elpd_new_group is None
                                                   else [float(v) for v in cv.elpd_new_group]),
                           "settings": _text(cv.settings), "too_few": cv.too_few})
    if kept is not None:
        ds = ds.assign(heldout_index=("kept", kept.index), heldout_fold=("kept", kept.fold),
                       heldout_mu=(("kept_draw", "kept"), kept.mu), heldout_noise_var=("kept", kept.noise_var))
    return ds


def checks_dataset(implausible: float, ks_pvalue: float, within_band: bool, ci_prob: float, psense: list[str],
                   pit: np.ndarray | None = None, band: np.ndarray | None = None,
                   structure: Sequence[StructureCheck] = ()) -> xr.Dataset:
    """The checks unit's Dataset: the prior predictive's implausible fraction, the LOO-PIT test
    (p-value, inside its ``ci_prob`` band, the values ``pit`` and the band's ``(point, lower,
    upper)``), the parameters power-scaling flags (``psense``, JSON) and the residual-structure
    tests (``structure_*`` over ``structure_column``, :func:`bayesfric.compare.structure_dataset`)."""
    ds = xr.Dataset(attrs={"prior_implausible": float(implausible), "loo_pit_pvalue": float(ks_pvalue),
                           "loo_pit_ok": int(bool(within_band)), "ci_prob": float(ci_prob),
                           "psense": _text(list(psense))})
    if pit is not None:
        ds["pit"] = ("pit_row", np.asarray(pit, dtype=float).ravel())
    if band is not None:
        ds["pit_band"] = (("band_edge", "band_point"), np.asarray(band, dtype=float).reshape(3, -1))
    if structure:
        ds = ds.assign(compare.structure_dataset(structure).data_vars)
    return ds


def _checks_unit(job: LawJob, fit: xr.DataTree, program) -> xr.Dataset:
    pit = compare.loo_pit_check(fit, seed=job.seed)
    sens = compare.prior_sensitivity(fit)
    prior = compare.fit_prior_draws(fit, program.law.params)  # the fit's 500 prior draws
    implausible = compare.prior_predictive_check(program, seed=job.seed, prior=prior).implausible
    psense = [f"{i} ({d})" for i, d in zip(sens.index, sens["diagnosis"], strict=True) if d != "-"]
    start = time.perf_counter()  # residuals against the data set's other columns
    structure = compare.residual_structure(fit, job.ds, program=program)
    out = checks_dataset(implausible, pit.ks_pvalue, pit.within_band, pit.ci_prob, psense, pit.pit, pit.band,
                         structure)
    out.attrs["structure_s"] = time.perf_counter() - start
    return out


def _compute_rest(job: LawJob, unit: Unit, fit: xr.DataTree, engines: Engines) -> xr.Dataset:
    """The Dataset of a unit after the fit (its scorer's result)."""
    passed = compare.verdict_of(fit).passed
    if unit.stage == "loo":
        # refits that drop one point start from the full fit's draws when it passed the gate; a
        # failed fit gets PSIS only unless the study runs failed fits' costly stages (failed_fits = "run")
        refit = passed or unit.params.get("failed_fits") == "run"
        return loo_dataset(compare.psis_loo(fit, engine=lambda: _engine(job, fit, passed, engines), seed=job.seed,
                                            no_refit="" if refit else NO_REFIT))
    if unit.stage == "cv":
        # random K-fold drops a few points (warm start); grouped and blocked folds start cold
        p = unit.params
        folds = compare.Folds(np.asarray(p["train"]), np.asarray(p["heldout"]), p["scheme"], p["labels"])
        return cv_dataset(compare.cross_validate(_engine(job, fit, passed and p["kind"] == "kfold", engines), folds,
                                                 seed=job.seed, predictive=p["kind"] in ("blocked", "forecast"),
                                                 joint=p["kind"] in ("grouped", "forecast"),
                                                 new_groups=tuple(p["new_groups"]) if "new_groups" in p else None,
                                                 min_groups=MIN_GROUPS if p["kind"] == "grouped" else 0))
    program = _program(job)
    if unit.stage == "bridge":
        return evidence_dataset(compare.bridge_log_evidence(program, fit, seed=job.seed))
    if unit.stage == "importance":  # one proposal at one mode: approximate on a multimodal fit (modes)
        result = compare.laplace_is_log_evidence(program, seed=job.seed)
        if note := single_mode_note(fit):
            result = replace(result, diagnostics={**result.diagnostics, "multimodal": note})
        return evidence_dataset(result)
    if unit.stage == "smc":
        return evidence_dataset(compare.smc_log_evidence(program, seed=job.seed, particles=unit.params["particles"],
                                                         runs=unit.params["runs"]))
    if unit.stage == "checks":
        return _checks_unit(job, fit, program)  # the LOO-PIT values and band: the report draws them
    raise InternalError(f"unknown unit stage {unit.stage!r}")


def compute(job: LawJob, unit: Unit, fit: xr.DataTree | None = None,
            engines: Engines | None = None) -> tuple[Result, float]:
    """Compute one unit; return its result (the fit, or the unit's Dataset) and its wall seconds.

    ``fit`` (the law's fit) is required by every unit except the fit itself. Runs in this process
    or on a Dask worker alike. A unit's Dataset carries its ``key``, ``stage`` and ``compute_s``
    (the seconds it took) as attributes: the run store trusts an entry only under its own key.
    ``engines`` keeps the law's compiled engine from one unit to the next (one compilation for
    the fit and every refit); without it each unit builds its own (read back from disk).
    """
    engines = Engines() if engines is None else engines
    start = time.perf_counter()
    if unit.stage == "fit":
        if job.sampler == "nuts":  # the all-true mask of the engine its folds will use
            dt = engines.of(job).fit(job.ds)
        else:
            dt = SAMPLERS[job.sampler](_program(job), job.ds, job.config)
        return dt, time.perf_counter() - start
    result = _compute_rest(job, unit, fit, engines)
    seconds = time.perf_counter() - start
    result.attrs.update(key=unit.key, stage=unit.stage, compute_s=seconds)
    return result, seconds


def compute_seconds(unit: Unit, result: Result) -> float:
    """Wall seconds the unit took when it was computed (NaN for a fit: its seconds lie beside it
    in the store, :meth:`bayesfric.study.store.RunStore.seconds`)."""
    if not isinstance(result, xr.Dataset):
        return float("nan")
    return float(result.attrs.get("compute_s", float("nan")))
