"""Sizing one fit: a fit file read and checked, and a question checked against the fit's law.

Used by ``bayesfric size FIT.nc --at ...`` and by :func:`bayesfric.size` on a fit; the answer
itself is :func:`bayesfric.sizing.size_fit` (weight 1, the fit's own data as the tested range).
Every problem is a :class:`~bayesfric.errors.UserError` of one line naming the file (or the fit)
and the key.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import xarray as xr

from bayesfric.errors import UserError
from bayesfric.sizing.points import SizingError, SizingQuestion, check_question
from bayesfric.sizing.result import SizingAnswer

__all__ = ["read_fit", "fit_question", "answer_fit"]


def read_fit(path: str | Path) -> xr.DataTree:
    """The fit saved at ``path`` (``bayesfric fit --out``, :func:`bayesfric.inference.save_fit`, a
    study's ``fits/<law>.nc``), read into memory and checked to be a bayesfric fit. The package's
    one reader of fit files; :func:`bayesfric.load_fit` adds the program that produced it.

    Raises
    ------
    UserError
        No such file, not a file, not readable as NetCDF, or not a bayesfric fit.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: fit file not found" if not path.exists() else f"{path}: not a file")
    try:
        fit = xr.open_datatree(path, engine="h5netcdf").load()
    except Exception:  # h5py/netCDF raise many types for a file that is not a fit
        raise UserError(f"{path}: not a readable fit (a NetCDF file written by `bayesfric fit --out`)") from None
    _check_is_fit(fit, str(path))
    return fit


def _check_is_fit(fit: object, where: str) -> None:
    if not isinstance(fit, xr.DataTree):
        raise UserError(f"{where}: not a fit (an xarray.DataTree from bayesfric.fit), got {type(fit).__name__}")
    if not {"law", "noise", "priors", "constants"} <= set(fit.attrs) or not {"posterior", "constant_data"} <= set(
            fit.children):
        raise UserError(f"{where}: not a bayesfric fit (no law, noise model or posterior recorded)")


def fit_question(fit: xr.DataTree, question: SizingQuestion, *, keys: Mapping[str, str] | None = None,
                 where: str = "the fit") -> SizingQuestion:
    """``question`` checked against the law of ``fit`` (:func:`~bayesfric.sizing.points.check_question`:
    every input named is one the law reads and every one it reads is given; the capacity is of
    its response), with its capacity parsed. ``keys`` names the question's keys in errors
    (:data:`~bayesfric.sizing.points.CLI_KEYS` for the command line); ``where`` names the fit.

    Raises
    ------
    UserError
        Not a bayesfric fit, a law that cannot be rebuilt (no longer known by its name, or a
        law file the fit records gone: :class:`~bayesfric.laws.plugins.LawModuleError`), a
        trajectory (stateful) law without a steady state, or a question the law cannot answer
        (:class:`~bayesfric.sizing.points.SizingError`). A trajectory law's question is asked of
        its steady state at constant speed (:func:`bayesfric.sizing.steady.sizing_law`).
    """
    from bayesfric.laws.variants import law_of_fit
    from bayesfric.sizing.steady import sizing_law

    _check_is_fit(fit, where)
    try:
        law = sizing_law(law_of_fit(fit.attrs))  # the law as it ran on the fit's data
    except KeyError as exc:
        raise UserError(f"{where}: {exc.args[0]}") from None
    except SizingError as exc:
        raise UserError(f"{where}: {exc.problem}") from None
    return check_question(question, law.operating_inputs, law.operating_inputs, law.response, keys=keys,
                          inputs_of=f"law {law.name!r}")


def answer_fit(fit: xr.DataTree, question: SizingQuestion, *, name: str, keys: Mapping[str, str] | None = None,
               where: str = "the fit", seed: int = 0) -> SizingAnswer:
    """The answer of one fit to ``question``: the question checked against the fit's law
    (:func:`fit_question`, errors naming ``keys`` and ``where``), then
    :func:`bayesfric.sizing.size_fit` (``name`` names the fit in the result).

    Raises
    ------
    UserError
        As :func:`fit_question`.
    """
    from bayesfric.sizing import size_fit

    return size_fit(fit, fit_question(fit, question, keys=keys, where=where), name=name, seed=seed)
