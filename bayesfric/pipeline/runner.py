"""Run a study: fit every candidate law, compare them every way the study asks, write the reports.

Output goes to ``<out_root>/<study>/`` atomically: everything is written into a marked hidden
work folder ``<out_root>/.<study>.<token>`` that replaces the old report folder only when the
whole study succeeded, so a failed or interrupted run never leaves a half-written report. Every
check of the study, its paths and its data runs before anything is written; an existing
``<out_root>/<study>`` is replaced only if bayesfric created it for this study. A run stopped
by SIGINT or SIGTERM removes its work folder on the way out; work folders of runs killed outright
(SIGKILL) are removed by the next run of the study (:mod:`bayesfric.fsutil`).

The work itself, the units of every law and the result tree, is :mod:`bayesfric.study.runner`;
this module runs it, then sizing, the claims and the report (:mod:`bayesfric.report.summary`), and
installs the folder. It sits above the report, which reads the study package.

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
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from bayesfric import fsutil, identifiability, sizing
from bayesfric.fingerprint import package_fingerprint
from bayesfric.report.summary import write_reports
from bayesfric.sizing import exceed
from bayesfric.sizing.forecast import study_misses
from bayesfric.study.claims import evaluate_claims
from bayesfric.study.config import Study, StudyError
from bayesfric.study.executor import open_client, timing_table, unit_seconds, write_timings
from bayesfric.study.plan import QuickRun, _plan_laws, _prepare
from bayesfric.study.runner import result_tree, run_laws
from bayesfric.study.tree import run_attrs

__all__ = ["run_study", "execute_study", "StudyRun", "current_report", "INPUTS_FILE"]


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


@dataclass(frozen=True)
class StudyRun:
    """What one run of a study leaves in memory (:func:`execute_study`): its report folder and,
    when the run wrote the report (not an unchanged rerun), the result tree it saved as
    ``results.nc`` and every law's full fit, so a caller never reads back what this process wrote."""

    folder: Path
    tree: xr.DataTree | None = None
    fits: Mapping[str, xr.DataTree] | None = None
    sized: sizing.SizingAnswer | None = None  # the sizing answer the report rendered (questions at points)


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
    for line in identifiability.describe(study.identifiability, identifiability.companions_of(study.laws)):
        print(f"[{study.name}] before fitting, the data do not identify {line}", flush=True)
    work = fsutil.create_work_folder(root, study.name)
    try:
        rows: list = []
        fits, scored = run_laws(study, work, plans, schemes, out_root=out_root, fresh=fresh, client=client,
                                 timings=rows, quick=quick, live_progress=live_progress)
        write_timings(rows, work / "timings.csv")
        if timings is not None:
            timings += rows
        tree = result_tree(study, ds, schemes, fits, scored, rows, QuickRun(settings, (study.kfold, kfold))
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
            forecast = [label for label, _, kind in schemes if kind == "forecast"]
            misses = study_misses({n: s.cv for n, (s, _) in scored.items()}, forecast, ds, column)
            tree["service"] = exceed.answer_study(service, held, tree, unit=ds[column].attrs.get("units", ""),
                                                  seed=seed, misses=misses)
        claims = evaluate_claims(study.claims, tree)
        tree.attrs.update(run_attrs(time.perf_counter() - start, unit_seconds(rows)))
        tree.attrs["rerun_options"] = "".join(  # the report's "Rerun:" line repeats how it was run
            [f" --out {out_root}" if out_root != Path("reports") else "", " --quick" if quick else ""])
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
    return StudyRun(final, tree, fits, sized)
