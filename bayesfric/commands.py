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

from bayesfric.errors import UserError

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
    """``--select COORD=VALUE`` options (:func:`bayesfric.precheck.parse_select`)."""
    from bayesfric.precheck import parse_select as parsed

    return parsed(items)


def _checked_program(law, ds, priors: dict[str, Prior], noise, config):
    """The fit's program, its priors, walkers and memory checked before sampling
    (:func:`bayesfric.api.fitting.checked_program`, errors naming the options)."""
    from bayesfric.api.fitting import checked_program
    from bayesfric.precheck import option

    return checked_program(law, ds, priors, noise, config, key=option, prior_key="--prior {}".format)


def cmd_fit(args: argparse.Namespace) -> None:
    """``bayesfric fit``: the options, the data and ``--out`` were checked before JAX loaded
    (:func:`bayesfric.precheck.fit`: ``args.config``, ``args.dataset``); the law, its priors and
    the memory here, before sampling."""
    from bayesfric.inference import fit, save_fit
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import for_data
    from bayesfric.model import Noise

    try:
        law = get_law(args.law)
    except KeyError as exc:
        raise UserError(exc.args[0]) from None
    law = parse_fix(args.fix, law)
    ds = args.dataset
    law = for_data(law, ds)  # its motion kind and units as they run on this data
    noise = Noise(kind=args.noise, group=args.group)
    priors = parse_priors(args.prior, list(law.params) + list(noise.sites()), law.name)
    _checked_program(law, ds, priors, noise, args.config)  # checked before sampling
    dt = fit(law, ds, priors=priors, noise=noise, config=args.config)
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


def _executor(args: argparse.Namespace) -> dict:
    """The run store and executor options of ``study`` and ``main`` (checked by :mod:`bayesfric.precheck`)."""
    return dict(fresh=args.fresh, workers=args.workers, scheduler=args.scheduler)


def cmd_study(args: argparse.Namespace) -> None:
    from bayesfric.pipeline.runner import run_study

    run_study(args.file, out_root=args.out, quick=args.quick, **_executor(args))


def cmd_report(args: argparse.Namespace) -> None:
    from bayesfric.report.summary import rerender

    print(f"report rendered from {args.results} into {rerender(args.results, args.out)}")


def cmd_size(args: argparse.Namespace) -> None:
    """``bayesfric size``: the question (``args.question``) was parsed before JAX loaded
    (:func:`bayesfric.precheck.size`)."""
    from bayesfric.report.sizing import text_report

    if args.horizon is not None:
        return _time_to_exceed(args)
    question = args.question
    if args.target.endswith(".toml"):  # the study's stored fits and weights (bayesfric.study.resize)
        from bayesfric.study import load_study
        from bayesfric.study.resize import size_from_report

        result = size_from_report(load_study(args.target), [question] if question is not None else None,
                                  args.reports, cli=True,
                                  run_hint=f"`bayesfric study {args.target} --out {args.reports}`")
    else:  # one fit (bayesfric.sizing.single)
        from bayesfric.sizing import CLI_KEYS
        from bayesfric.sizing.single import answer_fit, read_fit

        result = answer_fit(read_fit(args.target), question, name=Path(args.target).name, keys=CLI_KEYS,
                            where=args.target)
    print(text_report(result))


def _time_to_exceed(args: argparse.Namespace) -> None:
    """``size FIT.nc --at ... --capacity ... --horizon ...``: when the capacity is first exceeded
    (the options checked by :func:`bayesfric.precheck.size`; errors name them)."""
    from bayesfric.api.sizing import time_to_exceed
    from bayesfric.report.service import text
    from bayesfric.sizing import CLI_KEYS, SizingError

    try:
        answer = time_to_exceed(args.target, args.at, capacity=args.capacity, horizon=args.horizon)
    except SizingError as exc:
        head, _, sub = exc.key.partition(".")
        option = CLI_KEYS.get(head, head)
        raise UserError(exc.problem, f"{option} {sub}".strip() if option else "") from None
    print(text(answer))


def _about(attrs: dict) -> str:
    """The lines ``predict`` and ``score`` print before their result: what answers, for what."""
    lines = [f"WARNING: {attrs[key]}" for key in ("new_run", "bend") if attrs.get(key)]
    lines += [f"{attrs['source']} on {attrs['data']}", f"answering for: {attrs['answer_for']}",
             f"weights: {attrs['weighting']} ({attrs['weighting_note']})"]
    lines += [f"{key}: {attrs[key]}" for key in ("excluded", "no_average", "noise_note") if attrs.get(key)]
    if attrs.get("envelope"):
        lines.append(f"outside the fitted envelope (within-model bands only; sizing's calibrated answers add the "
                     f"form error measured there): {attrs['envelope']}")
    return "\n".join(lines + [attrs["bands"]])


def cmd_predict(args: argparse.Namespace) -> None:
    from bayesfric.api.predicting import CLI_KEYS, QUANTILES, predicted, predictions_table
    from bayesfric.csvout import write_csv
    from bayesfric.quantities import QUANTITIES

    pred = predicted(args.target, args.log, QUANTILES if args.quantiles is None else args.quantiles, args.group,
                     args.seed, CLI_KEYS)
    print(_about(pred.attrs))
    response = pred.attrs.get("response")
    unit = f" ({response} in {QUANTITIES[response].unit}, inputs in SI)" if response in QUANTITIES else " (SI)"
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)  # missing parents are created (checked before)
    write_csv(args.out, predictions_table(pred))
    print(f"{pred.sizes['law']} × {pred.sizes['obs']} predictions written to {args.out}{unit}")


def cmd_score(args: argparse.Namespace) -> None:
    from bayesfric.api.predicting import CLI_KEYS, score_text, scored
    from bayesfric.csvout import write_csv

    table = scored(args.target, args.log, args.group, args.seed, CLI_KEYS)
    print(_about(table.attrs))
    print(score_text(table))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        print(f"scores written to {write_csv(args.out, table)}")


def cmd_main(args: argparse.Namespace) -> None:
    """``bayesfric main``: its options were checked by :func:`bayesfric.precheck.main`."""
    from bayesfric.pipeline.mainjob import run_flagship

    run_flagship(out_root=args.out, quick=args.quick, jobs=args.jobs, studies=args.studies, **_executor(args))
