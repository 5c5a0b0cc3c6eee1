"""What each ``bayesfric`` command does with its parsed options (:mod:`bayesfric.cli` defines the
options, reports errors and exits): each ``cmd_<command>`` turns options into library calls
(:mod:`bayesfric.api.fitting`, :mod:`bayesfric.sizing.single`, :mod:`bayesfric.study.resize`,
:func:`bayesfric.pipeline.runner.run_study` ...) and prints what they return. A problem is a
:class:`~bayesfric.errors.UserError` naming the option. Heavy modules are imported inside each
command, so ``bayesfric fit`` imports no plotting or study-runner code.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from bayesfric.errors import DataError, UserError

if TYPE_CHECKING:
    from bayesfric.priors import Prior

__all__ = ["cmd_laws", "cmd_fit", "cmd_data", "cmd_study", "cmd_report", "cmd_size", "cmd_predict", "cmd_score",
           "cmd_main", "parse_priors", "parse_fix", "parse_select"]


def cmd_laws(args: argparse.Namespace) -> None:
    """``bayesfric laws``: from the stored catalogue while it is current (no JAX import:
    :mod:`bayesfric.lawcatalogue`), else from the registry itself; the same text either way."""
    from bayesfric.lawcatalogue import listing

    try:
        text = listing(args.family, markdown=args.markdown, names=args.names)
    except KeyError:
        raise UserError(f"no laws in family {args.family!r}") from None
    if text is not None:
        print(text)
        return
    from bayesfric.laws import all_laws
    from bayesfric.listing import laws_listing

    laws = [w for w in all_laws() if args.family in (None, w.family)]
    if not laws:
        raise UserError(f"no laws in family {args.family!r}")
    print("\n".join(w.name for w in laws) if args.names else laws_listing(laws, markdown=args.markdown))


def parse_priors(items: list[str] | None, known: list[str], law: str) -> dict[str, Prior]:
    """``--prior NAME=JSON`` options: NAME a parameter of the law or noise model, JSON an object."""
    from bayesfric.priors import Prior, PriorError

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


def parse_fix(items: list[str] | None, law):
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


def _option(key: str) -> str:
    """The option of ``fit`` that sets the sampler setting ``key``."""
    return "--sampler" if key == "name" else f"--{key.replace('_', '-')}"


def _fit_settings(args: argparse.Namespace):
    """The sampler configuration of ``fit``'s options (:class:`~bayesfric.inference.config.SamplerConfig`,
    checked as a study's ``[sampler]`` table is, errors naming the options)."""
    from bayesfric.api.fitting import sampler_options

    return sampler_options(args.sampler, args.seed, {"draws": args.draws, "tune": args.tune, "chains": args.chains,
                                                     "walkers": args.walkers, "init": args.init, "metric": args.metric,
                                                     "retry_target_accept": args.retry_target_accept,
                                                     "progress": not args.quiet}, key=_option)


def _load_selected(data: str, items: list[str] | None):
    from bayesfric.datasets import load_dataset, resolve, select

    ds = load_dataset(resolve(data))
    try:
        return select(ds, parse_select(items))
    except DataError as exc:
        raise UserError(f"--select {' '.join(items or [])}: {exc}") from None


def _checked_program(law, ds, priors: dict[str, Prior], noise, config):
    """The fit's program, its priors, walkers and memory checked before sampling
    (:func:`bayesfric.api.fitting.checked_program`, errors naming the options)."""
    from bayesfric.api.fitting import checked_program

    return checked_program(law, ds, priors, noise, config, key=_option, prior_key="--prior {}".format)


def cmd_fit(args: argparse.Namespace) -> None:
    from bayesfric.fsutil import PathError, check_output_file
    from bayesfric.inference import fit, save_fit
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import for_data
    from bayesfric.model import Noise

    config = _fit_settings(args)
    if args.out is not None:
        try:
            check_output_file(args.out)
        except PathError as exc:
            raise UserError(f"--out {exc}") from None
    try:
        law = get_law(args.law)
    except KeyError as exc:
        raise UserError(exc.args[0]) from None
    law = parse_fix(args.fix, law)
    ds = _load_selected(args.data, args.select)
    law = for_data(law, ds)  # its motion kind and units as they run on this data
    noise = Noise(kind=args.noise, group=args.group)
    if args.group is not None and args.group not in ds.coords:
        raise UserError(f"--group {args.group}: not a coordinate of the data ({', '.join(ds.coords)})")
    priors = parse_priors(args.prior, list(law.params) + list(noise.sites()), law.name)
    _checked_program(law, ds, priors, noise, config)  # checked before sampling
    dt = fit(law, ds, priors=priors, noise=noise, config=config)
    from bayesfric.report.tables import fit_report  # after the fit: it imports arviz-stats (see diagnostics)

    print(fit_report(dt, law))
    if args.out:
        print(f"fit written to {save_fit(dt, args.out)}")


def cmd_data(args: argparse.Namespace) -> None:
    """``bayesfric data list | check | reduce``: data files only (no JAX, numpyro, report or dask import)."""
    from bayesfric.runtime import without_dask

    without_dask()  # xarray would import dask at its first array: about 0.5 s of a light command
    if args.data_cmd == "reduce":
        from bayesfric.datasets.reduce import run_command

        run_command(args)
    elif args.data_cmd == "list":
        from bayesfric.datasets.registry import builtin_names, load_builtin
        from bayesfric.listing import datasets_listing

        print(datasets_listing({name: load_builtin(name) for name in builtin_names()}))
    else:
        from bayesfric.datasets.loader import load_dataset
        from bayesfric.datasets.registry import describe

        ds = load_dataset(args.file, args.meta)
        print(describe(ds))
        print("OK: the file is valid")


def _check_reports_root(out: str) -> None:
    from bayesfric.fsutil import PathError, check_output_folder

    try:
        check_output_folder(out)
    except PathError as exc:
        raise UserError(f"--out {exc}") from None


def _executor(args: argparse.Namespace) -> dict:
    from bayesfric.limits import process_problem

    if args.workers < 0:
        raise UserError(f"--workers: must be 0 (serial) or a number of processes ≥ 1, got {args.workers}")
    if problem := process_problem(args.workers, "worker processes"):
        raise UserError(f"--workers: {problem}")
    if args.workers and args.scheduler:
        raise UserError("--workers and --scheduler: give one (a local cluster, or an existing one)")
    return dict(fresh=args.fresh, workers=args.workers, scheduler=args.scheduler)


def cmd_study(args: argparse.Namespace) -> None:
    from bayesfric.pipeline.runner import run_study

    _check_reports_root(args.out)
    run_study(args.file, out_root=args.out, quick=args.quick, **_executor(args))


def cmd_report(args: argparse.Namespace) -> None:
    from bayesfric.report.summary import rerender

    print(f"report rendered from {args.results} into {rerender(args.results, args.out)}")


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


def cmd_size(args: argparse.Namespace) -> None:
    from bayesfric.report.sizing import text_report

    if args.horizon is not None:
        return _time_to_exceed(args)
    question = _size_question(args)
    if args.target.endswith(".toml"):  # the study's stored fits and weights (bayesfric.study.resize)
        from bayesfric.study import load_study
        from bayesfric.study.resize import size_from_report

        result = size_from_report(load_study(args.target), [question] if question is not None else None,
                                  args.reports, cli=True,
                                  run_hint=f"`bayesfric study {args.target} --out {args.reports}`")
    elif args.target.endswith(".nc"):  # one fit (bayesfric.sizing.single)
        from bayesfric.sizing import CLI_KEYS
        from bayesfric.sizing.single import answer_fit, read_fit

        if question is None:
            raise UserError('--at: required with a fit, e.g. --at "velocity=2 rad/s"')
        result = answer_fit(read_fit(args.target), question, name=Path(args.target).name, keys=CLI_KEYS,
                            where=args.target)
    else:
        raise UserError(f"{args.target}: give a study file (.toml) or a fit (.nc)")
    print(text_report(result))


def _time_to_exceed(args: argparse.Namespace) -> None:
    """``size FIT.nc --at ... --capacity ... --horizon ...``: when the capacity is first exceeded."""
    from bayesfric.api.sizing import time_to_exceed
    from bayesfric.report.service import text

    if not args.target.endswith(".nc"):
        raise UserError(f"--horizon: give a fit (.nc) of a law with a trend, not {args.target} (a study answers its "
                        "own [[sizing]] horizon questions in its report)")
    for option, value in (("--at", args.at), ("--capacity", args.capacity)):
        if value is None:
            raise UserError(f"{option}: required with --horizon")
    if args.confidence is not None or args.energy_rotation is not None:
        raise UserError("--horizon: asks a time to exceed; --confidence and --energy-rotation do not apply")
    print(text(time_to_exceed(args.target, args.at, capacity=args.capacity, horizon=args.horizon)))


def _checked_out(path: str | None) -> None:
    from bayesfric.fsutil import PathError, check_output_file

    if path is not None:
        try:
            check_output_file(path)
        except PathError as exc:
            raise UserError(f"--out {exc}") from None


def _about(attrs: dict) -> str:
    """The lines ``predict`` and ``score`` print before their result: what answers, for what."""
    lines = [f"{attrs['source']} on {attrs['data']}", f"answering for: {attrs['answer_for']}",
             f"weights: {attrs['weighting']} ({attrs['weighting_note']})"]
    lines += [f"{key}: {attrs[key]}" for key in ("excluded", "no_average", "noise_note") if attrs.get(key)]
    return "\n".join(lines + [attrs["bands"]])


def cmd_predict(args: argparse.Namespace) -> None:
    from bayesfric.api.predicting import CLI_KEYS, QUANTILES, predicted, predictions_table
    from bayesfric.csvout import write_csv
    from bayesfric.quantities import QUANTITIES

    _checked_out(args.out)
    pred = predicted(args.target, args.log, QUANTILES if args.quantiles is None else args.quantiles, args.group,
                     args.seed, CLI_KEYS)
    print(_about(pred.attrs))
    response = pred.attrs.get("response")
    unit = f" ({response} in {QUANTITIES[response].unit}, inputs in SI)" if response in QUANTITIES else " (SI)"
    write_csv(args.out, predictions_table(pred))
    print(f"{pred.sizes['law']} × {pred.sizes['obs']} predictions written to {args.out}{unit}")


def cmd_score(args: argparse.Namespace) -> None:
    from bayesfric.api.predicting import CLI_KEYS, score_text, scored
    from bayesfric.csvout import write_csv

    _checked_out(args.out)
    table = scored(args.target, args.log, args.group, args.seed, CLI_KEYS)
    print(_about(table.attrs))
    print(score_text(table))
    if args.out:
        print(f"scores written to {write_csv(args.out, table)}")


def cmd_main(args: argparse.Namespace) -> None:
    from bayesfric.limits import process_problem
    from bayesfric.pipeline.mainjob import run_flagship

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
