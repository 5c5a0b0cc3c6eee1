"""What a study run keeps so that sizing never refits: the ``/sizing_basis`` node of ``results.nc``.

Sizing reads three nodes of a study's result tree (:mod:`bayesfric.report.results`):

``/weights``
    over ``(law, weighting)``: every weight the study computed (``"stacking LOO"``,
    ``"stacking <blocked label>"`` for every blocked scheme ...) and why a weighting left a law out;
``/diagnostics``
    over ``law``: the gate's verdict (``passed``, ``problems``), whether the evidence estimators
    agreed (shown, never a reason to leave a law out of sizing);
``/sizing_basis``
    built here (:func:`basis_node`): each law's fit file and evidence disagreement, its measured
    miss on every blocked scheme (:mod:`bayesfric.sizing.calibration`; ``miss_*`` over
    ``(law, scheme)``, ``miss_n`` −1 where none was measured), its extrapolation penalties
    (``penalty`` over ``(law, penalty_scheme)``) and the blocked schemes themselves (``axis``,
    ``direction`` and ``use_abs`` over ``scheme``).

The study run builds these nodes once from its results and answers its own sizing questions from
them in memory (:func:`sources` with the fits it holds); ``bayesfric size STUDY.toml`` reads the
same nodes back from ``results.nc`` (:func:`read_basis`). Which weights answer a question is
chosen per question from its direction (:mod:`bayesfric.sizing.basis`). The exclusion reason is
derived from the verdict's boolean (:func:`exclusion`), never parsed from text.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from bayesfric.sizing.basis import LOO, NEW_GROUP
from bayesfric.sizing.calibration import Miss, Scheme
from bayesfric.sizing.compute import LawSource
from bayesfric.sizing.points import SizingError
from bayesfric.sizing.single import read_fit

__all__ = ["NODES", "RESULTS", "schemes_of", "basis_node", "read_basis", "exclusion", "basis_schemes", "sources"]

#: The result tree's file in a report folder (:data:`bayesfric.report.results.RESULTS`).
RESULTS = "results.nc"
#: The result-tree nodes sizing reads.
NODES = ("weights", "diagnostics", "sizing_basis")
#: Nodes sizing reads where a tree has them: the laws' checks (residual structure: which group
#: columns a law is blind to, :mod:`bayesfric.sizing.newrun`).
OPTIONAL = ("checks",)
#: The fields of a measured miss (:class:`bayesfric.sizing.calibration.Miss`) besides its count.
MISS_FIELDS = ("rate", "beta", "se", "reach")


def schemes_of(study, data: xr.Dataset, blocked: Sequence[str]) -> list[Scheme]:
    """The study's blocked extrapolation schemes as sizing reads them (leave-future-out ones are
    not envelope extrapolations and are left out); ``|x|`` where the input has both signs, as
    :func:`bayesfric.compare.blocked_masks` blocks it. ``blocked`` are the schemes' labels, in the
    order of ``study.blocked``."""
    out = []
    for label, spec in zip(blocked, study.blocked, strict=True):
        if spec.future:
            continue
        values = data[spec.axis].values
        out.append(Scheme(label, spec.axis, spec.direction, bool((values < 0).any() and (values > 0).any())))
    return out


def basis_node(laws: Sequence[xr.Dataset], schemes: Sequence[Scheme], grouped: Sequence[str] = ()) -> xr.Dataset:
    """The ``/sizing_basis`` node from each law's result Dataset (after its weights,
    :mod:`bayesfric.study.lawresult`): fit files, evidence disagreement, misses on ``schemes``
    (:func:`schemes_of`), penalties, the blocked schemes and the leave-one-group-out labels
    (``grouped``, attr ``grouped``, one per line) whose stacking weights answer for a new group."""
    names = [str(w.attrs["law"]) for w in laws]
    labels = list(dict.fromkeys(str(k) for w in laws for k, done in zip(w["scheme"].values,
                                                                         w["penalty_computed"].values, strict=True)
                                if done))
    penalty = np.array([[float(w["penalty"].sel(scheme=k)) if k in w["scheme"].values and
                         bool(w["penalty_computed"].sel(scheme=k)) else math.nan for k in labels] for w in laws])
    node = xr.Dataset(
        {"fit": ("law", [str(w.attrs["fit_file"]) for w in laws]),
         "evidence_disagreement": ("law", [float(w["evidence_difference"]) for w in laws]),
         "penalty": (("law", "penalty_scheme"), penalty.reshape(len(laws), len(labels)))}
        | _miss_arrays(laws, schemes),
        coords={"law": names, "scheme": [s.label for s in schemes], "penalty_scheme": labels,
                "axis": ("scheme", [s.axis for s in schemes]),
                "direction": ("scheme", [s.direction for s in schemes]),
                "use_abs": ("scheme", [s.use_abs for s in schemes])},
        attrs={"description": "what sizing reads besides /weights and /diagnostics (bayesfric.sizing.store)",
               "grouped": "\n".join(grouped)})
    node["miss_n"].attrs["description"] = "held-out points of the blocked fold's miss; -1: no miss measured"
    node["penalty"].attrs.update(units="nats per held-out point")
    return node


def _miss_arrays(laws: Sequence[xr.Dataset], schemes: Sequence[Scheme]) -> dict[str, tuple]:
    shape = (len(laws), len(schemes))
    values = {k: np.full(shape, np.nan) for k in MISS_FIELDS}
    count = np.full(shape, -1, dtype=np.int64)
    for i, w in enumerate(laws):
        for j, scheme in enumerate(schemes):
            if scheme.label in w["miss_scheme"].values:
                at = w.sel(miss_scheme=scheme.label)
                for k in MISS_FIELDS:
                    values[k][i, j] = float(at[f"miss_{k}"])
                count[i, j] = int(at["miss_n"])
    dims = ("law", "scheme")
    return {f"miss_{k}": (dims, v) for k, v in values.items()} | {"miss_n": (dims, count)}


def read_basis(folder: Path) -> xr.DataTree:
    """The nodes sizing reads (:data:`NODES`), loaded from ``folder/results.nc``; a missing or
    foreign file, or one written before sizing read it, is a :class:`SizingError`."""
    path = Path(folder) / RESULTS
    if not path.is_file():
        raise SizingError("", f"{path}: missing (the report was written before sizing read it); run the study again")
    try:
        with xr.open_datatree(path, engine="h5netcdf") as tree:
            nodes = {name: tree[name].to_dataset().load() for name in NODES + OPTIONAL if name in tree.children}
    except (OSError, ValueError) as exc:
        raise SizingError("", f"{path}: unreadable ({exc}); run the study again") from None
    if not set(NODES) <= set(nodes):
        raise SizingError("", f"{path}: holds no sizing basis (written by an older bayesfric); run the study again")
    return xr.DataTree.from_dict(nodes)


def exclusion(passed: bool, problems: str = "") -> str | None:
    """Why sizing may not use a law's predictions (None: it may): its full fit failed the
    diagnostics gate (``problems``: the gate's problems, joined). Only a reason about its
    predictions counts: an unreliable *evidence* estimate removes a law from the evidence ranking
    and nothing else."""
    if passed:
        return None
    return "failed the diagnostics gate" + (f" ({problems})" if problems else "")


def basis_schemes(basis: xr.DataTree) -> list[Scheme]:
    """The blocked schemes of a sizing basis (:func:`schemes_of`)."""
    node = basis["sizing_basis"]
    return [Scheme(str(label), str(axis), str(direction), bool(use_abs)) for label, axis, direction, use_abs in
            zip(node["scheme"].values, node["axis"].values, node["direction"].values, node["use_abs"].values,
                strict=True)]


def _law_terms(basis: xr.DataTree, name: str, new_group: bool = True) -> tuple[dict, str, dict, dict]:
    """(stacking weights by basis key, weight note, misses, penalties) of one law; with
    ``new_group``, the first leave-one-group-out weighting also under :data:`NEW_GROUP`."""
    weights, notes = {}, []
    node = basis["weights"].to_dataset().sel(law=name)
    for key, value, excluded in zip(node["weighting"].values, node["weight"].values, node["excluded"].values,
                                    strict=True):
        key = str(key)
        if key.startswith("stacking ") and math.isfinite(float(value)):
            weights[LOO if key == "stacking LOO" else key.removeprefix("stacking ")] = float(value)
        if str(excluded):
            notes.append(f"{key}: {excluded}")
    grouped = [g for g in str(basis["sizing_basis"].attrs.get("grouped", "")).split("\n") if g in weights]
    if new_group and grouped:
        weights[NEW_GROUP] = weights[grouped[0]]
    row = basis["sizing_basis"].to_dataset().sel(law=name)
    misses = {str(label): Miss(str(label), *(float(row[f"miss_{k}"].values[j]) for k in ("rate", "beta", "se")),
                               int(row["miss_n"].values[j]), float(row["miss_reach"].values[j]))
              for j, label in enumerate(row["scheme"].values) if int(row["miss_n"].values[j]) >= 0}
    penalties = {str(k): float(v) for k, v in zip(row["penalty_scheme"].values, row["penalty"].values, strict=True)
                 if math.isfinite(float(v))}
    return weights, "; ".join(notes), misses, penalties


def _fit_of(basis: xr.DataTree, folder: Path, name: str) -> xr.DataTree:
    path = folder / str(basis["sizing_basis"]["fit"].sel(law=name).values)
    if not path.is_file() or path.resolve().parent != (folder / "fits").resolve():
        raise SizingError("", f"{path}: fit of {name} missing from the report; run the study again")
    try:
        return read_fit(path)
    except (OSError, ValueError) as exc:  # read_fit's UserError names the file
        raise SizingError("", f"{exc}; run the study again") from None


def _checks(basis: xr.DataTree, name: str) -> tuple:
    """The law's residual-structure checks, where the tree kept them (``/checks``)."""
    from bayesfric.compare.structure import DIM, checks_of

    if "checks" not in basis.children or DIM not in basis["checks"].dims:
        return ()
    node = basis["checks"].to_dataset()
    return checks_of(node.sel(law=name)) if name in node["law"].values else ()


def sources(basis: xr.DataTree, folder: Path, laws: Sequence[str] | None = None,
            fits: dict[str, xr.DataTree] | None = None, data_hash: str | None = None,
            selection: str | None = None) -> list[LawSource]:
    """The :class:`LawSource` of every law of the basis (in the order of ``laws`` when given).

    ``basis`` holds the nodes :data:`NODES` (a study's result tree or :func:`read_basis`). Fits
    come from ``fits`` (in memory, the runner) or from ``folder/fits/*.nc``.

    Raises
    ------
    SizingError
        A law of ``laws`` has no entry (the study changed since it ran), a fit file is missing or
        unreadable, or a fit was made from other data than ``data_hash`` or another row
        ``selection`` (the data's ``selection`` attr).
    """
    known = [str(n) for n in basis["sizing_basis"]["law"].values]
    names = list(laws) if laws is not None else known
    missing = [n for n in names if n not in known]
    if missing:
        raise SizingError("", f"{folder}: the report has no fit of {', '.join(missing)} (the study's laws changed "
                              "since it ran); run the study again")
    out = []
    diagnostics = basis["diagnostics"].to_dataset()
    for name in names:
        fit = fits[name] if fits is not None and name in fits else _fit_of(basis, folder, name)
        if data_hash and fit.attrs.get("data_hash") not in (None, "", data_hash):
            raise SizingError("", f"{folder}: the fit of {name} was made from other data (hash "
                                  f"{fit.attrs.get('data_hash')}, the study's data now {data_hash}); "
                                  "run the study again")
        if selection is not None and str(fit.attrs.get("data_selection", "")) != selection:
            raise SizingError("", f"{folder}: the fit of {name} was made from another row selection "
                                  f"({fit.attrs.get('data_selection') or 'all rows'}; the study now selects "
                                  f"{selection or 'all rows'}); run the study again")
        weights, notes, misses, penalties = _law_terms(basis, name)
        verdict = diagnostics.sel(law=name)
        excluded = exclusion(bool(verdict["passed"].values), str(verdict["problems"].values))
        out.append(LawSource(name, fit, weights, excluded, notes, misses, penalties, _checks(basis, name)))
    return out
