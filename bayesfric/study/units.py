"""A law's work in a study, split into units with explicit inputs and plain serialisable outputs.

Units of one law (:func:`plan_law`): ``fit`` (the full fit), then — all reading the fit —
``loo`` (PSIS-LOO with exact refits of high-k points), one ``cv`` unit per cross-validation scheme,
``bridge`` and ``importance`` evidence estimates, ``smc`` (opt-in) and ``checks`` (prior
predictive, LOO-PIT, power-scaling sensitivity). Every unit runs through :func:`compute`, a pure
function of a :class:`LawJob` (the law, its priors and constants, noise, selected data, sampler
settings, seed), the :class:`Unit` and the fit; it returns the fit (a DataTree) or a
:class:`~bayesfric.study.store.Record` (arrays plus a JSON-able record), plain objects that the run
store writes and reads back (:mod:`bayesfric.study.store`) and a Dask worker sends as they are; in
one process the units hand each other the objects, never their bytes. Each unit gets the study
seed explicitly (no random stream is shared between units), so the order in which units run —
serially or on any number of workers — does not change a number. :func:`assemble` turns the results back into a
:class:`~bayesfric.study.outcome.LawOutcome`; the same function reads fresh and stored results.

The fit's verdict decides the rest: under ``[compare] failed_fits = "skip"`` (the default) a law
whose full fit failed the diagnostics gate gets no CV refits and no evidence (the costly stages);
its outcome lists them in ``skipped`` and its flags say why. That is why every unit of a law waits
for its fit, even those that could start without it (blocked CV, importance sampling).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from bayesfric import compare
from bayesfric.compare.heldout import HeldOut
from bayesfric.compare.loo import loo_from_values
from bayesfric.fingerprint import data_fingerprint, law_fingerprint, unit_key
from bayesfric.inference import MAPPINGS_BUDGET, SAMPLERS, release_compiled_code
from bayesfric.inference.diagnostics import Verdict
from bayesfric.laws.variants import law_of_fit
from bayesfric.model import Noise, build_program
from bayesfric.study.outcome import Checks, LawOutcome
from bayesfric.study.store import Record, Result

__all__ = ["LawJob", "Unit", "make_job", "plan_law", "compute", "assemble", "COSTLY"]

#: Stages skipped for a law whose full fit failed the gate under ``failed_fits = "skip"``.
COSTLY = ("cv", "bridge", "importance", "smc")


@dataclass(frozen=True)
class LawJob:
    """Everything the units of one law depend on (picklable: sent to Dask workers as is)."""

    spec: Any  # bayesfric.study.config.LawSpec
    noise: Noise
    ds: xr.Dataset
    sampler: str
    settings: dict
    seed: int
    key: str  # hash of all of the above (with the law's and the package's code)


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
        """Store file kind: ``"nc"`` for the fit, ``"npz"`` otherwise."""
        return "nc" if self.stage == "fit" else "npz"

    @property
    def title(self) -> str:
        return f"{self.law} {self.label if self.stage != 'cv' else 'cv ' + self.label}"


def make_job(spec, noise: Noise, ds: xr.Dataset, sampler: str, settings: dict, seed: int) -> LawJob:
    """The :class:`LawJob` of a study's law, keyed by everything the law's results depend on."""
    program = build_program(spec.build(), ds, priors=spec.priors, noise=noise)
    law = program.law  # the entry's variant as it runs on this data, named by the entry's label
    key = unit_key(law=law.name, law_code=law_fingerprint(law), priors=dict(program.priors),
                   resolved=dict(program.resolved), noise=noise, constants=dict(program.constants),
                   data=data_fingerprint(ds), sampler=sampler, settings=settings, seed=seed)
    return LawJob(spec, noise, ds, sampler, dict(settings), seed, key)


def plan_law(job: LawJob, study, schemes: list[tuple[str, Any, str]]) -> tuple[Unit, list[Unit]]:
    """The fit unit of a law and the units that follow it (before any skip decision)."""
    name = job.spec.name

    def unit(stage: str, label: str, **params) -> Unit:
        return Unit(name, stage, label, unit_key(law=job.key, stage=stage, params=params), params)

    rest = []
    if study.loo:
        rest.append(unit("loo", "loo"))
    for label, folds, kind in schemes:
        rest.append(unit("cv", label, kind=kind, train=folds.train, heldout=folds.heldout,
                         scheme=folds.scheme, labels=list(folds.labels)))
    if study.evidence:
        rest += [unit("bridge", "bridge"), unit("importance", "importance")]
        if study.smc:
            rest.append(unit("smc", "SMC", particles=study.smc_particles, runs=study.smc_runs))
    rest.append(unit("checks", "checks"))
    return unit("fit", "fit"), rest


# -- computing ------------------------------------------------------------------------------------
_ENGINES: dict[str, Any] = {}  # this process's compiled engine of ONE law (fit and folds: one compilation)


def _program(job: LawJob):
    return build_program(job.spec.build(), job.ds, priors=job.spec.priors, noise=job.noise)


def _base_engine(job: LawJob):
    """The law's compiled NUTS engine: its full fit and every fold refit in this process.

    The engine's compiled warm-up is the study's ``tune``; the full fit uses all of it. Folds
    that remove a region or series start cold with a Stan warm-up of at most 500 steps, folds
    that drop a few points start from the full fit (:func:`_engine`); both run inside the same
    compiled sampler. An emcee study's folds are refitted with NUTS at the NUTS defaults' length.
    """
    if any(k != job.key for k in _ENGINES):
        _ENGINES.clear()
        release_compiled_code(when_mapped_above=MAPPINGS_BUDGET)  # the previous law's samplers are not reused
    if job.key not in _ENGINES:
        s = job.settings
        nuts_keys = ("target_accept", "retry_target_accept", "max_tree_depth", "metric", "init")
        settings = (dict(draws=s["draws"], tune=s["tune"], chains=s.get("chains", 4),
                         **{k: s[k] for k in nuts_keys if k in s})
                    if job.sampler == "nuts" else dict(draws=1000, tune=500, chains=4))
        _ENGINES[job.key] = compare.RefitEngine(_program(job), seed=job.seed, **settings)
    return _ENGINES[job.key]


def _engine(job: LawJob, fit: xr.DataTree, warm: bool):
    """The law's engine, warm-started from ``fit`` (a 250-step warm-up) or cold (≤ 500 steps)."""
    base = _base_engine(job)
    warm_tune = min(250, base.tune)  # a warm start needs ≥ 120 warm-up steps within the engine's
    if warm and warm_tune >= 120:
        return base.warm_started(fit, warm_tune)
    cold_tune = min(500, base.tune)
    return base.cold_started(cold_tune) if cold_tune >= 120 else base


def _json_default(value: Any) -> Any:
    return value.tolist() if hasattr(value, "tolist") else str(value)


def _evidence_record(result) -> dict:
    return {"log_z": result.log_z, "error": result.error, "method": result.method,
            "diagnostics": json.loads(json.dumps(result.diagnostics, default=_json_default))}


def _compute_rest(job: LawJob, unit: Unit, fit: xr.DataTree) -> tuple[dict, dict]:
    """(record, arrays) of a unit after the fit."""
    passed = compare.verdict_of(fit).passed
    if unit.stage == "loo":
        # refits that drop one point start from the full fit's draws when it passed the gate
        loo = compare.psis_loo(fit, engine=lambda: _engine(job, fit, warm=passed), seed=job.seed)
        return ({"handling": loo.handling, "refit_failed": loo.refit_failed, "refitted": loo.refitted},
                {"elpd_i": loo.elpd_i})
    if unit.stage == "cv":
        # random K-fold drops a few points (warm start); grouped and blocked folds start cold
        p = unit.params
        folds = compare.Folds(np.asarray(p["train"]), np.asarray(p["heldout"]), p["scheme"], p["labels"])
        cv = compare.cross_validate(_engine(job, fit, warm=passed and p["kind"] == "kfold"), folds, seed=job.seed,
                                    predictive=p["kind"] == "blocked")
        kept = cv.predictive.arrays() if cv.predictive is not None else {}
        return ({"law": cv.law, "scheme": cv.scheme, "elpd": cv.elpd, "se": cv.se, "seconds": cv.seconds,
                 "verdicts": [v.to_json() for v in cv.verdicts], "settings": cv.settings},
                {"elpd_i": cv.elpd_i, "heldout": cv.heldout} | kept)
    program = _program(job)
    if unit.stage == "bridge":
        return _evidence_record(compare.bridge_log_evidence(program, fit, seed=job.seed)), {}
    if unit.stage == "importance":
        return _evidence_record(compare.laplace_is_log_evidence(program, seed=job.seed)), {}
    if unit.stage == "smc":
        return _evidence_record(compare.smc_log_evidence(program, seed=job.seed, particles=unit.params["particles"],
                                                         runs=unit.params["runs"])), {}
    if unit.stage == "checks":
        pit = compare.loo_pit_check(fit, seed=job.seed)
        sens = compare.prior_sensitivity(fit)
        prior = compare.fit_prior_draws(fit, program.law.params)  # the fit's 500 prior draws
        return {"implausible": compare.prior_predictive_check(program, seed=job.seed, prior=prior).implausible,
                "ks_pvalue": pit.ks_pvalue, "within_band": bool(pit.within_band), "ci_prob": pit.ci_prob,
                "psense": [f"{i} ({d})" for i, d in zip(sens.index, sens["diagnosis"], strict=True) if d != "-"]}, \
            {"pit": pit.pit, "pit_band": pit.band}  # the LOO-PIT values and band: the report draws them
    raise ValueError(f"unknown unit stage {unit.stage!r}")


def compute(job: LawJob, unit: Unit, fit: xr.DataTree | None = None) -> tuple[Result, float]:
    """Compute one unit; return its result (the fit, or a :class:`Record`) and its wall seconds.

    ``fit`` (the law's fit) is required by every unit except the fit itself. Runs in this process
    or on a Dask worker alike.
    """
    start = time.perf_counter()
    if unit.stage == "fit":
        if job.sampler == "nuts":  # the all-true mask of the engine its folds will use
            dt = _base_engine(job).fit(job.ds)
        else:
            dt = SAMPLERS[job.sampler](_program(job), job.ds, seed=job.seed, **job.settings)
        return dt, time.perf_counter() - start
    record, arrays = _compute_rest(job, unit, fit)
    seconds = time.perf_counter() - start
    return Record({"key": unit.key, "stage": unit.stage, "compute_s": seconds} | record, arrays), seconds


def compute_seconds(unit: Unit, result: Result) -> float:
    """Wall seconds the unit took when it was computed (NaN for a fit: its seconds lie beside it
    in the store, :meth:`bayesfric.study.store.RunStore.seconds`)."""
    if not isinstance(result, Record):
        return float("nan")
    return float(result.record.get("compute_s", float("nan")))


# -- assembling ----------------------------------------------------------------------------------
def _evidence(result: Record) -> compare.Evidence:
    record = result.record
    return compare.Evidence(record["log_z"], record["error"], record["method"], record["diagnostics"])


def assemble(fit: xr.DataTree, fit_file, units: list[Unit], results: dict[str, Result],
             kinds: dict[str, str], skipped: list[Unit], failed_fits: str) -> LawOutcome:
    """The :class:`LawOutcome` of a law from its fit and its units' results (fresh or stored).

    ``kinds`` maps a CV label to its scheme kind (kfold, grouped, blocked); ``skipped`` lists the
    units not run because the fit failed the gate.
    """
    by_stage = {u.label: results[u.key] for u in units if u.key in results}
    loo = None
    if "loo" in by_stage:
        record, arrays = by_stage["loo"].record, by_stage["loo"].arrays
        loo = loo_from_values(fit, arrays["elpd_i"], record["handling"], record["refit_failed"], record["refitted"])
    cv = {u.label: _cv(results[u.key]) for u in units if u.stage == "cv" and u.key in results}
    penalties = {label: compare.extrapolation_penalty(loo, result) for label, result in cv.items()
                 if kinds[label] == "blocked" and loo is not None}
    evidence = {name: _evidence(by_stage[name]) for name in ("bridge", "importance", "SMC") if name in by_stage}
    # Two estimators that share only the density (bench_evidence.py); never averaged.
    agreement = (compare.compare_estimators(evidence["bridge"], evidence["importance"])
                 if {"bridge", "importance"} <= set(evidence) else None)
    checks = _checks(by_stage["checks"].record, by_stage["checks"].arrays) if "checks" in by_stage else None
    return LawOutcome(law=law_of_fit(fit.attrs), fit=fit, fit_file=fit_file, verdict=compare.verdict_of(fit),
                      loo=loo, cv=cv, penalty={k: p.per_point for k, p in penalties.items()},
                      penalty_se={k: p.se for k, p in penalties.items()}, evidence=evidence, agreement=agreement,
                      checks=checks,
                      skipped=tuple(u.label for u in skipped), failed_fits=failed_fits)


def _cv(result: Record) -> compare.CVResult:
    record, arrays = result.record, result.arrays
    return compare.CVResult(law=record["law"], scheme=record["scheme"], elpd=record["elpd"], se=record["se"],
                            elpd_i=arrays["elpd_i"], heldout=arrays["heldout"].astype(bool),
                            verdicts=[Verdict.from_json(v) for v in record["verdicts"]], seconds=record["seconds"],
                            settings=record["settings"], predictive=HeldOut.from_arrays(arrays))


def _checks(record: dict, arrays: dict) -> Checks:
    pit = arrays.get("pit")
    return Checks(prior_implausible=record["implausible"], loo_pit_pvalue=record["ks_pvalue"],
                  loo_pit_ok=bool(record["within_band"]), ci_prob=record["ci_prob"], psense=tuple(record["psense"]),
                  pit=pit, pit_band=arrays.get("pit_band"),
                  pit_shape=compare.pit_shape(pit) if pit is not None else None)
