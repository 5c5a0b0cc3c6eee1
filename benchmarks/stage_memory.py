"""Resident memory per stage of a study, for ``bench_scale_study.py --trace`` (issue 30, item 3).

A thread samples the process's resident set size every :data:`INTERVAL_S` seconds and charges
it to the innermost stage running: the functions of :data:`STAGES` are wrapped (module attribute
replaced) so that each call pushes its label. :func:`report` gives, per label, the calls, the
seconds, the resident memory on entry (first call) and on exit (last call), the highest sampled
inside it, and ``raised_gb``: how far the process's high-water mark (``ru_maxrss``, which no
sampling misses) rose while it was the innermost stage running (its own share).
"""

from __future__ import annotations

import functools
import importlib
import resource
import threading
import time

import psutil

#: Seconds between two samples of the resident memory.
INTERVAL_S = 0.1
#: (module, attribute) of the functions traced; a unit's label adds its stage and law.
STAGES = [
    ("bayesfric.study.executor", "compute"),
    ("bayesfric.study.store", "fit_to_bytes"),
    ("bayesfric.study.units", "rebuild"),
    ("bayesfric.study.store", "load_fit_bytes"),
    ("bayesfric.study.store", "load_unit_bytes"),
    ("bayesfric.study.runner", "_weights"),
    ("bayesfric.study.runner", "_law_results"),
    ("bayesfric.study.tree", "score_table"),
    ("bayesfric.study.runner", "study_tree"),
    ("bayesfric.pipeline.runner", "evaluate_claims"),
    ("bayesfric.compare", "loo_pit_check"),
    ("bayesfric.compare", "prior_sensitivity"),
    ("bayesfric.compare", "prior_predictive_check"),
    ("bayesfric.compare", "psis_loo"),
    ("bayesfric.compare", "ranking_sensitivity"),
    ("bayesfric.report.summary", "write_reports"),
    ("bayesfric.report.summary", "draw"),
    ("bayesfric.report.summary", "build"),
    ("bayesfric.report.summary", "render"),
    ("bayesfric.report.summary", "result_tree"),
    ("bayesfric.report.summary", "write_results"),
]

_stack: list[str] = []
_seen: dict[str, dict] = {}


def _label(name: str, args: tuple) -> str:
    unit = args[1] if name == "compute" and len(args) > 1 else None
    return f"{name} {unit.stage} {unit.law}" if unit is not None else name


def _wrap(name: str, fn):
    @functools.wraps(fn)
    def traced(*args, **kwargs):
        label = _label(name, args)
        rss = psutil.Process().memory_info().rss
        row = _seen.setdefault(label, {"calls": 0, "seconds": 0.0, "enter_gb": rss / 1e9, "peak_gb": 0.0,
                                       "raised_gb": 0.0})
        row["calls"] += 1
        _mark()
        _stack.append(label)
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            row["seconds"] += time.perf_counter() - start
            row["exit_gb"] = psutil.Process().memory_info().rss / 1e9
            _mark()
            _stack.pop()
    return traced


_high = [0]
_outside: dict[str, float] = {"raised_gb": 0.0}


def _mark() -> None:
    """Charge the rise of the high-water mark since the last mark to the innermost stage running."""
    high = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # kB on Linux
    row = _seen[_stack[-1]] if _stack else _outside
    row["raised_gb"] += (high - _high[0]) / 1e9
    _high[0] = high


def _sample(stop: threading.Event) -> None:
    proc = psutil.Process()
    while not stop.wait(INTERVAL_S):
        rss = proc.memory_info().rss / 1e9
        for label in list(_stack):  # every enclosing stage saw this memory
            row = _seen.get(label)
            if row is not None:
                row["peak_gb"] = max(row["peak_gb"], rss)


def start() -> threading.Event:
    """Wrap :data:`STAGES` and start sampling; set the returned event to stop."""
    for module, attr in STAGES:
        mod = importlib.import_module(module)
        setattr(mod, attr, _wrap(attr, getattr(mod, attr)))
    stop = threading.Event()
    threading.Thread(target=_sample, args=(stop,), daemon=True).start()
    return stop


def report() -> list[dict]:
    """One row per label, in order of first call."""
    _mark()
    rows = [{"stage": k} | row for k, row in _seen.items()] + [{"stage": "(no stage)"} | _outside]
    return [{n: round(v, 3) if isinstance(v, float) else v for n, v in row.items()} for row in rows]
