"""The provenance line every figure, table and sizing answer of a data set carries.

A data set says where its numbers come from (``attrs["provenance"]``: ``measured``,
``reconstructed`` from a paper's figures, or ``simulated``; ``attrs["source"]``). The label is
the same wherever it is printed, so it lives with the data sets, below sizing and the report,
which both print it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["provenance_label", "provenance_text"]


def provenance_label(ds: Any) -> str:
    """The label of a data set (reconstructed / measured / simulated), from its ``attrs``.

    Examples
    --------
    >>> import xarray as xr
    >>> provenance_label(xr.Dataset(attrs={"provenance": "simulated", "source": "a test"}))
    'SIMULATED data — a test'
    """
    return provenance_text(ds.attrs)


def provenance_text(attrs: Mapping[str, Any]) -> str:
    """:func:`provenance_label` from a data set's attributes (``provenance``, ``source``).

    Examples
    --------
    >>> provenance_text({"provenance": "reconstructed", "source": "Armstrong 1991, fig. 3"})
    'RECONSTRUCTED data (not measured) — reconstructed from Armstrong 1991, fig. 3'
    """
    prov = attrs.get("provenance", "?")
    source = attrs.get("source", "")
    if prov == "reconstructed":
        return f"RECONSTRUCTED data (not measured) — reconstructed from {source}"
    if prov == "simulated":
        return f"SIMULATED data — {source}"
    return f"measured data — {source}"
