"""An output path checked against what the command reads: no command writes onto its own input.

``bayesfric predict FIT log.csv --out log.csv`` would replace the measured log with predictions,
``--out log.toml`` its sidecar, ``--out REPORT/results.nc`` a study's results, ``score fit.nc
new.csv --out fit.nc`` the fit. Every command that takes ``--out`` (``fit``, ``predict``,
``score``, ``data reduce``; ``study`` and ``main`` for the files a study reads, checked by its
plan) checks its output here before any work (:func:`checked_out`): the path must be writable
(:func:`bayesfric.fsutil.check_output_file`), must not be a file the command reads (compared
resolved, links followed, and by inode where both exist, so a hard link is the same file) and must
not lie inside a folder it reads (a study's report folder). The message names the option, the
path and what it would overwrite, in one line.

A base module: it imports the standard library, :mod:`bayesfric.errors`, :mod:`bayesfric.fsutil`
and :mod:`bayesfric.builtin` only, so the command line runs it before JAX loads.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from bayesfric.errors import UserError
from bayesfric.fsutil import MARKER, PathError, check_output_file

__all__ = ["same_file", "overwrite_problem", "checked_out", "data_files", "target_reads"]


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether ``a`` and ``b`` name one file: the same resolved path, or the same inode (a hard link)."""
    a, b = Path(a), Path(b)
    try:
        if a.resolve() == b.resolve():
            return True
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def _inside(path: Path, folder: Path) -> bool:
    try:
        return path.resolve().is_relative_to(folder.resolve())
    except (OSError, ValueError):
        return False


def overwrite_problem(out: str | Path, reads: Iterable[tuple[str | Path, str]] = (),
                      folders: Iterable[tuple[str | Path, str]] = ()) -> str | None:
    """Why writing ``out`` would overwrite what the command reads (None: it would not).

    Parameters
    ----------
    out : str or Path
        The output file.
    reads : iterable of (path, what)
        The files the command reads and what each is (``"the log"``, ``"the log's sidecar"``).
    folders : iterable of (path, what)
        The folders it reads from (a study's report folder): ``out`` must lie outside them.

    Examples
    --------
    >>> overwrite_problem("a/log.csv", [("a/./log.csv", "the log")])
    'would overwrite a/./log.csv, the log this command reads'
    >>> overwrite_problem("r/results.nc", folders=[("r", "the report folder")])
    'would write inside r, the report folder this command reads'
    """
    for path, what in reads:
        if same_file(out, path):
            return f"would overwrite {path}, {what} this command reads"
    for folder, what in folders:
        if _inside(Path(out), Path(folder)):
            return f"would write inside {folder}, {what} this command reads"
    return None


def checked_out(path: str | Path | None, option: str = "--out", reads: Iterable[tuple[str | Path, str]] = (),
                folders: Iterable[tuple[str | Path, str]] = ()) -> Path | None:
    """``path`` checked before any work: writable (:func:`bayesfric.fsutil.check_output_file`)
    and not one of the files or inside the folders the command reads (:func:`overwrite_problem`).
    None passes (no output asked for).

    Raises
    ------
    UserError
        One line: ``<option> <path>: <problem>``.
    """
    if path is None:
        return None
    if problem := overwrite_problem(path, reads, folders):
        raise UserError(f"{option} {path}: {problem}; write the output elsewhere")
    try:
        return check_output_file(path)
    except PathError as exc:
        raise UserError(f"{option} {exc}") from None


def data_files(ref: str | Path, meta: str | Path | None = None) -> list[tuple[Path, str]]:
    """The CSV file and sidecar a data argument reads (a CSV path, or a built-in data set's name),
    with what each is; a name that is neither gives none (the loader reports it)."""
    from bayesfric.builtin import builtin_folder

    path = Path(ref)
    if path.suffix != ".csv" and not path.exists():
        path = builtin_folder("bayesfric.builtin_data", "data") / str(ref) / f"{ref}.csv"
        if not path.exists():
            return []
    sidecar = Path(meta) if meta is not None else path.with_suffix(".toml")
    return [(path, "the data file"), (sidecar, "the data file's sidecar")]


def target_reads(target: str | Path) -> tuple[list[tuple[Path, str]], list[tuple[Path, str]]]:
    """(files, folders) that ``predict``/``score`` read of their TARGET: a report folder (all of
    it), a ``results.nc`` (and its report folder where that carries bayesfric's marker), or a fit."""
    path = Path(target)
    if path.is_dir():
        return [], [(path, "the report folder")]
    folders = [(path.parent, "the report folder")] if (path.parent / MARKER).is_file() else []
    return [(path, "the fit or study result")], folders
