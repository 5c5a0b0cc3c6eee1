"""Run a study: fit every candidate law, compare them every way the study asks, write the reports.

Output goes to ``<out_root>/<study>/`` atomically: everything is written into a marked hidden
work folder ``<out_root>/.<study>.<token>`` that replaces the old report folder only when the
whole study succeeded, so a failed or interrupted run never leaves a half-written report. Every
check of the study, its paths and its data runs before anything is written; an existing
``<out_root>/<study>`` is replaced only if bayesfric created it for this study; work folders of
killed runs are removed by the next run of the study (:mod:`bayesfric.fsutil`).

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
import dataclasses
import hashlib
import json
import math
import shutil
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from bayesfric import compare, fsutil, sizing
from bayesfric.fingerprint import package_fingerprint
from bayesfric.study import units
from bayesfric.study.claims import evaluate_claims
from bayesfric.study.config import Study, StudyError
from bayesfric.study.executor import open_client, run_units, timing_table, write_timings
from bayesfric.study.outcome import LawOutcome, QuickRun, StudyOutcome, UnitSeconds, Weight
from bayesfric.study.plan import (  # checked and planned before anything is written; re-exported
    QUICK,
    QUICK_KFOLD,
    _plan_laws,
    _prepare,
    load_study_data,
    sizing_questions,
    validate_against_data,
)
from bayesfric.study.scores import score_table
from bayesfric.study.store import RunStore, store_folder
from bayesfric.study.tree import run_attrs, study_tree

__all__ = ["run_study", "execute_study", "StudyRun",
           "current_report", "validate_against_data", "sizing_questions", "load_study_data", "INPUTS_FILE",
           "QUICK", "QUICK_KFOLD"]

#: Written into a report folder: the key of everything the report was rendered from. A rerun
#: whose key matches (an unchanged study, every unit in the store) leaves the report as it is.
INPUTS_FILE = ".bayesfric-inputs"



def _inputs_key(study: Study, plans: list, quick: bool) -> str:
    """SHA-256 of everything a report is rendered from: the study file, every unit key (data,
    laws, priors, settings, seed, computing code) and every source file and template."""
    text = study.path.read_bytes() if study.path.is_file() else json.dumps(study.raw, sort_keys=True).encode()
    digest = hashlib.sha256(text)  # a study built in Python (bayesfric.Study) has no file: its keys
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


def _run_laws(study: Study, ds, work: Path, plans: list, schemes, *, out_root: Path,
              fresh: bool, client, timings: list, quick: bool, live_progress: bool | None = None) -> list[LawOutcome]:
    """Every law's units through the run store and the executor; their outcomes, in study order.

    Under ``--quick`` every stage runs even after a failed fit (``failed_fits = "run"``): quick
    settings rarely reach the gate's ESS, and a smoke test should exercise every stage.

    Units whose key is in the store are reused, the rest are computed (serially, or on the Dask
    ``client``); each result is stored as soon as it is done (:mod:`bayesfric.study.executor`).
    The fits are copied into ``work/fits/``.
    """
    store = RunStore(store_folder(out_root, study.name), read=not fresh)
    for tmp in store.clean():
        print(f"[{study.name}] removed a temporary file of an interrupted run: {tmp}", flush=True)
    failed_fits = "run" if quick else study.failed_fits
    results, skipped, rows = run_units(plans, store, study=study.name, failed_fits=failed_fits,
                                       client=client, live=live_progress)
    timings += rows
    kinds = {label: kind for label, _, kind in schemes}
    outcomes = []
    for job, fit, rest in plans:
        fit_file = work / "fits" / f"{job.spec.name}.nc"
        fit_file.parent.mkdir(parents=True, exist_ok=True)
        # inside the work folder: installed atomically with the report; the bytes are the store's
        shutil.copyfile(store.path(fit.key, fit.kind), fit_file)
        out = units.assemble(results[fit.key], fit_file, rest, results, kinds, skipped[job.spec.name], failed_fits)
        seconds = {r.label if r.stage != "cv" else f"cv {r.label}": r.seconds for r in rows
                   if r.law == job.spec.name and r.status == "computed"}
        outcomes.append(dataclasses.replace(out, timings=seconds))
    return outcomes


def _unit_seconds(rows: list) -> UnitSeconds:
    """Seconds the units computed in this run took, and what the reused ones cost when computed
    (the report's footer: a resumed run's wall time alone hides the real cost)."""
    reused = [r.stored_seconds for r in rows if r.status == "reused"]
    return UnitSeconds(computed=float(sum(r.seconds for r in rows if r.status == "computed")), reused=len(reused),
                       saved=float(sum(s for s in reused if math.isfinite(s))),
                       unknown=sum(not math.isfinite(s) for s in reused))


def _assign_weights(out: StudyOutcome) -> None:
    """Stacking and pseudo-BMA+ weights from LOO, stacking from the first blocked scheme, and the
    prior sensitivity of the LOO ranking. Failed fits are excluded unless the study says otherwise."""
    fits = {w.name: w.fit for w in out.laws}
    bases = []
    if out.study.loo:
        bases += [("stacking LOO", "loo", "stacking"), ("pseudo-BMA+ LOO", "loo", "pseudo-BMA+")]
    # every blocked scheme: a sizing question is weighed by the schemes that extrapolate in its direction
    bases += [(f"stacking {label}", label, "stacking") for label in out.blocked]
    by_law: dict[str, dict[str, Weight]] = {w.name: {} for w in out.laws}
    for label, key, method in bases:
        results = {w.name: r for w in out.laws if (r := w.loo if key == "loo" else w.cv.get(key)) is not None}
        try:
            weights = compare.model_weights(results, method=method, include_failed=out.study.include_failed,
                                            fits=fits)
        except ValueError as exc:  # e.g. every fit excluded
            out.weight_errors.append((label, str(exc)))
            continue
        for name in by_law:
            excluded = weights.excluded.get(name, "")
            by_law[name][label] = Weight(weights.weights.get(name, 0.0 if excluded else float("nan")), excluded)
    out.laws = [dataclasses.replace(w, weights=by_law[w.name]) for w in out.laws]
    if out.study.loo and len(fits) > 1:
        reliable = {w.name: w.fit for w in out.laws if w.reliable or out.study.include_failed}
        if len(reliable) > 1:
            psis = {w.name: w.loo.psis for w in out.laws if w.name in reliable and w.loo is not None}
            out.sensitivity = compare.ranking_sensitivity(reliable, baseline=psis)


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
    work = fsutil.create_work_folder(root, study.name)
    try:
        rows: list = []
        outcomes = _run_laws(study, ds, work, plans, schemes, out_root=out_root, fresh=fresh,
                             client=client, timings=rows, quick=quick, live_progress=live_progress)
        write_timings(rows, work / "timings.csv")
        if timings is not None:
            timings += rows
        outcome = StudyOutcome(study=study, data=ds, laws=outcomes, schemes=[s[0] for s in schemes],
                               blocked=[s[0] for s in schemes if s[2] == "blocked"],
                               heldout={s[0]: s[1].heldout.any(axis=0) for s in schemes})
        if quick:
            outcome.quick = QuickRun(settings, (study.kfold, kfold))
        _assign_weights(outcome)
        outcome.table = score_table(outcome)
        tree = study_tree(outcome)  # built once: sizing, the claims and the report read it
        sized = None
        if questions:
            print(f"[{study.name}] sizing {len(questions)} question(s) ...", flush=True)
            fits = {w.name: tree[f"fits/{w.name}"] for w in outcome.laws}
            sized = sizing.size_study(questions, ds, sizing.sources(tree, work, list(fits), fits=fits),
                                      sizing.basis_schemes(tree), study_name=study.name, seed=seed)
        claims = evaluate_claims(study.claims, tree)
        tree.attrs.update(run_attrs(time.perf_counter() - start, _unit_seconds(rows)))
        from bayesfric.report.summary import write_reports  # here: bayesfric.report reads bayesfric.study

        tree = write_reports(tree, work, ds, {w.name: w.fit for w in outcome.laws}, claims, sized)
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
    return StudyRun(final, tree, {w.name: w.fit for w in outcome.laws})
