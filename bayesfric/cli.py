"""Command-line interface: ``bayesfric laws | fit | data | study | size | main``.

Every user error (bad data, unknown law, bad prior, bad study file, bad option — argparse's own
errors included) prints one line ``bayesfric: error: ...`` to stderr, exits with status 2 and
writes nothing. ``fit`` validates its sampler options against the study schema's ``[sampler]``
table (:data:`bayesfric.study.config.SAMPLER`), the memory they imply (:mod:`bayesfric.limits`, as
``--workers`` and ``--jobs``) and its ``--out`` path before sampling.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import NoReturn

from bayesfric.datasets.loader import DataError
from bayesfric.datasets.reduce import add_arguments as reduce_arguments
from bayesfric.errors import UserError
from bayesfric.laws.base import LawDeclarationError
from bayesfric.priors import Prior, PriorError
from bayesfric.quantities import UnitError

__all__ = ["main", "UserError", "UsageError", "build_parser"]


USER_ERRORS = (DataError, PriorError, UnitError, UserError, LawDeclarationError)


def _cmd_laws(args: argparse.Namespace) -> None:
    from bayesfric.laws import all_laws
    from bayesfric.laws.variants import translation_problem
    from bayesfric.report.tables import format_table, law_rows

    laws = [w for w in all_laws() if args.family in (None, w.family)]
    if not laws:
        raise UserError(f"no laws in family {args.family!r}")
    if args.names:
        for w in laws:
            print(w.name)
        return
    header = ["law", "inputs", "parameter", "unit", "prior", "source"]
    for family in sorted({w.family for w in laws}):
        print(f"\n== family {family} ==")
        rows = []
        for w in (w for w in laws if w.family == family):
            rows += law_rows(w)
        print(format_table(header, rows, markdown=args.markdown))
        for w in (w for w in laws if w.family == family):
            problem = translation_problem(w)
            motion = "also force data (translational)" if problem is None else f"rotary only: {problem}"
            print(f"  {w.name}: {w.summary}  [{w.source}; response {w.response}; {motion}]")


class UsageError(UserError):
    """A command-line usage error reported by argparse."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``bayesfric: error: [subcommand: ]message (see --help)``."""

    def error(self, message: str) -> NoReturn:
        sub = self.prog.removeprefix("bayesfric").strip()
        hint = f" (see `{self.prog} --help`)"
        raise UsageError(f"{sub}: {message}{hint}" if sub else f"{message}{hint}")


def _parse_priors(items: list[str] | None, known: list[str], law: str) -> dict[str, Prior]:
    """``--prior NAME=JSON`` options: NAME a parameter of the law or noise model, JSON an object."""
    out = {}
    for item in items or []:
        if "=" not in item:
            example = 'T_C=\'{"dist": "HalfNormal", "scale": 2}\''
            raise UserError(f"--prior {item!r}: expected NAME=JSON, e.g. {example}")
        name, spec = item.split("=", 1)
        if name not in known:
            raise UserError(f"--prior {name}: law {law!r} has no parameter {name!r} (parameters: {', '.join(known)})")
        try:
            out[name] = Prior.from_dict(json.loads(spec))
        except json.JSONDecodeError as exc:
            raise UserError(f"--prior {name}: invalid JSON ({exc.msg})") from None
        except PriorError as exc:
            raise UserError(f"--prior {name}: {exc}") from None
    return out


def _parse_fix(items: list[str] | None, law):
    """``--fix NAME=VALUE`` options: the law with each named parameter (or constant) held at VALUE (SI)."""
    from bayesfric.laws.variants import VariantError, vary

    fixed: dict[str, float] = {}
    for item in items or []:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise UserError(f"--fix {item!r}: expected NAME=VALUE, e.g. --fix i=1.5")
        try:
            value = float(text)
        except ValueError:
            raise UserError(f"--fix {name}: {text!r} is not a number") from None
        try:
            vary(law, fixed={name: value})  # each option checked alone, so the error names it
        except VariantError as exc:
            raise UserError(f"--fix {name}: {exc.problem}") from None
        fixed[name] = value
    return vary(law, fixed=fixed)


def _parse_select(items: list[str] | None) -> dict[str, object]:
    """``--select COORD=VALUE`` options; VALUE is read as an integer, a number or else a string."""
    out: dict[str, object] = {}
    for item in items or []:
        if "=" not in item:
            raise UserError(f"--select {item!r}: expected COORD=VALUE")
        key, value = item.split("=", 1)
        for convert in (int, float, str):
            try:
                out[key] = convert(value)
                break
            except ValueError:
                continue
    return out


def _option(key: str) -> str:
    """The option of ``fit`` that sets the sampler setting ``key``."""
    return "--sampler" if key == "name" else f"--{key.replace('_', '-')}"


def _fit_settings(args: argparse.Namespace) -> dict[str, object]:
    """Sampler options of ``fit``, validated against the study schema's ``[sampler]`` table."""
    from bayesfric.api.fitting import sampler_options

    return sampler_options(args.sampler, args.seed, {"draws": args.draws, "tune": args.tune, "chains": args.chains,
                                                     "walkers": args.walkers, "init": args.init, "metric": args.metric,
                                                     "retry_target_accept": args.retry_target_accept}, key=_option)


def _load_selected(data: str, items: list[str] | None):
    from bayesfric.datasets import load_dataset, resolve, select

    ds = load_dataset(resolve(data))
    try:
        return select(ds, _parse_select(items))
    except DataError as exc:
        raise UserError(f"--select {' '.join(items or [])}: {exc}") from None


def _checked_program(law, ds, priors: dict[str, Prior], noise, sampler: str, settings: dict[str, object]):
    """The fit's program, its priors, walkers and memory checked before sampling
    (:func:`bayesfric.api.fitting.checked_program`, errors naming the options)."""
    from bayesfric.api.fitting import checked_program

    return checked_program(law, ds, priors, noise, sampler, settings, key=_option, prior_key="--prior {}".format)


def _cmd_fit(args: argparse.Namespace) -> None:
    from bayesfric.fsutil import PathError, check_output_file
    from bayesfric.inference import fit, save_fit
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import for_data
    from bayesfric.model import Noise

    settings = _fit_settings(args)
    if args.out is not None:
        try:
            check_output_file(args.out)
        except PathError as exc:
            raise UserError(f"--out {exc}") from None
    try:
        law = get_law(args.law)
    except KeyError as exc:
        raise UserError(exc.args[0]) from None
    law = _parse_fix(args.fix, law)
    ds = _load_selected(args.data, args.select)
    law = for_data(law, ds)  # its motion kind and units as they run on this data
    noise = Noise(kind=args.noise, group=args.group)
    if args.group is not None and args.group not in ds.coords:
        raise UserError(f"--group {args.group}: not a coordinate of the data ({', '.join(ds.coords)})")
    priors = _parse_priors(args.prior, list(law.params) + list(noise.sites()), law.name)
    _checked_program(law, ds, priors, noise, args.sampler, settings)  # checked before sampling
    dt = fit(law, ds, sampler=args.sampler, priors=priors, noise=noise, seed=args.seed, progress=not args.quiet,
             **settings)
    from bayesfric.report.tables import fit_report  # after the fit: it imports arviz-stats (see diagnostics)

    print(fit_report(dt, law))
    if args.out:
        print(f"fit written to {save_fit(dt, args.out)}")


def _cmd_data(args: argparse.Namespace) -> None:
    from bayesfric.datasets import builtin_names, describe, load_builtin, load_dataset

    if args.data_cmd == "reduce":
        from bayesfric.datasets.reduce import run_command

        run_command(args)
    elif args.data_cmd == "list":
        from bayesfric.report.tables import format_table

        rows = []
        for name in builtin_names():
            ds = load_builtin(name)
            rows.append([name, ds.attrs["provenance"], str(ds.sizes["obs"]), ds.attrs.get("response", ""),
                         ds.attrs.get("source", "")[:90]])
        print(format_table(["data set", "provenance", "rows", "response", "source"], rows))
    else:
        ds = load_dataset(args.file, args.meta)
        print(describe(ds))
        print("OK: the file is valid")


def _check_reports_root(out: str) -> None:
    from bayesfric.fsutil import PathError, check_output_folder

    try:
        check_output_folder(out)
    except PathError as exc:
        raise UserError(f"--out {exc}") from None


def _run_options(q: argparse.ArgumentParser) -> None:
    """Options of ``study`` and ``main``: the run store and the Dask executor."""
    q.add_argument("--fresh", action="store_true", help="recompute every unit instead of reusing the run store")
    q.add_argument("--workers", type=int, default=0, metavar="N",
                   help="run units on a local Dask cluster of N processes (default: serial)")
    q.add_argument("--scheduler", metavar="ADDRESS", help="run units on the Dask cluster at ADDRESS (tcp://host:8786)")


def _executor(args: argparse.Namespace) -> dict:
    from bayesfric.limits import process_problem

    if args.workers < 0:
        raise UserError(f"--workers: must be 0 (serial) or a number of processes ≥ 1, got {args.workers}")
    if problem := process_problem(args.workers, "worker processes"):
        raise UserError(f"--workers: {problem}")
    if args.workers and args.scheduler:
        raise UserError("--workers and --scheduler: give one (a local cluster, or an existing one)")
    return dict(fresh=args.fresh, workers=args.workers, scheduler=args.scheduler)


def _cmd_study(args: argparse.Namespace) -> None:
    from bayesfric.study.runner import run_study

    _check_reports_root(args.out)
    run_study(args.file, out_root=args.out, quick=args.quick, **_executor(args))


def _size_question(args: argparse.Namespace):
    """The question given with ``--at`` (None without it); options that need ``--at`` checked."""
    from bayesfric.sizing import CLI_KEYS, make_question, parse_at

    if args.at is None:
        for option, value in (("--confidence", args.confidence), ("--capacity", args.capacity),
                              ("--energy-rotation", args.energy_rotation)):
            if value is not None:
                raise UserError(f"{option}: applies only with --at (a study's [[sizing]] questions carry their own)")
        return None
    confidence = 0.99 if args.confidence is None else args.confidence
    return make_question(parse_at(args.at), confidence, capacity=args.capacity, energy_rotation=args.energy_rotation,
                         keys=CLI_KEYS)


def _size_study(args: argparse.Namespace, question):
    from bayesfric.study import load_study
    from bayesfric.study.resize import size_from_report

    return size_from_report(load_study(args.target), [question] if question is not None else None, args.reports,
                            cli=True, run_hint=f"`bayesfric study {args.target} --out {args.reports}`")


def _size_fit(args: argparse.Namespace, question):
    from bayesfric import sizing
    from bayesfric.sizing.single import fit_question, read_fit

    if question is None:
        raise UserError('--at: required with a fit, e.g. --at "velocity=2 rad/s"')
    fit = read_fit(args.target)
    question = fit_question(fit, question, keys=sizing.CLI_KEYS, where=args.target)
    return sizing.size_fit(fit, question, name=Path(args.target).name)


def _cmd_size(args: argparse.Namespace) -> None:
    from bayesfric.report.sizing import text_report

    question = _size_question(args)
    if args.target.endswith(".toml"):
        result = _size_study(args, question)
    elif args.target.endswith(".nc"):
        result = _size_fit(args, question)
    else:
        raise UserError(f"{args.target}: give a study file (.toml) or a fit (.nc)")
    print(text_report(result))


def _cmd_main(args: argparse.Namespace) -> None:
    from bayesfric.limits import process_problem
    from bayesfric.study.mainjob import run_flagship

    _check_reports_root(args.out)
    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs: must be a number of studies ≥ 1, got {args.jobs}")
    if args.jobs is not None and (problem := process_problem(args.jobs, "study processes")):
        raise UserError(f"--jobs: {problem}")
    if args.jobs is not None and args.jobs > 1 and (args.workers or args.scheduler):
        raise UserError("--jobs and --workers/--scheduler: give one (studies side by side, or units on Dask)")
    if args.studies is not None and not Path(args.studies).is_dir():
        raise UserError(f"--studies {args.studies}: not a folder")
    run_flagship(out_root=args.out, quick=args.quick, jobs=args.jobs, studies=args.studies, **_executor(args))


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="bayesfric", description="Bayesian model comparison of friction laws.")
    sub = p.add_subparsers(dest="command", required=True)

    q = sub.add_parser("laws", help="list the registered friction laws with units, priors and sources")
    q.add_argument("--family", help="only this family")
    q.add_argument("--markdown", action="store_true", help="Markdown tables")
    q.add_argument("--names", action="store_true", help="names only")
    q.set_defaults(func=_cmd_laws)

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
                   help="NUTS mass matrix: diag (default) | dense (strongly correlated coefficients)")
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
    q.set_defaults(func=_cmd_fit)

    q = sub.add_parser("data", help="list built-in data sets, check a user's file, or reduce a raw log")
    dsub = q.add_subparsers(dest="data_cmd", required=True, metavar="{list,check,reduce}")
    d = dsub.add_parser("list", help="built-in data sets with provenance")
    d.set_defaults(func=_cmd_data)
    d = dsub.add_parser("check", help="validate CSV + TOML metadata and print what was understood")
    d.add_argument("file", help="CSV file")
    d.add_argument("--meta", help="metadata TOML (default: FILE with .toml suffix)")
    d.set_defaults(func=_cmd_data)
    d = dsub.add_parser("reduce", help="steady-state reduction of a raw log: segment means with standard errors "
                                       "and counts (bayesfric.datasets.reduce)")
    reduce_arguments(d)
    d.set_defaults(func=_cmd_data)

    q = sub.add_parser("study", help="run a study TOML file and write reports/<study>/")
    q.add_argument("file", help="study TOML file")
    q.add_argument("--out", default="reports", help="reports root folder")
    q.add_argument("--quick", action="store_true", help="fewer draws and folds (smoke test, not for decisions)")
    _run_options(q)
    q.set_defaults(func=_cmd_study)

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
    q.add_argument("--reports", default="reports", help="reports root folder of the study (default reports)")
    q.set_defaults(func=_cmd_size)

    q = sub.add_parser("main", help="the main job: run every study in studies/ and write reports/")
    q.add_argument("--out", default="reports", help="reports root folder")
    q.add_argument("--quick", action="store_true", help="fewer draws and folds (smoke test)")
    q.add_argument("--studies", metavar="FOLDER", help="run the study files in FOLDER (default: the seed studies)")
    q.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="studies run at once, one process each (default: one per CPU core; 1: one after the other)")
    _run_options(q)
    q.set_defaults(func=_cmd_main)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bayesfric`` command; returns the exit status (2 on a user error)."""
    from bayesfric.runtime import configure

    configure()  # x64 and the persistent compilation cache
    try:
        args = build_parser().parse_args(argv)
        args.func(args)
    except USER_ERRORS as exc:
        msg = exc.args[0] if exc.args else str(exc)
        print(f"bayesfric: error: {' '.join(str(msg).splitlines())}", file=sys.stderr)  # always one line
        return 2
    except KeyboardInterrupt:
        print("bayesfric: interrupted", file=sys.stderr)
        return 130
    return 0


def run() -> NoReturn:
    """The ``bayesfric`` console command: :func:`main`, then exit without the interpreter's teardown.

    Everything a command writes is complete when :func:`main` returns (results are written
    atomically, synchronously); what is left is tearing down the interpreter: collecting the
    objects of JAX, XLA, xarray and matplotlib one by one: a warm ``bayesfric fit robot_joint
    stribeck`` took 4.05 s with it and 3.48 s without (three pairs, 2026-11-24). So this waits
    for compilations still running in the background (their results belong in the persistent
    cache), flushes the standard streams, and leaves with :func:`os._exit`. Code that calls
    :func:`main` in-process (tests, notebooks) keeps the normal exit.
    """
    code = main()
    from bayesfric.exported import finish_compilations

    finish_compilations()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    run()
