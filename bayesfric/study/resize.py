"""Sizing from a study's written report: its stored fits and ``results.nc``, without refitting.

Used by ``bayesfric size STUDY.toml`` and by :func:`bayesfric.size` on a study or a study's
result. The answer itself is :func:`bayesfric.sizing.size_study`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from bayesfric import sizing
from bayesfric.errors import UserError
from bayesfric.fsutil import is_marked
from bayesfric.sizing.result import SizingAnswer
from bayesfric.study.config import Study
from bayesfric.study.plan import load_study_data, sizing_questions

__all__ = ["size_from_report"]


def size_from_report(study: Study, questions: list[sizing.SizingQuestion] | None, reports: str | Path, *,
                     cli: bool = False, keys: Mapping[str, str] | None = None,
                     run_hint: str = "") -> SizingAnswer:
    """Answer ``questions`` (None: the study's own ``[[sizing]]``) from the report of ``study``
    in the reports root ``reports``.

    Parameters
    ----------
    study : Study
        A loaded study (its data are loaded again and must be the data the fits were made from).
    questions : list of SizingQuestion, optional
        Asked besides the study file; checked against the data and the laws
        (:func:`bayesfric.study.runner.sizing_questions`), errors naming the option (``cli``)
        or the key in ``keys``.
    reports : str or Path
        The reports root the study was run into.
    run_hint : str
        How to write the report, for the error when there is none.

    Raises
    ------
    UserError
        No question, no report of the study there, a report without its sizing basis, or
        fits that no longer match the study's laws or data.
    """
    ds = load_study_data(study)
    if questions is None and not study.sizing:
        raise UserError(f"{study.path}: the study asks no sizing question: add a [[sizing]] entry or give "
                        f"{'--at' if cli else 'at'}")
    asked = questions is not None  # asked besides the file: errors name the option or key, not sizing[i]
    checked = sizing_questions(study, ds, questions, cli=cli and asked, keys=keys if asked else None)
    folder = Path(reports) / study.name
    if not is_marked(folder, study.name):
        hint = run_hint or f"`bayesfric study {study.path} --out {reports}`"
        raise UserError(f"{study.path}: no report of study {study.name!r} in {reports}: run {hint} first")
    basis = sizing.read_basis(folder)
    laws = sizing.sources(basis, folder, [spec.name for spec in study.laws], data_hash=ds.attrs.get("data_hash"),
                          selection=str(ds.attrs.get("selection", "")))
    return sizing.size_study(checked, ds, laws, sizing.basis_schemes(basis), study_name=study.name,
                             seed=study.sampler["seed"], fan=False)
