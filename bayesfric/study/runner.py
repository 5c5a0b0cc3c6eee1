"""Run a study: fit every candidate law, compare them every way the study asks, write the reports.

Output goes to ``<out_root>/<study>/`` atomically: everything is written into a marked hidden
work folder ``<out_root>/.<study>.<token>`` that replaces the old report folder only when the
whole study succeeded, so a failed or interrupted run never leaves a half-written report. Every
check of the study, its paths and its data runs before anything is written; an existing
``<out_root>/<study>`` is replaced only if bayesfric created it for this study. A run stopped
by SIGINT or SIGTERM removes its work folder on the way out; work folders of runs killed outright
(SIGKILL) are removed by the next run of the study (:mod:`bayesfric.fsutil`).

The work itself is split into units (:mod:`bayesfric.study.units`) that are read back from the run
store when their key matches and computed otherwise, serially or on Dask
(:mod:`bayesfric.study.store`, :mod:`bayesfric.study.executor`); ``timings.csv`` in the report says
which, and how long each took. A killed run keeps its finished units for the next one.

Besides the report files, every run saves its result tree ``results.nc``, whose ``/weights``,
``/diagnostics`` and ``/sizing_basis`` nodes (:mod:`bayesfric.sizing.store`) hold the weights,
verdicts, weighting exclusions, misses and penalties of every law, so ``bayesfric size`` can
answer sizing questions from ``fits/*.nc`` later without refitting. A study
with ``[[sizing]]`` questions also gets them answered here: ``sizing.csv``, a fan figure per
question and a sizing section in ``summary.md`` and ``report.html``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from bayesfric import compare, fsutil, identifiability, sizing
from bayesfric.fingerprint import package_fingerprint
from bayesfric.laws.variants import law_of_fit
from bayesfric.sizing import exceed
from bayesfric.sizing.store import schemes_of
from bayesfric.study import units
from bayesfric.study.claims import evaluate_claims
from bayesfric.study.config import Study, StudyError
from bayesfric.study.executor import open_client, run_units, timing_table, unit_seconds, write_timings
from bayesfric.study.lawresult import Weight, law_result
from bayesfric.study.plan import (  # checked and planned before anything is written; re-exported
    QUICK,
    QUICK_KFOLD,
    QuickRun,
    _plan_laws,
    _prepare,
    load_study_data,
    sizing_questions,
    validate_against_data,
)
from bayesfric.study.store import RunStore, store_folder
from bayesfric.study.tree import run_attrs, study_tree

__all__ = ["run_study", "execute_study", "StudyRun",
           "current_report", "validate_against_data", "sizing_questions", "load_study_data", "INPUTS_FILE",
           "QUICK", "QUICK_KFOLD"]

#: Written into a report folder: the key of everything the report was rendered from. A rerun
#: whose key matches (an unchanged study, every unit in the store) leaves the report as it is.
INPUTS_FILE = ".bayesfric-inputs"



def _portable(raw: dict) -> dict:
    """A study's tables without the places they name (:func:`_inputs_key` of a study built in
    Python): each law file as the SHA-256 of its bytes, the data set as its file name (its
    content is in every unit key)."""
    out = json.loads(json.dumps(raw, default=str))
    section = out.get("study") if isinstance(out.get("study"), dict) else {}
    files = []
    for name in section.get("modules") or []:
        try:
            files.append(hashlib.sha256(Path(str(name)).read_bytes()).hexdigest())
        except OSError:
            files.append(Path(str(name)).name)
    if files:
        section["modules"] = files
    data = out.get("data") if isinstance(out.get("data"), dict) else {}
    if isinstance(data.get("dataset"), str):
        data["dataset"] = Path(data["dataset"]).name
    return out


def _inputs_key(study: Study, plans: list, quick: bool) -> str:
    """SHA-256 of everything a report is rendered from: the study file's bytes, every unit key
    (data, laws, priors, settings, seed, computing code) and every source file and template.

    No absolute path enters it (nor a unit key: :func:`bayesfric.fingerprint.data_fingerprint`),
    so a project folder moved or copied with its ``reports/`` finds its report current.
    """
    text = (study.path.read_bytes() if study.path.is_file()
            else json.dumps(_portable(study.raw), sort_keys=True).encode())
    digest = hashlib.sha256(text)  # a study built in Python (bayesfric.Study) has no file: its tables
    digest.update(json.dumps({"quick": quick, "units": [[u.key for u in (fit, *rest)] for _, fit, rest in plans]},
                             sort_keys=True).encode())
    digest.update(package_fingerprint().encode())
    return digest.hexdigest()


def _report_is_current(final: Path, study: str, key: str) -> bool:
    """The report folder was written by bayesfric for this study from exactly these inputs."""
    try:
        return fsutil.is_marked(final, study) and (final / INPUTS_FILE).read_text().strip() == key
    except OSError:
        return False


def _unchanged_note(name: str, final: Path) -> str:
    return (f"[{name}] unchanged: the report in {final} was written from the same study file, data, "
            "units and code; nothing recomputed or rewritten (--fresh recomputes)")


def current_report(path: str | Path, out_root: str | Path = "reports", quick: bool = False) -> Path | None:
    """The report folder of the study at ``path`` when an unchanged rerun would leave it as it is
    (same study file, data, unit keys and code: what :func:`run_study` checks first), else None;
    prints the study's "unchanged" line when it is. Checks the study and its data as
    :func:`run_study` does (same errors), writes nothing."""
    study, final, ds, settings, _, schemes, _ = _prepare(path, out_root, quick)
    plans = _plan_laws(study, ds, schemes, settings, study.sampler["seed"])
    if not _report_is_current(final, study.name, _inputs_key(study, plans, quick)):
        return None
    print(_unchanged_note(study.name, final), flush=True)
    return final


def _run_laws(study: Study, work: Path, plans: list, schemes, *, out_root: Path, fresh: bool, client,
              timings: list, quick: bool, live_progress: bool | None = None) -> tuple[dict, dict]:
    """Every law's units through the run store and the executor: each law's fit and its units'
    results rebuilt as the compare layer's objects (:func:`bayesfric.study.units.rebuild`), by
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
        scored[name] = (units.rebuild(fits[name], rest, results, kinds), [u.label for u in skipped[name]])
    return fits, scored


def _weights(study: Study, blocked: list[str], scored: dict, fits: dict) -> tuple[dict, list]:
    """Stacking and pseudo-BMA+ weights from LOO and stacking from every blocked scheme, by law,
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


@dataclass(frozen=True)
class StudyRun:
    """What one run of a study leaves in memory (:func:`execute_study`): its report folder and,
    when the run wrote the report (not an unchanged rerun), the result tree it saved as
    ``results.nc`` and every law's full fit, so a caller never reads back what this process wrote."""

    folder: Path
    tree: xr.DataTree | None = None
    fits: Mapping[str, xr.DataTree] | None = None


def run_study(path: str | Path | Study, out_root: str | Path = "reports", quick: bool = False, *, fresh: bool = False,
              workers: int = 0, scheduler: str | None = None, client=None, timings: list | None = None,
              live_progress: bool | None = None) -> Path:
    """Run the study file at ``path`` and write ``<out_root>/<study name>/``.

    Parameters
    ----------
    path : str, Path or Study
        Study TOML file, or a study already loaded (:func:`~bayesfric.study.config.load_study`,
        :class:`bayesfric.Study`).
    out_root : str or Path
        Reports root folder (created if missing).
    quick : bool
        Smoke test: fewer draws and folds (:data:`QUICK`, :data:`QUICK_KFOLD`), applied after
        the study's own settings were validated; the report says so.
    fresh : bool
        Recompute every unit instead of reusing the run store (results are stored again).
    workers, scheduler
        Run units on a Dask local cluster of ``workers`` processes, or on the cluster whose
        scheduler listens at ``scheduler`` (:func:`bayesfric.study.executor.open_client`);
        ``client`` passes an open Dask client instead (the main job shares one).
    timings : list, optional
        Receives the run's :class:`~bayesfric.study.executor.Timing` rows (one per unit).
    live_progress : bool, optional
        A progress bar (True) or plain lines (False); default: a bar when stdout is a terminal.

    Returns
    -------
    Path
        The report folder.

    Raises
    ------
    StudyError, DataError
        One line, on bad input, before anything is written.
    """
    return execute_study(path, out_root, quick, fresh=fresh, workers=workers, scheduler=scheduler, client=client,
                         timings=timings, live_progress=live_progress).folder


def execute_study(path: str | Path | Study, out_root: str | Path = "reports", quick: bool = False, *,
                  fresh: bool = False, workers: int = 0, scheduler: str | None = None, client=None,
                  timings: list | None = None, live_progress: bool | None = None) -> StudyRun:
    """:func:`run_study`, returning the :class:`StudyRun` (folder, result tree and fits) instead of
    the folder alone; same parameters and errors."""
    start = time.perf_counter()
    prepared = _prepare(path, out_root, quick)
    with contextlib.ExitStack() as stack:
        if client is None:  # connected before anything is written: a bad --scheduler writes nothing
            client = stack.enter_context(open_client(workers, scheduler))
        return _write_study(prepared, Path(out_root), quick, fresh, client, timings, start, live_progress)


def _result_tree(study: Study, ds, schemes: list, fits: dict, scored: dict, rows: list,
                 quick: QuickRun | None) -> xr.DataTree:
    """The study's result tree (:func:`bayesfric.study.tree.study_tree`) from its laws' results:
    their weights, the ranking's prior sensitivity and each law's result Dataset."""
    blocked = [label for label, _, kind in schemes if kind == "blocked"]
    forecast = [label for label, _, kind in schemes if kind == "forecast"]  # time to exceed weighs by these
    weights, errors = _weights(study, blocked + forecast, scored, fits)
    laws = _law_results(study, ds, blocked, scored, fits, weights, rows,
                        "run" if quick is not None else study.failed_fits)
    checks = identifiability.checks_dataset(study.identifiability, identifiability.companions_of(study.laws))
    return study_tree(study, ds, schemes, laws, fits, sensitivity=_sensitivity(study, scored, fits),
                      weight_errors=errors, quick=quick, identifiability=checks)


def _write_study(prepared, out_root: Path, quick: bool, fresh: bool, client, timings: list | None,
                 start: float, live_progress: bool | None = None) -> StudyRun:
    """Run the prepared study's units and write its report folder atomically (see :func:`run_study`)."""
    study, final, ds, settings, kfold, schemes, questions = prepared
    seed = study.sampler["seed"]
    root = final.parent
    plans = _plan_laws(study, ds, schemes, settings, seed)
    inputs_key = _inputs_key(study, plans, quick)
    if not fresh and _report_is_current(final, study.name, inputs_key):
        print(_unchanged_note(study.name, final), flush=True)
        return StudyRun(final)
    for stale in fsutil.clean_stale_work(root, study.name):
        print(f"[{study.name}] removed the work folder of an interrupted run: {stale}", flush=True)
    for line in identifiability.describe(study.identifiability, identifiability.companions_of(study.laws)):
        print(f"[{study.name}] before fitting, the data do not identify {line}", flush=True)
    work = fsutil.create_work_folder(root, study.name)
    try:
        rows: list = []
        fits, scored = _run_laws(study, work, plans, schemes, out_root=out_root, fresh=fresh, client=client,
                                 timings=rows, quick=quick, live_progress=live_progress)
        write_timings(rows, work / "timings.csv")
        if timings is not None:
            timings += rows
        tree = _result_tree(study, ds, schemes, fits, scored, rows, QuickRun(settings, (study.kfold, kfold))
                            if quick else None)  # built once: sizing, the claims and the report read it
        sized = None
        held = {name: tree[f"fits/{name}"] for name in fits}
        if at_point := [q for q in questions if q.horizon is None]:
            print(f"[{study.name}] sizing {len(at_point)} question(s) ...", flush=True)
            sized = sizing.size_study(at_point, ds, sizing.sources(tree, work, list(held), fits=held),
                                      sizing.basis_schemes(tree), study_name=study.name, seed=seed)
        if service := [q for q in questions if q.horizon is not None]:
            print(f"[{study.name}] time to exceed, {len(service)} question(s) ...", flush=True)
            column = next(c for spec in study.laws for c in spec.trend)
            tree["service"] = exceed.answer_study(service, held, tree, unit=ds[column].attrs.get("units", ""),
                                                  seed=seed)
        claims = evaluate_claims(study.claims, tree)
        tree.attrs.update(run_attrs(time.perf_counter() - start, unit_seconds(rows)))
        from bayesfric.report.summary import write_reports  # here: bayesfric.report reads bayesfric.study

        tree = write_reports(tree, work, ds, fits, claims, sized)
        (work / INPUTS_FILE).write_text(inputs_key + "\n")  # an unchanged rerun reuses the whole report
        try:
            fsutil.install_folder(work, final, study.name)
        except fsutil.PathError as exc:
            raise StudyError(f"{study.path}: [study] name: {exc}") from None
    except BaseException:
        fsutil.remove_work_folder(work, study.name)
        raise
    print(timing_table(rows, f"[{study.name}] time per stage"), flush=True)
    print(f"[{study.name}] report written to {final} ({time.perf_counter() - start:.0f} s)")
    return StudyRun(final, tree, fits)
