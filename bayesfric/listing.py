"""Plain-text and Markdown tables, and the listings of ``bayesfric laws`` and ``bayesfric data list``.

A base module (standard library only) so that the light commands render their tables without
importing the report package, whose other tables read fits (arviz, JAX), and so that the stored
law catalogue (:mod:`bayesfric.lawcatalogue`) depends on the laws and this file only.
:mod:`bayesfric.report.tables` re-exports every name.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import xarray as xr

    from bayesfric.laws.base import Law

__all__ = ["format_table", "datasets_listing", "law_rows", "laws_listing"]


def format_table(header: list[str], rows: list[list[str]], markdown: bool = False) -> str:
    """Plain-text (aligned) or Markdown table."""
    if markdown:
        lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines)
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows, strict=True)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return "\n".join([fmt.format(*header), fmt.format(*("-" * w for w in widths))]
                     + [fmt.format(*r) for r in rows])


def datasets_listing(datasets: Mapping[str, xr.Dataset]) -> str:
    """``bayesfric data list``: one row per data set (by name): provenance, rows, response, source."""
    rows = [[name, ds.attrs["provenance"], str(ds.sizes["obs"]), ds.attrs.get("response", ""),
             ds.attrs.get("source", "")[:90]] for name, ds in datasets.items()]
    return format_table(["data set", "provenance", "rows", "response", "source"], rows)


def law_rows(law: Law) -> list[list[str]]:
    """Rows (law, inputs, parameter, unit, prior, source) describing a declaration."""
    rows = []
    for i, (name, p) in enumerate(law.params.items()):
        shape = f"{name}{list(p.shape)}" if p.shape else name
        rows.append([law.name if i == 0 else "", ", ".join(law.operating_inputs) if i == 0 else "",
                     shape, p.unit, str(p.prior), p.source])
    return rows


def laws_listing(laws: list[Law], markdown: bool = False) -> str:
    """``bayesfric laws``: per family, a table of the laws' parameters (:func:`law_rows`), then one
    line per law: its summary, source, response and whether it also runs on force data."""
    from bayesfric.laws.variants import translation_problem

    header = ["law", "inputs", "parameter", "unit", "prior", "source"]
    out = []
    for family in sorted({w.family for w in laws}):
        members = [w for w in laws if w.family == family]
        out += [f"\n== family {family} ==", format_table(header, [r for w in members for r in law_rows(w)], markdown)]
        for w in members:
            problem = translation_problem(w)
            motion = "also force data (translational)" if problem is None else f"rotary only: {problem}"
            out.append(f"  {w.name}: {w.summary}  [{w.source}; response {w.response}; {motion}]")
    return "\n".join(out)
