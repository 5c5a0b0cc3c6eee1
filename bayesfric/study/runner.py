"""A study's results: its laws' units through the run store and the executor, their weights and
each law's result Dataset, and the result tree that sizing, the claims and the report read.

The work is split into units (:mod:`bayesfric.study.units`) that are read back from the run store
when their key matches and computed otherwise, serially or on Dask (:mod:`bayesfric.study.store`,
:mod:`bayesfric.study.executor`); ``timings.csv`` in the report says which, and how long each took.
A killed run keeps its finished units for the next one.

The checks and the plan made before anything is written are :mod:`bayesfric.study.plan`
(re-exported here). The run of a study from its file to its installed report folder, which calls
these and then the report, is :mod:`bayesfric.pipeline.runner`, above the report: this package
never imports :mod:`bayesfric.report`, which reads it.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import xarray as xr

from bayesfric import compare, identifiability, sizing
from bayesfric.laws.variants import law_of_fit
from bayesfric.sizing.store import schemes_of
from bayesfric.study.config import Study
from bayesfric.study.executor import run_units
from bayesfric.study.lawresult import Weight, law_result
from bayesfric.study.plan import (  # checked and planned before anything is written; re-exported
    QUICK,
    QUICK_KFOLD,
    QuickRun,
    load_study_data,
    sizing_questions,
    validate_against_data,
)
from bayesfric.study.rebuild import rebuild
from bayesfric.study.store import RunStore, store_folder
from bayesfric.study.tree import study_tree

__all__ = ["run_laws", "result_tree", "validate_against_data", "sizing_questions", "load_study_data",
           "QUICK", "QUICK_KFOLD", "QuickRun"]


def run_laws(study: Study, work: Path, plans: list, schemes, *, out_root: Path, fresh: bool, client,
              timings: list, quick: bool, live_progress: bool | None = None) -> tuple[dict, dict]:
    """Every law's units through the run store and the executor: each law's fit and its units'
    results rebuilt as the compare layer's objects (:func:`bayesfric.study.rebuild.rebuild`), by
    law, in study order.

    Under ``--quick`` every stage runs even after a failed fit (``failed_fits = "run"``): quick
    settings rarely reach the gate's ESS, and a smoke test should exercise every stage.

    Units whose key is in the store are reused, the rest are computed (serially, or on the Dask
    ``client``); each result is stored as soon as it is done (:mod:`bayesfric.study.executor`).
    The fits are copied into ``work/fits/``; ``timings`` receives one row per unit and the
    skipped stages are returned with the results.
    """
    store = RunStore(store_folder(out_root, study.name), read=not fresh)
    for tmp in store.clean():
        print(f"[{study.name}] removed a temporary file of an interrupted run: {tmp}", flush=True)
    failed_fits = "run" if quick else study.failed_fits
    results, skipped, rows = run_units(plans, store, study=study.name, failed_fits=failed_fits,
                                       client=client, live=live_progress)
    timings += rows
    kinds = {label: kind for label, _, kind in schemes}
    fits, scored = {}, {}
    for job, fit, rest in plans:
        name = job.spec.name
        fit_file = work / "fits" / f"{name}.nc"
        fit_file.parent.mkdir(parents=True, exist_ok=True)
        # inside the work folder: installed atomically with the report; the bytes are the store's
        shutil.copyfile(store.path(fit.key, fit.kind), fit_file)
        fits[name] = results[fit.key]
        scored[name] = (rebuild(fits[name], rest, results, kinds), [u.label for u in skipped[name]])
    return fits, scored


def _weights(study: Study, blocked: list[str], scored: dict, fits: dict) -> tuple[dict, list]:
    """Stacking and pseudo-BMA+ weights from LOO and stacking from every scheme in ``blocked``
    (blocked, leave-future-out and leave-one-group-out labels), by law,
    and the weightings that could not be computed (why). Failed fits are excluded unless the
    study says otherwise."""
    bases = []
    if study.loo:
        bases += [("stacking LOO", "loo", "stacking"), ("pseudo-BMA+ LOO", "loo", "pseudo-BMA+")]
    # every blocked scheme: a sizing question is weighed by the schemes that extrapolate in its direction
    bases += [(f"stacking {label}", label, "stacking") for label in blocked]
    by_law: dict[str, dict[str, Weight]] = {name: {} for name in scored}
    errors = []
    for label, key, method in bases:
        results = {name: r for name, (s, _) in scored.items()
                   if (r := s.loo if key == "loo" else s.cv.get(key)) is not None}
        try:
            weights = compare.model_weights(results, method=method, include_failed=study.include_failed, fits=fits)
        except ValueError as exc:  # e.g. every fit excluded
            errors.append((label, str(exc)))
            continue
        for name in by_law:
            excluded = weights.excluded.get(name, "")
            by_law[name][label] = Weight(weights.weights.get(name, 0.0 if excluded else float("nan")), excluded)
    return by_law, errors


def _new_group_weights(study: Study, blocked: list[str], scored: dict, fits: dict, by_law: dict,
                       errors: list) -> None:
    """Add to ``by_law`` (and ``errors``) the weights of every blocked scheme scored for a new level
    of the study's group column (:mod:`bayesfric.compare.newgroup`; a scheme that cannot tell the
    laws apart with so few groups says why in ``errors``)."""
    from bayesfric.compare.newgroup import label
    from bayesfric.compare.weights import new_group_weights

    if not study.grouped:
        return
    for scheme in blocked:
        key = f"stacking {label(study.grouped, scheme)}"
        results = {name: r for name, (s, _) in scored.items() if (r := s.cv.get(scheme)) is not None}
        try:
            weights = new_group_weights(results, fits, study.include_failed)
        except ValueError as exc:
            errors.append((key, str(exc)))
            continue
        for name in by_law:
            excluded = weights.excluded.get(name, "")
            by_law[name][key] = Weight(weights.weights.get(name, 0.0 if excluded else float("nan")), excluded)


def _sensitivity(study: Study, scored: dict, fits: dict) -> compare.RankingSensitivity | None:
    """The prior sensitivity of the LOO ranking (two or more fits that may be ranked)."""
    if not study.loo or len(fits) < 2:
        return None
    reliable = {name: fit for name, fit in fits.items() if compare.verdict_of(fit).passed or study.include_failed}
    if len(reliable) < 2:
        return None
    psis = {name: scored[name][0].loo.psis for name in reliable if scored[name][0].loo is not None}
    return compare.ranking_sensitivity(reliable, baseline=psis)


def _law_results(study: Study, ds, blocked: list[str], scored: dict, fits: dict, weights: dict, rows: list,
                 failed_fits: str) -> list[xr.Dataset]:
    """Each law's result Dataset (:func:`bayesfric.study.lawresult.law_result`), in study order."""
    schemes = schemes_of(study, ds, blocked)
    out = []
    for name, (s, skipped) in scored.items():
        misses = {m.label: sizing.measure_miss(s.cv[m.label], ds, m) if m.label in s.cv else None for m in schemes}
        seconds = {r.label if r.stage != "cv" else f"cv {r.label}": r.seconds for r in rows
                   if r.law == name and r.status == "computed"}
        out.append(law_result(law_of_fit(fits[name].attrs), f"fits/{name}.nc", compare.verdict_of(fits[name]),
                              loo=s.loo, cv=s.cv, penalty=s.penalty, evidence=s.evidence, agreement=s.agreement,
                              checks=s.checks, misses=misses, weights=weights[name], skipped=skipped,
                              failed_fits=failed_fits, timings=seconds))
    return out


def result_tree(study: Study, ds, schemes: list, fits: dict, scored: dict, rows: list,
                 quick: QuickRun | None) -> xr.DataTree:
    """The study's result tree (:func:`bayesfric.study.tree.study_tree`) from its laws' results:
    their weights, the ranking's prior sensitivity and each law's result Dataset."""
    blocked = [label for label, _, kind in schemes if kind == "blocked"]
    forecast = [label for label, _, kind in schemes if kind == "forecast"]  # time to exceed weighs by these
    grouped = [label for label, _, kind in schemes if kind == "grouped"]  # sizing for a new group weighs by these
    weights, errors = _weights(study, blocked + forecast + grouped, scored, fits)
    _new_group_weights(study, blocked, scored, fits, weights, errors)
    laws = _law_results(study, ds, blocked, scored, fits, weights, rows,
                        "run" if quick is not None else study.failed_fits)
    checks = identifiability.checks_dataset(study.identifiability, identifiability.companions_of(study.laws))
    return study_tree(study, ds, schemes, laws, fits, sensitivity=_sensitivity(study, scored, fits),
                      weight_errors=errors, quick=quick, identifiability=checks)
