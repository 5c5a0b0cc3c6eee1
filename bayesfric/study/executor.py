"""Run a study's units serially or on Dask distributed, reusing the run store; progress and timings.

:func:`run_units` walks every law's units (:mod:`bayesfric.study.units`): a unit whose key is in
the store is read back; the others are computed here (serial) or on the workers of a Dask
``Client`` (``--workers N`` starts a ``LocalCluster`` of N single-threaded processes;
``--scheduler ADDRESS`` connects to a running cluster, see :func:`open_client`). A law's fit runs
first; when it is done (or read back) its other units are scheduled, all independent of each
other, and the laws are independent of each other. Results (the fit, or the unit's
``xarray.Dataset``) travel back to this process as objects (pickled by Dask
from a worker, handed over as they are in this process) and are written to the store here, one
atomic file per unit as soon as it is done, so a worker that dies, or a run that is killed, loses
only the units in flight, and the workers need no file system shared with the client. Serial
and parallel runs compute the same units from the same inputs and seeds, hence the same numbers.

Progress: a tqdm bar (units done / total, the law and stage last finished, elapsed and estimated
time left) on a terminal; plain lines when stdout is not one (CI logs). Inside a unit run in this
process the NUTS chains report too (:mod:`bayesfric.inference.progress`: warm-up and draws per
chain, divergences, time left), in the bar's postfix or as plain lines; units on Dask workers
report only when they end. The time left is the sum over the units still to run of their
law's fit cost times their stage's cost per fit-second (:class:`CostModel`), both measured on the
units done (a reused unit counts with the seconds it took when computed), not the mean unit.
Every unit leaves a :class:`Timing` row (computed, reused or skipped, its seconds in this run, and
what it cost when computed); :func:`timing_table` prints the per-stage summary and
:func:`write_timings` the rows as CSV.
"""

from __future__ import annotations

import contextlib
import logging
import math
import sys
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import astuple, dataclass, fields
from pathlib import Path

import numpy as np
from tqdm import tqdm

from bayesfric.compare import verdict_of
from bayesfric.csvout import write_csv
from bayesfric.errors import UserError
from bayesfric.inference.progress import reporting
from bayesfric.study.store import Result, RunStore
from bayesfric.study.units import COSTLY, Engines, LawJob, Unit, compute, compute_seconds

#: Seconds to wait for ``--scheduler ADDRESS`` to answer.
CONNECT_TIMEOUT_S = 20

__all__ = ["Timing", "run_units", "open_client", "timing_table", "write_timings", "Progress", "UnitSeconds",
           "unit_seconds"]


@dataclass(frozen=True)
class Timing:
    """One unit of a run: ``status`` is computed, reused (read from the store) or skipped."""

    study: str
    law: str
    stage: str
    label: str
    status: str
    seconds: float  # wall seconds spent in this run (0 for reused and skipped units)
    stored_seconds: float  # what the unit cost when it was computed (NaN: skipped, or stored by an older run)


@dataclass(frozen=True)
class UnitSeconds:
    """Seconds the units computed in this run took, and what the reused ones cost when computed
    (``unknown``: reused units stored without their seconds)."""

    computed: float
    reused: int
    saved: float
    unknown: int


def unit_seconds(rows: list[Timing]) -> UnitSeconds:
    """The :class:`UnitSeconds` of a run's timing rows (the report's footer: a resumed run's wall
    time alone hides the real cost)."""
    reused = [r.stored_seconds for r in rows if r.status == "reused"]
    return UnitSeconds(computed=float(sum(r.seconds for r in rows if r.status == "computed")), reused=len(reused),
                       saved=float(sum(s for s in reused if math.isfinite(s))),
                       unknown=sum(not math.isfinite(s) for s in reused))


class CostModel:
    """Expected compute seconds of a unit from the units done: its law's fit seconds times its
    stage's seconds per fit-second (median over the laws done), so a stateful law whose fit took
    ten minutes is expected to take about as many times longer for its refits as for a static law.

    Before any fit is done nothing is known (:meth:`left` returns None); a law whose fit is not
    done yet is expected to cost the median fit; a stage not seen yet, the median ratio of all
    stages seen (1 before any).
    """

    def __init__(self, units: list[Unit]):
        self.pending = {u.key: u for u in units}
        self.fit_s: dict[str, float] = {}  # law -> seconds of its fit (computed now or before)
        self.ratios: dict[str, list[float]] = {}  # stage -> unit seconds / its law's fit seconds
        self.waiting: list[tuple[Unit, float]] = []  # units done before their law's fit cost was known

    def done(self, unit: Unit, cost: float) -> None:
        """``unit`` finished (computed, reused or skipped) and cost ``cost`` seconds (NaN: unknown)."""
        self.pending.pop(unit.key, None)
        if not np.isfinite(cost):
            return
        if unit.stage == "fit":
            self.fit_s[unit.law] = cost
            for other, seconds in [w for w in self.waiting if w[0].law == unit.law]:
                self._ratio(other, seconds)
            self.waiting = [w for w in self.waiting if w[0].law != unit.law]
        elif unit.law in self.fit_s:
            self._ratio(unit, cost)
        else:
            self.waiting.append((unit, cost))

    def _ratio(self, unit: Unit, seconds: float) -> None:
        if self.fit_s[unit.law] > 0:
            self.ratios.setdefault(unit.stage, []).append(seconds / self.fit_s[unit.law])

    def expected(self, unit: Unit) -> float:
        """Seconds ``unit`` is expected to take."""
        fit = self.fit_s.get(unit.law, float(np.median(list(self.fit_s.values()))))
        if unit.stage == "fit":
            return fit
        seen = self.ratios.get(unit.stage)
        if seen:
            return fit * float(np.median(seen))
        every = [r for rs in self.ratios.values() for r in rs]
        return fit * (float(np.median(every)) if every else 1.0)

    def left(self) -> float | None:
        """Seconds of the units not done yet, or None while no fit cost is known."""
        if not self.fit_s:
            return None
        return float(sum(self.expected(u) for u in self.pending.values()))


class Progress:
    """Units done / total with the law and stage, elapsed and remaining time (tqdm, or plain lines).

    With ``units`` (every unit of the run) the time left comes from the :class:`CostModel`;
    without, from the mean unit so far.
    """

    def __init__(self, total: int, name: str, stream=None, live: bool | None = None,
                 units: list[Unit] | None = None):
        self.stream = stream or sys.stdout
        self.name, self.total, self.done = name, total, 0
        self.start = time.perf_counter()
        self.costs = CostModel(units) if units is not None else None
        self.live = bool(getattr(self.stream, "isatty", lambda: False)()) if live is None else live
        self.bar = (tqdm(total=total, desc=name, unit="unit", file=self.stream, dynamic_ncols=True)
                    if self.live else None)

    def step(self, unit: Unit, status: str, seconds: float, cost: float = float("nan")) -> None:
        """Count one unit as finished; ``cost`` is what it took when computed (a reused unit's saving)."""
        self.done += 1
        if status == "computed":
            cost = seconds
        what = f"{unit.law} {unit.label}: {status}" + (f" in {seconds:.1f} s" if status == "computed" else "")
        if status == "reused" and np.isfinite(cost):
            what += f" (saved {cost:.1f} s)"
        if self.costs is not None:
            self.costs.done(unit, cost)
        left = self.costs.left() if self.costs is not None else None
        if self.bar is not None:  # tqdm's own estimate counts units; the description has the costed one
            if left is not None:
                self.bar.set_description_str(f"{self.name} (~{left:.0f} s left)", refresh=False)
            self.bar.set_postfix_str(what, refresh=False)
            self.bar.update(1)
            return
        elapsed = time.perf_counter() - self.start
        if left is None:
            left = elapsed / self.done * (self.total - self.done)  # rough: units differ in cost
        print(f"[{self.name}] {self.done}/{self.total} {what} (elapsed {elapsed:.0f} s, ~{left:.0f} s left)",
              file=self.stream, flush=True)

    def inside(self, unit: Unit):
        """The reporting context of the chains inside ``unit`` (:func:`bayesfric.inference.progress.reporting`):
        the bar's postfix on a terminal, plain lines on this progress's stream otherwise."""
        label = f"{self.name} {unit.law} {unit.label}"
        if self.bar is not None:
            bar = self.bar
            return reporting(label, stream=self.stream, live=True, sink=lambda text: bar.set_postfix_str(text))
        return reporting(label, stream=self.stream, live=False)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


@contextlib.contextmanager
def open_client(workers: int = 0, scheduler: str | None = None) -> Iterator[object | None]:
    """A Dask ``Client`` for ``--workers N`` or ``--scheduler ADDRESS``; None for a serial run.

    ``workers`` starts a ``LocalCluster`` of that many processes with one thread each (JAX
    already uses the cores of a process for one unit's linear algebra); it is closed on exit.
    ``scheduler`` connects to a running scheduler (``tcp://host:8786``), which is left running.
    """
    if not workers and not scheduler:
        yield None
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        option = "--scheduler" if scheduler else "--workers"
        raise UserError(f"{option}: needs Dask distributed, an optional extra: pip install 'bayesfric[dask]'") from None
    if scheduler:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise UserError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler ({exc})") from None
        with client:
            yield client
        return
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, \
            Client(cluster) as client:
        yield client


class _Serial:
    """In-process executor with the interface :func:`run_units` needs; a law's units run together.
    Each unit runs inside ``inside(unit)`` (its chains' progress) and gets a shallow copy of the
    fit (a unit's changes to the tree's structure or attributes do not reach the others); the
    law's units share its compiled engine (``engines``, this executor's own)."""

    def __init__(self, inside=None):
        self.queue: deque = deque()
        self.inside = inside or (lambda unit: contextlib.nullcontext())
        self.engines = Engines()

    def submit(self, job, unit, fit, first: bool) -> None:
        (self.queue.appendleft if first else self.queue.append)((job, unit, fit))

    def completed(self) -> Iterator[tuple[LawJob, Unit, Result, float]]:
        while self.queue:
            job, unit, fit = self.queue.popleft()
            with self.inside(unit):
                result, seconds = compute(job, unit, None if fit is None else fit.copy(), self.engines)
            yield job, unit, result, seconds


def compute_reporting(study: str, job: LawJob, unit: Unit, fit) -> tuple[Result, float]:
    """:func:`compute` on a Dask worker, its chains reporting in plain lines on the worker's stderr
    (a local cluster's workers share the terminal; a remote worker's lines go to its log), one
    every :data:`bayesfric.inference.progress.PLAIN_INTERVAL_S` seconds, none for a short unit.
    The law's compiled engine is kept by the worker (:func:`_worker_engines`) for its next unit."""
    with reporting(f"{study} {unit.law} {unit.label}", live=False):
        return compute(job, unit, fit, _worker_engines())


def _worker_engines() -> Engines:
    """The :class:`~bayesfric.study.units.Engines` of the Dask worker running this task: an
    attribute of the worker object, made on its first unit (outside a worker: a new one)."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):  # not inside a Dask task
        return Engines()
    if not isinstance(engines := getattr(worker, "bayesfric_engines", None), Engines):
        engines = Engines()
        worker.bayesfric_engines = engines
    return engines


class _Dask:
    """Units as Dask futures; the fit is scattered once and shared by the law's units."""

    def __init__(self, client, study: str = ""):
        from distributed import as_completed

        self.client, self.study = client, study
        self.pending = as_completed()
        self.meta: dict = {}
        self.shared: dict[int, object] = {}

    def submit(self, job, unit, fit, first: bool) -> None:
        if fit is not None:
            ident = id(fit)
            if ident not in self.shared:  # hash=False: no tokenising of every array of the fit
                self.shared[ident] = self.client.scatter(fit, hash=False)
            fit = self.shared[ident]
        future = self.client.submit(compute_reporting, self.study, job, unit, fit, pure=False,
                                    key=f"{unit.law}-{unit.stage}-{unit.key[:12]}")
        self.meta[future.key] = (job, unit)
        self.pending.add(future)

    def completed(self) -> Iterator[tuple[LawJob, Unit, Result, float]]:
        for future in self.pending:
            job, unit = self.meta.pop(future.key)
            result, seconds = future.result()  # a unit's error (or a lost worker, after retries) stops the run
            future.release()
            yield job, unit, result, seconds


def run_units(plans: list[tuple[LawJob, Unit, list[Unit]]], store: RunStore, *, study: str,
              failed_fits: str = "skip", client=None, stream=None, live: bool | None = None
              ) -> tuple[dict[str, Result], dict[str, list[Unit]], list[Timing]]:
    """Results of every unit of ``plans`` (law job, fit unit, units after the fit), reusing the store.

    Returns
    -------
    results : dict
        Unit key -> result: the fit (an ``xarray.DataTree``, fully in memory; its file is in the
        store, ``store.path(key, "nc")``) or the unit's ``xarray.Dataset``, computed in this run
        or read back from the store.
    skipped : dict
        Law -> units not run because its fit failed the gate (``failed_fits = "skip"``).
    timings : list of Timing
        One row per unit.
    """
    every = [u for _, fit, rest in plans for u in [fit, *rest]]
    progress = Progress(len(every), study, stream, live, units=every)
    executor = _Serial(progress.inside) if client is None else _Dask(client, study)
    results: dict[str, Result] = {}
    skipped: dict[str, list[Unit]] = {job.spec.name: [] for job, _, _ in plans}
    timings: list[Timing] = []
    follow = {fit.key: rest for _, fit, rest in plans}

    def finished(job: LawJob, unit: Unit, result: Result, status: str, seconds: float) -> None:
        results[unit.key] = result
        if status == "computed":
            cost = seconds
        elif unit.kind == "nc":  # a fit's seconds lie beside it in the store
            cost = store.seconds(unit.key, unit.kind)
        else:
            cost = compute_seconds(unit, result)
        timings.append(Timing(study, unit.law, unit.stage, unit.label, status, seconds, cost))
        progress.step(unit, status, seconds, cost)
        if unit.stage == "fit":
            _follow(job, unit, result)

    def _follow(job: LawJob, unit: Unit, fit) -> None:
        passed = verdict_of(fit).passed
        misses = []
        for nxt in follow[unit.key]:
            if not passed and failed_fits == "skip" and nxt.stage in COSTLY:
                skipped[job.spec.name].append(nxt)
                timings.append(Timing(study, nxt.law, nxt.stage, nxt.label, "skipped", 0.0, float("nan")))
                progress.step(nxt, "skipped (fit failed the gate)", 0.0)
            elif not reuse(job, nxt):
                misses.append(nxt)
        for nxt in reversed(misses):  # reversed: each goes to the front of the serial queue, so they run in order
            executor.submit(job, nxt, fit, first=True)

    def reuse(job: LawJob, unit: Unit) -> bool:
        hit = store.get(unit.key, unit.kind)
        if hit is not None:
            finished(job, unit, hit, "reused", 0.0)
        return hit is not None

    try:
        for job, fit, _ in plans:
            if not reuse(job, fit):
                executor.submit(job, fit, None, first=False)
        for job, unit, result, seconds in executor.completed():
            store.put(unit.key, unit.kind, result)
            if unit.kind == "nc":
                store.put_seconds(unit.key, unit.kind, seconds)
            finished(job, unit, result, "computed", seconds)
    finally:
        progress.close()
    return results, skipped, timings


def timing_table(rows: list[Timing], title: str = "time per stage") -> str:
    """Per-stage summary of ``rows``: units computed / reused / skipped and seconds computed."""
    stages: dict[str, list[float]] = {}
    for r in rows:
        entry = stages.setdefault(r.stage, [0, 0, 0, 0.0])
        entry[("computed", "reused", "skipped").index(r.status)] += 1
        entry[3] += r.seconds
    lines = [f"{title}:", f"  {'stage':<11}{'computed':>9}{'reused':>8}{'skipped':>8}{'seconds':>10}"]
    for stage, (done, reused, skip, secs) in stages.items():
        lines.append(f"  {stage:<11}{done:>9}{reused:>8}{skip:>8}{secs:>10.1f}")
    total = [sum(v[i] for v in stages.values()) for i in range(4)]
    lines.append(f"  {'total':<11}{total[0]:>9}{total[1]:>8}{total[2]:>8}{total[3]:>10.1f}")
    return "\n".join(lines)


def write_timings(rows: list[Timing], path: Path) -> Path:
    """Write ``rows`` as CSV (one row per unit) to ``path`` (labels neutralised: :mod:`bayesfric.csvout`)."""
    return write_csv(path, [[f"{v:.3f}" if isinstance(v, float) else v for v in astuple(r)] for r in rows],
                     header=[f.name for f in fields(Timing)])
