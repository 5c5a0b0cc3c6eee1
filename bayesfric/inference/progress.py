"""Progress inside a fit: warm-up and sampling per chain, divergences so far, time left.

The NUTS engine (:mod:`bayesfric.inference.engine`) runs each chain's warm-up and sampling as
consecutive calls of one compiled chunk of :data:`bayesfric.inference.chunked.CHUNK_STEPS`
steps (:mod:`bayesfric.inference.chunked`) and, after every chunk, tells the
:class:`SamplingProgress` of the run how far each chain got. Nothing is shown unless the caller
asked for it with :func:`reporting` (``bayesfric fit`` without ``--quiet``, every unit of a
study): the library stays quiet by default.

* **On a terminal** one line is rewritten in place (at most every :data:`LIVE_INTERVAL_S`), or,
  inside a study whose own tqdm bar is on screen, the bar's postfix shows it.
* **Otherwise** (a log, CI, a pipe) plain lines, at most one every :data:`PLAIN_INTERVAL_S`
  seconds (``BAYESFRIC_PROGRESS_S`` overrides it), the first after that long, and a last one
  when a run that printed any ends: a fit shorter than the interval adds nothing to a log (a
  study has many short units), a long one says where it stands every interval.

A line reads, for a fit with four chains::

    [stribeck fit] chain 1 draws 420/1000 · chain 2 draws 388/1000 · chain 3 warm-up 480/500 · chain 4
    draws 401/1000 · 0 divergent · 14 s elapsed, ~21 s left

(one line in reality). Refits of several folds say ``fold 3/10`` and how many folds are done.
The time left divides the chains' remaining active steps (a warm start's idle warm-up rows are
free and not counted) by the steps per second measured since the first report; warm-up steps
early in a fit build longer trees than sampling steps, so the first estimates err long.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TextIO

import numpy as np

__all__ = ["reporting", "SamplingProgress", "current", "PLAIN_INTERVAL_S", "LIVE_INTERVAL_S"]

#: Least seconds between two plain progress lines (warm-up done and the end always print).
PLAIN_INTERVAL_S = 10.0
#: Least seconds between two redraws of the live line on a terminal.
LIVE_INTERVAL_S = 0.25


@dataclass
class _Target:
    """Where and how the runs inside a :func:`reporting` block report."""

    label: str
    stream: TextIO
    live: bool
    interval: float
    sink: Callable[[str], None] | None  # live text goes here instead (a study's tqdm postfix)


_LOCAL = threading.local()


def current() -> _Target | None:
    """The reporting target set by the innermost :func:`reporting` of this thread, or None."""
    return getattr(_LOCAL, "target", None)


@contextlib.contextmanager
def reporting(label: str, stream: TextIO | None = None, live: bool | None = None,
              interval: float | None = None, sink: Callable[[str], None] | None = None) -> Iterator[None]:
    """Show the progress of every NUTS run started in this block (in this thread).

    ``label`` names the fit (``"stribeck fit"``); ``stream`` defaults to stderr; ``live``
    defaults to whether the stream is a terminal; ``interval`` is the least seconds between
    plain lines (default :data:`PLAIN_INTERVAL_S` or ``BAYESFRIC_PROGRESS_S``); ``sink``, if
    given, receives the live text instead of the stream (a study's progress bar).
    """
    stream = stream or sys.stderr
    if live is None:
        live = bool(getattr(stream, "isatty", lambda: False)())
    if interval is None:
        interval = float(os.environ.get("BAYESFRIC_PROGRESS_S", PLAIN_INTERVAL_S))
    before = current()
    _LOCAL.target = _Target(label, stream, live, float(interval), sink)
    try:
        yield
    finally:
        _LOCAL.target = before


class SamplingProgress:
    """Per-chain progress of one engine run (thread-safe: chain groups report from their threads).

    Parameters
    ----------
    target : _Target or None
        From :func:`current`; None makes every method a no-op.
    folds, chains : int
        The run's folds and chains per fold.
    idle, tune, draws : int
        Schedule rows per chain: ``idle`` inactive warm-up rows (a warm or short cold start),
        then ``tune`` active warm-up rows, then ``draws`` sampling rows.
    unit : str
        What a chain is called (``"chain"``; emcee's one ``"ensemble of 32 walkers"``, named
        without a number when there is one).
    divergences : bool
        Whether the sampler has divergent transitions to count (NUTS yes, emcee no).
    """

    def __init__(self, target: _Target | None, folds: int, chains: int, idle: int, tune: int, draws: int,
                 unit: str = "chain", divergences: bool = True):
        self.target = target
        self.unit, self.divergences = unit, divergences
        self.folds, self.chains = folds, chains
        self.idle, self.tune, self.draws = idle, tune, draws
        self.rows = np.zeros((folds, chains), dtype=int)  # schedule rows done per chain
        self.divergent = np.zeros((folds, chains), dtype=int)  # in the sampling rows so far
        self.lock = threading.Lock()
        self.start = time.perf_counter()
        self.first: tuple[float, int] | None = None  # (time, active steps) at the first report
        # plain lines: the first after one interval; a terminal's line at once
        self.shown = -np.inf if target is None or target.live else self.start
        self.printed = False
        self.width = 0

    def _active(self) -> np.ndarray:
        return np.clip(self.rows - self.idle, 0, self.tune + self.draws)

    def update(self, folds: range | list[int], chains: range, rows: int, divergent: np.ndarray) -> None:
        """Chains ``chains`` of folds ``folds`` have done ``rows`` schedule rows; ``divergent``
        ``(len(folds), len(chains))`` holds the divergent transitions of their latest sampling rows."""
        if self.target is None:
            return
        with self.lock:
            for i, fold in enumerate(folds):
                if fold < self.folds:  # padding folds of the last batch are not shown
                    self.rows[fold, chains.start:chains.stop] = rows
                    self.divergent[fold, chains.start:chains.stop] += np.asarray(divergent[i], dtype=int)
            now = time.perf_counter()
            done = int(self._active().sum())
            if self.first is None:
                self.first = (now, done)
            finished = bool((self.rows >= self.idle + self.tune + self.draws).all())
            gap = LIVE_INTERVAL_S if self.target.live else self.target.interval
            if (finished and self.printed) or now - self.shown >= gap:
                self.shown, self.printed = now, True
                self._show(self.line(now, done), final=finished)

    def line(self, now: float, done: int) -> str:
        """The progress text at time ``now`` with ``done`` active steps behind."""
        active = self._active()
        total = self.folds * self.chains * (self.tune + self.draws)
        parts = [f"[{self.target.label}]"]
        folds_done = int((active >= self.tune + self.draws).all(axis=1).sum())
        whole = self.tune + self.draws
        running = [f for f in range(self.folds) if 0 < active[f].max() and not (active[f] >= whole).all()]
        if self.folds > 1:
            parts.append(f"folds done {folds_done}/{self.folds}")
        chains = []
        for f in running[:2] if self.folds > 1 else range(self.folds):
            for c in range(self.chains):
                where = f"{self.unit} {c + 1}" if self.chains > 1 or self.unit == "chain" else self.unit
                where = f"fold {f + 1} {where}" if self.folds > 1 else where
                a = active[f, c]
                state = f"warm-up {a}/{self.tune}" if a < self.tune else f"draws {a - self.tune}/{self.draws}"
                chains.append(f"{where} {state}")
        text = " ".join(parts) + (" " + " · ".join(chains) if chains else "")
        if self.divergences:
            text += f" · {int(self.divergent.sum())} divergent"
        text += f" · {now - self.start:.0f} s elapsed"
        if done >= total:
            return text + ", done"
        if self.first is not None and now > self.first[0] and done > self.first[1]:
            rate = (done - self.first[1]) / (now - self.first[0])
            text += f", ~{(total - done) / rate:.0f} s left"
        return text

    def _show(self, text: str, final: bool) -> None:
        target = self.target
        if target.sink is not None:
            target.sink(text)
            return
        if target.live:
            pad = max(0, self.width - len(text))
            self.width = len(text)
            target.stream.write("\r" + text + " " * pad + ("\n" if final else ""))
        else:
            target.stream.write(text + "\n")
        target.stream.flush()
