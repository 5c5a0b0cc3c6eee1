"""Every CSV file bayesfric writes goes through :func:`write_csv`: one writer, text cells made inert.

A spreadsheet runs a cell that starts with ``=``, ``+``, ``-``, ``@``, a tab or a carriage return
as a formula (CSV or formula injection): a blocked fold labelled ``=cmd|' /C calc'!A0`` or a claim
whose text starts with ``@`` would run when an engineer opens ``scores.csv`` or ``claims.csv``.
As the OWASP guidance on CSV injection describes, such a text cell is written with a single quote
``'`` in front (:func:`neutralise`), which spreadsheets show as text and never evaluate; the CSV
module quotes separators and doubles quotes inside cells. Numbers stay numbers: a numeric value
(``-0.5``, ``True``, NaN) is written as it is, and so is text that is a plain decimal number
(``"-0.500"``, ``"-1e3"``, what :func:`bayesfric.study.executor.write_timings` formats), which a
spreadsheet reads as a number, not a formula. Everything else (labels, names, claims, reasons,
units) comes from users, data files or laws and is neutralised wherever it appears.

Files are UTF-8 with ``\\n`` line ends; an empty table is an empty file.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["FORMULA_START", "neutralise", "write_csv"]

#: First characters that make a spreadsheet evaluate a cell (OWASP, CSV injection).
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
_NUMBER = re.compile(r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?")


def neutralise(value: Any) -> Any:
    """``value`` safe for a spreadsheet cell: text starting with one of :data:`FORMULA_START` (and
    not a plain decimal number) gets a leading ``'``; anything else is returned unchanged."""
    if isinstance(value, str) and value.startswith(FORMULA_START) and not _NUMBER.fullmatch(value):
        return "'" + value
    return value


def write_csv(path: str | Path, rows: Any, header: Sequence[str] | None = None) -> Path:
    """Write a table as CSV with every text cell neutralised (:func:`neutralise`), header included.

    Parameters
    ----------
    path : str or Path
        The file (replaced if it exists).
    rows : list of dict, list of sequences, or pandas.DataFrame
        Records (columns: every key, in first-seen order), rows under ``header``, or a data frame
        (written by pandas, its numbers as pandas writes them, without the index).
    header : sequence of str, optional
        Column names of sequence rows.
    """
    path = Path(path)
    if hasattr(rows, "to_csv"):  # a pandas DataFrame: its text columns neutralised, numbers untouched
        frame = rows.copy()
        for column in frame.select_dtypes(include=["object", "string"]).columns:
            frame[column] = frame[column].map(neutralise)
        frame.columns = [neutralise(c) for c in frame.columns]
        frame.to_csv(path, index=False, encoding="utf-8", lineterminator="\n")
        return path
    rows = list(rows)
    if header is None and rows and isinstance(rows[0], Mapping):
        header = list(dict.fromkeys(k for r in rows for k in r))
        rows = [[r.get(k, "") for k in header] for r in rows]
    with path.open("w", newline="", encoding="utf-8") as fh:
        if header is None and not rows:
            return path
        writer = csv.writer(fh, lineterminator="\n")
        if header is not None:
            writer.writerow([neutralise(h) for h in header])
        writer.writerows([neutralise(v) for v in row] for row in rows)
    return path
