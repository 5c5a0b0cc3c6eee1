"""What the report reads from a study's result tree, taken out once (:mod:`bayesfric.study.tree`).

A :class:`TreeView` holds the law × metric table (``/scores`` as the tidy table of
:mod:`bayesfric.study.scores`), the ranking criteria, the per-law nodes and the root attrs; the
report's ranking, findings, checks table, law sections and figures read it and nothing else of
the run's results (the figures also take the data set and the full fits' predictive draws).
"""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from bayesfric.compare.pit import PitShape, pit_shape
from bayesfric.compare.structure import StructureCheck, checks_of
from bayesfric.laws.variants import law_of_fit
from bayesfric.study import scores as sc
from bayesfric.study.tree import data_attrs, weight_errors

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr

    from bayesfric.laws.base import Law

__all__ = ["TreeView"]


class TreeView:
    """A study's result tree, as the report reads it.

    Parameters
    ----------
    tree : xarray.DataTree
        The study's result tree (:func:`bayesfric.study.tree.study_tree`, or ``results.nc`` opened).

    Examples
    --------
    >>> from bayesfric.report.view import TreeView
    >>> TreeView  # doctest: +ELLIPSIS
    <class '...TreeView'>
    """

    def __init__(self, tree: xr.DataTree) -> None:
        self.tree = tree
        self.table: pd.DataFrame = sc.table_of(tree["scores"].to_dataset())
        self.crits: list[sc.Criterion] = sc.criteria_of(tree)
        self.laws: list[str] = [str(n) for n in tree["scores"]["law"].values]
        self.diag = tree["diagnostics"].to_dataset()
        self.checks = tree["checks"].to_dataset()
        self.pointwise = tree["pointwise"].to_dataset()
        schemes = self.pointwise["scheme"]
        self.blocked: list[str] = [str(s) for s, b in zip(schemes.values, schemes["blocked"].values, strict=True) if b]
        self.attrs: dict[str, Any] = dict(tree.attrs)
        self.weight_errors: list[tuple[str, str]] = weight_errors(tree)
        self.quick: dict[str, Any] | None = dict(tree["quick"].attrs) if "quick" in tree.children else None
        self._laws: dict[str, Law] = {}

    @classmethod
    def of(cls, tree: xr.DataTree | TreeView) -> TreeView:
        """``tree`` itself when it is a view already, else a view of it."""
        return tree if isinstance(tree, TreeView) else cls(tree)

    def law(self, name: str) -> xr.Dataset:
        """The law's ``/diagnostics``."""
        return self.diag.sel(law=name)

    def passed(self, name: str) -> bool:
        """The law's full fit passed the diagnostics gate."""
        return bool(self.law(name)["passed"])

    def gate(self, name: str) -> str:
        """The law's gate in one word: ``passed``, ``multimodal`` (chains in separate modes, used as
        their stacked combination: :mod:`bayesfric.inference.modes`), ``unidentified`` (chains that
        did not mix along parameters the data do not determine, agreeing on every row: pooled) or
        ``FAILED``."""
        law = self.law(name)
        if "multimodal" in law and bool(law["multimodal"]):
            return "multimodal"
        if "unidentified" in law and str(law["unidentified"].values):
            return "unidentified"
        return "passed" if bool(law["passed"]) else "FAILED"

    def flag(self, name: str, variable: str) -> Any:
        """One value of the law's ``/diagnostics`` or ``/checks`` (``variable``), as a Python scalar."""
        node = self.diag if variable in self.diag else self.checks
        return node[variable].sel(law=name).values.item()

    def fit(self, name: str) -> xr.DataTree:
        """The law's fit as the tree keeps it (``/fits/<law>``: posterior, sample stats, data, attrs)."""
        return self.tree[f"fits/{name}"]

    def law_object(self, name: str) -> Law:
        """The law of the fit, rebuilt once from the fit's record (:func:`bayesfric.laws.variants.law_of_fit`)."""
        if name not in self._laws:
            self._laws[name] = law_of_fit(self.fit(name).attrs)
        return self._laws[name]

    def heldout(self, scheme: str) -> np.ndarray | None:
        """The rows ``scheme`` holds out (None for a scheme the study did not run)."""
        if scheme not in self.pointwise["scheme"].values:
            return None
        return np.asarray(self.pointwise["heldout"].sel(scheme=scheme).values, dtype=bool)

    @property
    def blocked_axes(self) -> dict[str, str]:
        """Blocked scheme -> the input it blocks along."""
        schemes = self.pointwise["scheme"]
        return {str(s): str(a) for s, a, b in zip(schemes.values, schemes["axis"].values, schemes["blocked"].values,
                                                   strict=True) if b}

    def pit(self, name: str) -> tuple[np.ndarray, np.ndarray | None, PitShape | None]:
        """The law's LOO-PIT values as its checks read them, the ECDF band they were tested
        against (``(3, points)``: points, lower, upper; None when not stored) and their shape
        (:func:`bayesfric.compare.pit.pit_shape` of those values; None without values)."""
        c = self.checks.sel(law=name)
        pit = np.asarray(c["pit"].values, dtype=float)
        pit = pit[np.isfinite(pit)]
        band = np.asarray(c["pit_band"].values, dtype=float) if "pit_band" in c else np.zeros((3, 0))
        band = band[:, np.isfinite(band[0])]
        return pit, (band if band.shape[1] else None), (pit_shape(pit) if pit.size else None)

    def structure(self, name: str) -> tuple[StructureCheck, ...]:
        """The law's residual-structure tests (:mod:`bayesfric.compare.structure`; none in a tree
        made before they existed)."""
        return checks_of(self.checks.sel(law=name))

    @cached_property
    def data(self) -> dict[str, str]:
        """The data set's attributes the tree keeps (:func:`bayesfric.study.tree.data_attrs`)."""
        return data_attrs(self.tree)

    @property
    def has_loo(self) -> bool:
        """The study scored PSIS-LOO (a ranking criterion)."""
        return any(c.metric == "elpd_loo" for c in self.crits)
