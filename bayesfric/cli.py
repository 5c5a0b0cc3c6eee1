"""Command-line interface: ``bayesfric laws | fit | data | study | report | size | predict | score | main``.

Every user error (bad data, unknown law, bad prior, bad study file, bad option — argparse's own
errors included) prints one line ``bayesfric: error: ...`` to stderr, exits with status 2 and
writes nothing. ``fit`` validates its sampler options against the study schema's ``[sampler]``
table (:data:`bayesfric.study.config.SAMPLER`), the memory they imply (:mod:`bayesfric.limits`, as
``--workers`` and ``--jobs``) and its ``--out`` path before sampling.

This module defines the options (:func:`build_parser`, one ``_add_<command>`` each) and turns
errors into exit statuses (:func:`main`); what each command does with its options is in
:mod:`bayesfric.commands`, which calls the library.

The light commands (``--version``, ``--help``, ``laws``, ``data list|check|reduce``) import
neither JAX nor numpyro: this module and :mod:`bayesfric.commands` import only the standard
library and base modules at start-up, JAX's process settings (:func:`bayesfric.runtime.configure`)
are applied only before a computing command, and ``laws`` reads the stored catalogue
(:mod:`bayesfric.lawcatalogue`). ``tests/test_cli_start.py`` checks the import list,
``benchmarks/bench_cli_start.py`` measures the time.

SIGINT and SIGTERM stop a command through :class:`bayesfric.fsutil.Interrupted` (set up by
:func:`run`): what the command was writing is removed on the way out (a study's work folder),
one line is printed and the exit status is 130 (SIGINT) or 143 (SIGTERM).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from typing import NoReturn

from bayesfric import commands, precheck
from bayesfric._version import __version__
from bayesfric.datasets.reduce_options import add_arguments as reduce_arguments
from bayesfric.errors import UserError

__all__ = ["main", "UserError", "UsageError", "build_parser"]


USER_ERRORS = (UserError,)  # every input error is one (bayesfric.errors): data, prior, unit, law, study ...


class UsageError(UserError):
    """A command-line usage error reported by argparse."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``bayesfric: error: [subcommand: ]message (see --help)``."""

    def error(self, message: str) -> NoReturn:
        sub = self.prog.removeprefix("bayesfric").strip()
        hint = f" (see `{self.prog} --help`)"
        raise UsageError(f"{sub}: {message}{hint}" if sub else f"{message}{hint}")


def _run_options(q: argparse.ArgumentParser) -> None:
    """Options of ``study`` and ``main``: the run store and the Dask executor."""
    q.add_argument("--fresh", action="store_true", help="recompute every unit instead of reusing the run store")
    q.add_argument("--workers", type=int, default=0, metavar="N",
                   help="run units on a local Dask cluster of N processes (default: serial)")
    q.add_argument("--scheduler", metavar="ADDRESS", help="run units on the Dask cluster at ADDRESS (tcp://host:8786)")


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command; each sets ``func``, the :mod:`bayesfric.commands` function that runs it."""
    p = _Parser(prog="bayesfric", description="Bayesian model comparison of friction laws.")
    p.add_argument("--version", action="version", version=f"bayesfric {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for add in (_add_laws, _add_fit, _add_data, _add_study, _add_report, _add_size, _add_predict, _add_score,
                _add_main):
        add(sub)
    return p


def _add_laws(sub) -> None:
    """``bayesfric laws``: the registry listed."""
    q = sub.add_parser("laws", help="list the registered friction laws with units, priors and sources")
    q.add_argument("--family", help="only this family")
    q.add_argument("--markdown", action="store_true", help="Markdown tables")
    q.add_argument("--names", action="store_true", help="names only")
    q.set_defaults(func=commands.cmd_laws, light=True)


def _add_fit(sub) -> None:
    """``bayesfric fit DATA LAW``: one law fitted."""
    q = sub.add_parser("fit", help="fit one law to a data file (CSV + TOML sidecar) or a built-in data set")
    q.add_argument("data", help="CSV file (sidecar FILE.toml next to it) or built-in data set name")
    q.add_argument("law", help="law name (see `bayesfric laws --names`)")
    q.add_argument("--sampler", choices=["nuts", "emcee"], default="nuts")
    q.add_argument("--out", help="write the fit (NetCDF DataTree) to this file (checked before sampling)")
    q.add_argument("--draws", type=int, default=None, help="draws per chain, ≥ 1 (emcee: steps before thinning)")
    q.add_argument("--tune", type=int, default=None, help="warm-up draws / burn-in steps, ≥ 0")
    q.add_argument("--chains", type=int, default=None, help="NUTS chains, ≥ 1")
    q.add_argument("--init", default=None, help="NUTS chain starts: median (default) | pathfinder")
    q.add_argument("--metric", default=None,
                   help="NUTS mass matrix: auto (default: dense where correlations are strong) | diag | dense")
    q.add_argument("--walkers", type=int, default=None, help="emcee walkers, ≥ 2 × free parameters")
    q.add_argument("--retry-target-accept", type=float, default=None,
                   help="NUTS: sample again at this target acceptance after divergences (default 0.99; 0: off)")
    q.add_argument("--seed", type=int, default=0, help="seed, 0 … 2**32 - 1")
    q.add_argument("--noise", choices=["normal", "student_t", "proportional", "ar1"], default="normal")
    q.add_argument("--group", help="group coordinate for partial-pooled offsets (series, run ...)")
    q.add_argument("--select", action="append", metavar="COORD=VALUE", help="use only these rows")
    q.add_argument("--prior", action="append", metavar="NAME=JSON", help="override a prior")
    q.add_argument("--fix", action="append", metavar="NAME=VALUE",
                   help="hold a parameter (or constant) at VALUE in SI units instead of sampling it, e.g. i=1.5")
    q.add_argument("--quiet", action="store_true", help="no progress bar")
    q.set_defaults(func=commands.cmd_fit, precheck=precheck.fit)


def _add_data(sub) -> None:
    """``bayesfric data list | check | reduce``."""
    q = sub.add_parser("data", help="list built-in data sets, check a user's file, or reduce a raw log")
    dsub = q.add_subparsers(dest="data_cmd", required=True, metavar="{list,check,reduce}")
    d = dsub.add_parser("list", help="built-in data sets with provenance")
    d.set_defaults(func=commands.cmd_data, light=True)
    d = dsub.add_parser("check", help="validate CSV + TOML metadata and print what was understood")
    d.add_argument("file", help="CSV file")
    d.add_argument("--meta", help="metadata TOML (default: FILE with .toml suffix)")
    d.set_defaults(func=commands.cmd_data, light=True)
    d = dsub.add_parser("reduce", help="steady-state reduction of a raw log: segment means with standard errors "
                                       "and counts (bayesfric.datasets.reduce)")
    reduce_arguments(d)
    d.set_defaults(func=commands.cmd_data, light=True)


def _add_study(sub) -> None:
    """``bayesfric study FILE``: one study run."""
    q = sub.add_parser("study", help="run a study TOML file and write reports/<study>/")
    q.add_argument("file", help="study TOML file")
    q.add_argument("--out", default="reports", help="reports root folder")
    q.add_argument("--quick", action="store_true", help="fewer draws and folds (smoke test, not for decisions)")
    _run_options(q)
    q.set_defaults(func=commands.cmd_study, precheck=precheck.study)


def _add_report(sub) -> None:
    """``bayesfric report RESULTS.nc --out FOLDER``: a study's report rendered again from its result tree."""
    q = sub.add_parser("report", help="render a study's report again from its results.nc alone (same bytes)")
    q.add_argument("results", help="a study's results.nc (reports/<study>/results.nc)")
    q.add_argument("--out", required=True, help="new report folder (must not exist, or be empty)")
    q.set_defaults(func=commands.cmd_report)


def _add_size(sub) -> None:
    """``bayesfric size STUDY|FIT``: actuator sizing."""
    q = sub.add_parser("size", help="actuator sizing: predictive friction at untested operating points, "
                                     "from a study's stored fits or one fit")
    q.add_argument("target", help="study TOML file (its report must exist) or fit file (.nc)")
    q.add_argument("--at", help='operating point, e.g. "bending_moment=8 MN*m, velocity=1.04 rpm" '
                                '(a range: "velocity=0.5..6 rad/s"); required with a fit')
    q.add_argument("--confidence", type=float, default=None, help="size for this quantile of |T|, in (0, 1) "
                                                                    "(default 0.99; with --at)")
    q.add_argument("--capacity", help='available drive torque or force, e.g. "40 kN*m" (with --at)')
    q.add_argument("--energy-rotation", help='friction energy of one rotation through this angle, e.g. "90 deg" '
                                             "(with --at; torque)")
    q.add_argument("--horizon", help='time to exceed --capacity, forecast up to this service time, e.g. "20000 h" '
                                     "(a fit of a law with a trend; one point)")
    q.add_argument("--reports", default="reports", help="reports root folder of the study (default reports)")
    q.set_defaults(func=commands.cmd_size, precheck=precheck.size)


def _predict_options(q: argparse.ArgumentParser) -> None:
    """Options of ``predict`` and ``score``: what predicts, the new log, which group."""
    q.add_argument("target", help="a study's report folder or its results.nc, or a fit file (.nc)")
    q.add_argument("log", help="the new log: CSV file (sidecar FILE.toml next to it) or built-in data set name")
    q.add_argument("--group", help="answer for this group of the fits (default: a new group, e.g. a new run)")
    q.add_argument("--seed", type=int, default=0, help="seed of a new group's offsets")


def _add_predict(sub) -> None:
    """``bayesfric predict TARGET LOG --out FILE``: predictions at every row of a new log."""
    q = sub.add_parser("predict", help="predict every row of a new log from a study's fits (and their "
                                        "model average) or one fit, without refitting")
    _predict_options(q)
    q.add_argument("--out", required=True, help="CSV file of the predictions (one row per law and log row, SI)")
    q.add_argument("--quantiles", type=float, nargs="+", default=None, metavar="Q",
                   help="quantile levels in (0, 1) of the mean curve and of the predictive with noise "
                        "(default 0.05 0.5 0.95)")
    q.set_defaults(func=commands.cmd_predict, precheck=precheck.predict)


def _add_score(sub) -> None:
    """``bayesfric score TARGET LOG``: the laws scored on a new log."""
    q = sub.add_parser("score", help="score a study's laws (and their model average) or one fit on a new log: "
                                      "elpd, RMS error, coverage of the 50 %% and 90 %% bands")
    _predict_options(q)
    q.add_argument("--out", help="also write the scores as a tidy CSV file (law, metric, value)")
    q.set_defaults(func=commands.cmd_score, precheck=precheck.score)


def _add_main(sub) -> None:
    """``bayesfric main``: every seed study."""
    q = sub.add_parser("main", help="the main job: run every study in studies/ and write reports/")
    q.add_argument("--out", default="reports", help="reports root folder")
    q.add_argument("--quick", action="store_true", help="fewer draws and folds (smoke test)")
    q.add_argument("--studies", metavar="FOLDER", help="run the study files in FOLDER (default: the seed studies)")
    q.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="studies run at once, one process each (default: one per CPU core; 1: one after the other)")
    _run_options(q)
    q.set_defaults(func=commands.cmd_main, precheck=precheck.main)


#: Exit status of a command stopped by a signal: 128 + the signal's number, as a shell reports it.
INTERRUPTED = {signal.SIGINT: 130, signal.SIGTERM: 143}


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bayesfric`` command; returns the exit status (2 on a user error,
    130/143 when stopped by SIGINT/SIGTERM).

    A command marked ``light`` (the listings and data commands) runs without JAX; every other
    command first applies JAX's process settings (:func:`bayesfric.runtime.configure`: x64 and
    the persistent compilation cache), after its options parsed.
    """
    try:
        args = build_parser().parse_args(argv)
        if (check := getattr(args, "precheck", None)) is not None:
            check(args)  # the command's arguments, before JAX loads (bayesfric.precheck)
        if not getattr(args, "light", False):
            from bayesfric.runtime import configure

            configure()
        args.func(args)
    except USER_ERRORS as exc:
        msg = exc.args[0] if exc.args else str(exc)
        print(f"bayesfric: error: {' '.join(str(msg).splitlines())}", file=sys.stderr)  # always one line
        return 2
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
        print(f"bayesfric: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return INTERRUPTED.get(signum, 130)
    return 0


def run() -> NoReturn:
    """The ``bayesfric`` console command: :func:`main`, then exit without the interpreter's teardown.

    Everything a command writes is complete when :func:`main` returns (results are written
    atomically, synchronously); what is left is tearing down the interpreter: collecting the
    objects of JAX, XLA, xarray and matplotlib one by one: a warm ``bayesfric fit robot_joint
    stribeck`` took 4.05 s with it and 3.48 s without (three pairs, 2026-11-24). So this waits
    for compilations still running in the background (their results belong in the persistent
    cache), flushes the standard streams, and leaves with :func:`os._exit`. Code that calls
    :func:`main` in-process (tests, notebooks) keeps the normal exit, and its own signal handlers:
    only here do SIGINT and SIGTERM become :class:`bayesfric.fsutil.Interrupted`
    (:func:`bayesfric.fsutil.handle_stop_signals`). A stopped command does not wait for
    background compilations; a light one never started any.
    """
    from bayesfric.fsutil import handle_stop_signals

    handle_stop_signals()
    code = main()
    exported = sys.modules.get("bayesfric.exported")  # loaded only by a computing command
    if exported is not None and code not in INTERRUPTED.values():
        exported.finish_compilations()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    run()
