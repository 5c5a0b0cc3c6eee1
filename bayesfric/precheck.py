"""The command line's argument checks, run before JAX loads.

:func:`bayesfric.cli.main` runs the check of a computing command (``fit``, ``size``, ``study``,
``main``, ``predict``, ``score``) after argparse and before :func:`bayesfric.runtime.configure`
imports JAX: a bad option, a missing file or an ``--out`` onto the command's own input costs a
fraction of a second, not JAX's import (6–10 s on a loaded machine). Only light modules are
imported here (the data loader, the unit vocabulary, :mod:`bayesfric.samplerconfig`,
:mod:`bayesfric.sizing.points`, :mod:`bayesfric.outpaths`; ``tests/test_cli_start.py`` checks the
import list); what needs a law's code, a fit's program or a study's laws is checked after, by
the library. What a check parses is kept on the options for the command (``args.config``,
``args.dataset``, ``args.question``), so nothing is parsed twice.
"""

from __future__ import annotations

import argparse
import json
import tomllib
from pathlib import Path

from bayesfric.errors import DataError, UserError
from bayesfric.outpaths import checked_out, data_files, target_reads

__all__ = ["fit", "size", "study", "main", "predict", "score", "option", "parse_select"]


def option(key: str) -> str:
    """The option of ``fit`` that sets the sampler setting ``key``."""
    return "--sampler" if key == "name" else f"--{key.replace('_', '-')}"


def parse_select(items: list[str] | None) -> dict[str, object]:
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


def _pairs(items: list[str] | None, option_name: str, form: str, example: str) -> list[tuple[str, str]]:
    """``NAME=VALUE`` options split, each with a name and an ``=``."""
    out = []
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise UserError(f"{option_name} {item!r}: expected {form}, e.g. {example}")
        out.append((name, value))
    return out


def _load_selected(data: str, items: list[str] | None):
    """The data set of ``fit`` with its ``--select`` rows (the loader: no JAX)."""
    from bayesfric.datasets.loader import load_dataset
    from bayesfric.datasets.registry import resolve
    from bayesfric.datasets.rows import select

    ds = load_dataset(resolve(data))
    try:
        return select(ds, parse_select(items))
    except DataError as exc:
        raise UserError(f"--select {' '.join(items or [])}: {exc}") from None


def fit(args: argparse.Namespace) -> None:
    """``fit``: the sampler options (as a study's ``[sampler]``), ``--out``, the syntax of
    ``--prior`` and ``--fix``, the data with ``--select``, and ``--group``."""
    from bayesfric.samplerconfig import SamplerConfig

    args.config = SamplerConfig.from_table(
        {"name": args.sampler, "seed": args.seed, "draws": args.draws, "tune": args.tune, "chains": args.chains,
         "walkers": args.walkers, "init": args.init, "metric": args.metric,
         "retry_target_accept": args.retry_target_accept, "progress": not args.quiet}, key=option)
    checked_out(args.out, reads=data_files(args.data))
    for name, spec in _pairs(args.prior, "--prior", "NAME=JSON", 'T_C=\'{"dist": "HalfNormal", "scale": 2}\''):
        try:
            json.loads(spec)
        except json.JSONDecodeError as exc:
            raise UserError(f"--prior {name}: invalid JSON ({exc.msg})") from None
    for name, text in _pairs(args.fix, "--fix", "NAME=VALUE", "--fix i=1.5"):
        try:
            float(text)
        except ValueError:
            raise UserError(f"--fix {name}: {text!r} is not a number") from None
    args.dataset = _load_selected(args.data, args.select)  # xarray and pint load here, not JAX
    from bayesfric.datasets.rows import group_problem

    if args.group is not None and (problem := group_problem(args.dataset, args.group)):
        raise UserError(f"--group {args.group}: {problem}")


def _size_question(args: argparse.Namespace):
    """The question given with ``--at`` (None without it); options that need ``--at`` checked."""
    from bayesfric.sizing.points import CLI_KEYS, make_question, parse_at

    if args.at is None:
        for name, value in (("--confidence", args.confidence), ("--capacity", args.capacity),
                            ("--energy-rotation", args.energy_rotation)):
            if value is not None:
                raise UserError(f"{name}: applies only with --at (a study's [[sizing]] questions carry their own)")
        return None
    confidence = 0.99 if args.confidence is None else args.confidence
    return make_question(parse_at(args.at), confidence, capacity=args.capacity, energy_rotation=args.energy_rotation,
                         keys=CLI_KEYS)


def _horizon_question(args: argparse.Namespace):
    """``size FIT --at ... --capacity ... --horizon ...``: a time to exceed, at one point."""
    from bayesfric.sizing.points import CLI_KEYS, make_question, parse_at

    if not args.target.endswith(".nc"):
        raise UserError(f"--horizon: give a fit (.nc) of a law with a trend, not {args.target} (a study answers its "
                        "own [[sizing]] horizon questions in its report)")
    for name, value in (("--at", args.at), ("--capacity", args.capacity)):
        if value is None:
            raise UserError(f"{name}: required with --horizon")
    if args.confidence is not None or args.energy_rotation is not None:
        raise UserError("--horizon: asks a time to exceed; --confidence and --energy-rotation do not apply")
    return make_question(parse_at(args.at), 0.99, capacity=args.capacity, keys=CLI_KEYS, horizon=args.horizon)


def size(args: argparse.Namespace) -> None:
    """``size``: the question's options (points and units, confidence, capacity, horizon) and the target."""
    args.question = _horizon_question(args) if args.horizon is not None else _size_question(args)
    path = Path(args.target)
    if path.suffix == ".toml":
        if not path.is_file():
            raise UserError(f"{path}: study file not found" if not path.exists() else f"{path}: not a file")
    elif path.suffix == ".nc":
        if args.question is None:
            raise UserError('--at: required with a fit, e.g. --at "velocity=2 rad/s"')
        if not path.is_file():
            raise UserError(f"{path}: fit file not found" if not path.exists() else f"{path}: not a file")
    else:
        raise UserError(f"{args.target}: give a study file (.toml) or a fit (.nc)")


def _reports_root(out: str) -> None:
    from bayesfric.fsutil import PathError, check_output_folder

    try:
        check_output_folder(out)
    except PathError as exc:
        raise UserError(f"--out {exc}") from None


def _executor(args: argparse.Namespace) -> None:
    from bayesfric.limits import process_problem

    if args.workers < 0:
        raise UserError(f"--workers: must be 0 (serial) or a number of processes ≥ 1, got {args.workers}")
    if problem := process_problem(args.workers, "worker processes"):
        raise UserError(f"--workers: {problem}")
    if args.workers and args.scheduler:
        raise UserError("--workers and --scheduler: give one (a local cluster, or an existing one)")


def study(args: argparse.Namespace) -> None:
    """``study``: the reports root, the executor's options and the study file (there, TOML)."""
    _reports_root(args.out)
    _executor(args)
    path = Path(args.file)
    if not path.is_file():
        raise UserError(f"{path}: study file not found" if not path.exists() else f"{path}: not a file")
    try:
        tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: invalid TOML: {exc}") from None
    except (UnicodeDecodeError, OSError):
        pass  # the study loader says what is wrong, in its words


def main(args: argparse.Namespace) -> None:
    """``main``: the reports root, ``--jobs``, ``--studies`` and the executor's options."""
    from bayesfric.limits import process_problem

    _reports_root(args.out)
    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs: must be a number of studies ≥ 1, got {args.jobs}")
    if args.jobs is not None and (problem := process_problem(args.jobs, "study processes")):
        raise UserError(f"--jobs: {problem}")
    if args.jobs is not None and args.jobs > 1 and (args.workers or args.scheduler):
        raise UserError("--jobs and --workers/--scheduler: give one (studies side by side, or units on Dask)")
    if args.studies is not None and not Path(args.studies).is_dir():
        raise UserError(f"--studies {args.studies}: not a folder")
    _executor(args)


def _predict_paths(args: argparse.Namespace) -> None:
    """TARGET and LOG exist, ``--seed`` is a seed, and ``--out`` is none of the files they are."""
    from bayesfric.argcheck import seed_value

    seed_value(args.seed, "--seed")
    target = Path(args.target)
    if not target.exists():
        raise UserError(f"{target}: no such file or report folder (a study's report folder, its results.nc, or a fit)")
    log = Path(args.log)
    reads = data_files(args.log)
    if (log.suffix == ".csv" and not log.is_file()) or not reads:
        raise UserError(f"{log}: no such file (LOG: a CSV file with its TOML sidecar, or a built-in data set)")
    files, folders = target_reads(target)
    checked_out(args.out, reads=files + reads, folders=folders)


def predict(args: argparse.Namespace) -> None:
    """``predict``: ``--quantiles``, ``--seed``, TARGET, LOG and ``--out``."""
    from bayesfric.argcheck import quantile_levels

    if args.quantiles is not None:
        args.quantiles = quantile_levels(args.quantiles, "--quantiles")
    _predict_paths(args)


def score(args: argparse.Namespace) -> None:
    """``score``: ``--seed``, TARGET, LOG and ``--out``."""
    _predict_paths(args)
