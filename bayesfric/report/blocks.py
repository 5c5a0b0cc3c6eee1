"""The building blocks of a report that its parts fill in (:mod:`bayesfric.report.ranking`,
:mod:`bayesfric.report.study_figures`) and the content model assembles
(:mod:`bayesfric.report.content`, which re-exports them): a :class:`Table` of strings and a
:class:`FigureRef`. Below all of them, so no part imports the content model back."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Table", "FigureRef"]


@dataclass
class Table:
    """A caption, a header and rows of strings; ``warn``: row indices to mark."""

    caption: str
    header: list[str]
    rows: list[list[str]]
    warn: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class FigureRef:
    """A figure file (relative to the report folder), its section and what to read from it."""

    section: str
    path: str
    caption: str
    alt: str
