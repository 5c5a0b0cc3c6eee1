"""A study's results as one ``xarray.DataTree``, built once after the weights and the score table.

Sizing, the claims and the report read this tree (the report adds its own nodes to it,
:mod:`bayesfric.report.results`); it is saved as ``results.nc`` beside the report and opens with
``xarray.open_datatree``. Nodes:

``/``
    attrs: study, data set, data hash, bayesfric version, CV schemes, blocked schemes, ``quick``,
    ``ranking_changed`` (the LOO ranking changes under power-scaled priors), what the report shows
    of the study (``title``, ``question``, ``study_file``, ``include_failed``, ``failed_fits``,
    ``noise``, ``sampler``) and of the data (``n_obs``, ``data_<attr>`` for :data:`DATA_ATTRS`);
    the finished run adds its ``seconds`` and its units' cost (:func:`run_attrs`).
``/scores``
    over ``(law, criterion)``: ``estimate``, ``se``, ``reliable``, ``reason``; a criterion is a
    metric and its scheme (``elpd_loo``, ``elpd_cv[<scheme>]``, ``penalty[<scheme>]``,
    ``log_evidence[<estimator>]``, ``weight[<weighting>]``), with ``metric`` and ``scheme``
    coordinates; ``computed`` is False where the study did not score the law under the criterion
    (:func:`bayesfric.study.scores.table_of` gives back the tidy table).
``/criteria``
    the ranking criteria in display order over ``rank`` (``metric``, ``scheme``, ``kind``); the
    first ranks the laws.
``/pointwise``
    ``elpd`` over ``(criterion, law, obs)``: PSIS-LOO and each CV scheme's pointwise elpd (NaN
    where a point is not held out or the stage did not run); ``heldout`` over ``(scheme, obs)``;
    ``pareto_k`` over ``(law, obs)`` (NaN where LOO did not run or was subsampled); a scheme's
    ``blocked`` flag and, for a blocked one, the input ``axis`` it blocks along.
``/weights``
    over ``(law, weighting)``: ``weight`` and ``excluded`` (why the weighting left the law out);
    ``not_computed`` over ``failed_weighting``: why a weighting was not computed at all.
``/diagnostics``, ``/checks``
    over ``law``: the gate's verdict (``passed``, ``problems``, ``verdict`` as the report writes
    it, ``multimodal`` and ``modes``: chains in separate modes, stacked), the law's ``flags`` (one
    line each), ``p_loo``, ``n_high_k``, ``cv_reliable`` (every fold passed), ``seconds`` and
    ``timing`` over ``(law, stage)``; the checks unit's LOO-PIT (``pit`` over ``(law, pit_row)``,
    its ECDF band ``pit_band``, p-value, band coverage ``ci_prob``, direction), prior checks
    (``checked``: the unit ran) and the residual-structure tests (``structure_*`` over ``(law,
    structure_column)``, :mod:`bayesfric.compare.structure`).
``/modes``
    multimodal fits' modes (:func:`bayesfric.study.lawresult.mode_node`: weight, chains, ranges).
``/quick``
    only in a ``--quick`` run: the capped sampler settings and K-fold's folds asked and used.
``/identifiability``
    with a stateful law: each requirement its parameters have of the data, measured before
    fitting, over ``requirement`` (``law``, ``params``, ``needs``, ``status``, ``measured``,
    ``companion``: the reduced entry the study added; :mod:`bayesfric.identifiability`).
``/sizing_basis``
    what sizing reads besides ``/weights`` and ``/diagnostics`` (:mod:`bayesfric.sizing.store`).
``/ranking_sensitivity``
    with two or more ranked fits: ``elpd``, ``max_pareto_k`` and ``place`` over ``(alpha, law)``,
    the LOO ranking under every prior power-scaled by α (attribute ``changed``).
``/fits/<law>``
    each law's posterior, sample statistics, observed and constant data, with the fit's
    provenance attrs (its program is rebuilt from them, :func:`bayesfric.model.program_of_fit`)
    and ``fit_file``; the pointwise log-likelihood and predictive draws stay in the full fit
    ``fits/<law>.nc``.

The tree is built from each law's result Dataset (:mod:`bayesfric.study.lawresult`, itself
flattened from the units' Datasets) and the study's plan; the report's content model and figures
(ranking, findings, checks, law sections, data lines, footer) read this tree alone, with the
claims' results and the sizing result (:mod:`bayesfric.report.content`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from bayesfric._version import __version__
from bayesfric.compare.checks import PARETO_K_RELIABLE, RankingSensitivity
from bayesfric.compare.structure import DIM, stack_structure
from bayesfric.sizing.store import basis_node, schemes_of
from bayesfric.study.lawresult import mode_node
from bayesfric.study.scores import criteria, score_table

if TYPE_CHECKING:
    from bayesfric.study.executor import UnitSeconds
    from bayesfric.study.plan import QuickRun
    from bayesfric.study.spec import Study

__all__ = ["study_tree", "criterion_name", "FIT_GROUPS", "LAW_NODES", "DATA_ATTRS", "data_attrs",
           "run_attrs", "weight_errors", "QUICK_SETTINGS",
           "sensitivity_of"]

#: Groups of a fit copied into ``/fits/<law>`` (the per-row groups stay in the fit file).
FIT_GROUPS = ("posterior", "sample_stats", "observed_data", "constant_data")
#: The data set's attributes the report shows, copied into the root attrs as ``data_<name>``.
DATA_ATTRS = ("name", "title", "provenance", "source", "selection")
#: The sampler settings a ``--quick`` run reports in ``/quick``.
QUICK_SETTINGS = ("draws", "tune", "chains", "thin")
#: The per-law nodes besides the scores and the fits.
LAW_NODES = ("weights", "diagnostics", "checks", "sizing_basis")


def criterion_name(metric: str, scheme: str) -> str:
    """The ``criterion`` coordinate of ``metric`` under ``scheme`` (``elpd_cv[<scheme>]``)."""
    return metric if not scheme else f"{metric}[{scheme}]"


def _merged(sequences: list[list[str]]) -> list[str]:
    """One order of the criteria that keeps each law's own order of its rows (a new criterion goes
    right after the one before it in that law's rows), so :func:`bayesfric.study.scores.table_of`
    gives each law's rows back in the order its scorers wrote them."""
    out: list[str] = []
    for names in sequences:
        before = -1
        for name in names:
            if name not in out:
                out.insert(before + 1, name)
            before = out.index(name)
    return out


def _criteria(crits: list) -> xr.Dataset:
    """``/criteria``: the study's ranking criteria in display order (:func:`bayesfric.study.scores.criteria`)."""
    return xr.Dataset({"metric": ("rank", [c.metric for c in crits]), "scheme": ("rank", [c.scheme for c in crits]),
                       "kind": ("rank", [c.kind for c in crits])}, coords={"rank": np.arange(len(crits))},
                      attrs={"description": "ranking criteria in display order: the first ranks the laws"})


def _scores(table, laws: list[str]) -> xr.Dataset:
    pairs = list(zip(table["metric"], table["scheme"], strict=True))
    crit = _merged([[criterion_name(m, s) for m, s in zip(rows["metric"], rows["scheme"], strict=True)]
                    for _, rows in table.groupby("law", sort=False)])
    meta = {criterion_name(m, s): (m, s) for m, s in pairs}
    shape = (len(laws), len(crit))
    est, se = np.full(shape, np.nan), np.full(shape, np.nan)
    reliable, computed = np.zeros(shape, dtype=bool), np.zeros(shape, dtype=bool)
    reason = np.full(shape, "", dtype=object)
    li, ci = {n: i for i, n in enumerate(laws)}, {c: j for j, c in enumerate(crit)}
    for row in table.itertuples(index=False):
        i, j = li[row.law], ci[criterion_name(row.metric, row.scheme)]
        est[i, j], se[i, j] = row.estimate, row.se
        reliable[i, j], reason[i, j], computed[i, j] = bool(row.reliable), str(row.reason), True
    dims = ("law", "criterion")
    node = xr.Dataset(
        {"estimate": (dims, est), "se": (dims, se), "reliable": (dims, reliable),
         "reason": (dims, reason.astype(str)), "computed": (dims, computed)},
        coords={"law": laws, "criterion": crit, "metric": ("criterion", [meta[c][0] for c in crit]),
                "scheme": ("criterion", [meta[c][1] for c in crit])},
    )
    node["computed"].attrs["description"] = "the study scored the law under the criterion (a row of scores.csv)"
    return node


def _pointwise(laws: Sequence[xr.Dataset], n: int, schemes: Sequence[tuple], axes: dict[str, str]) -> xr.Dataset:
    """``/pointwise`` from each law's results; ``schemes`` are the study's (label, folds, kind) and
    ``axes`` the input each blocked scheme blocks along."""
    names = [_name(w) for w in laws]
    labels = [s[0] for s in schemes]
    crit = ["elpd_loo"] + [criterion_name("elpd_cv", s) for s in labels]
    elpd = np.full((len(crit), len(laws), n), np.nan)
    pareto_k = np.full((len(laws), n), np.nan)
    scored = np.zeros((len(laws), n), dtype=bool)  # rows PSIS-LOO scored exactly (a subsample's rows)
    for i, w in enumerate(laws):
        if bool(w["loo_computed"]):
            elpd[0, i] = w["elpd_loo_i"].values
            pareto_k[i] = w["pareto_k"].values
            scored[i] = w["loo_scored"].values
        for j, scheme in enumerate(labels, start=1):
            if scheme in w["scheme"].values:
                elpd[j, i] = w["cv_elpd_i"].sel(scheme=scheme).values
    heldout = np.array([s[1].heldout.any(axis=0) for s in schemes], dtype=bool).reshape(len(schemes), n)
    node = xr.Dataset({"elpd": (("criterion", "law", "obs"), elpd), "heldout": (("scheme", "obs"), heldout),
                       "pareto_k": (("law", "obs"), pareto_k), "loo_scored": (("law", "obs"), scored)},
                      coords={"criterion": crit, "law": names, "scheme": labels, "obs": np.arange(n),
                              "blocked": ("scheme", [s[2] == "blocked" for s in schemes]),
                              "axis": ("scheme", [axes.get(s[0], "") for s in schemes])})
    node["loo_scored"].attrs["description"] = "rows PSIS-LOO scored exactly (all but a subsample's others)"
    return node


def _weights(laws: Sequence[xr.Dataset], errors: Sequence[tuple[str, str]]) -> xr.Dataset:
    names = list(dict.fromkeys(str(k) for w in laws for k in w["weighting"].values))
    value = np.full((len(laws), len(names)), np.nan)
    excluded = np.full((len(laws), len(names)), "", dtype=object)
    for i, w in enumerate(laws):
        for k, v, why in zip(w["weighting"].values, w["weight"].values, w["weight_excluded"].values, strict=True):
            value[i, names.index(str(k))], excluded[i, names.index(str(k))] = v, str(why)
    dims = ("law", "weighting")
    node = xr.Dataset({"weight": (dims, value), "excluded": (dims, excluded.astype(str)),
                       "not_computed": ("failed_weighting", np.array([why for _, why in errors],
                                                                     dtype=object).astype(str))},
                      coords={"law": [_name(w) for w in laws], "weighting": names,
                              "failed_weighting": np.array([label for label, _ in errors], dtype=str)})
    node["not_computed"].attrs["description"] = "why a weighting was not computed at all (none when all were)"
    return node


def weight_errors(tree: xr.DataTree) -> list[tuple[str, str]]:
    """The weightings a study could not compute, and why (``/weights`` ``not_computed``)."""
    node = tree["weights"]
    if "not_computed" not in node:
        return []
    return [(str(k), str(v)) for k, v in zip(node["failed_weighting"].values, node["not_computed"].values,
                                             strict=True)]


#: ``/diagnostics`` variables: copied from each law's result (:mod:`bayesfric.study.lawresult`).
DIAGNOSTICS = ("passed", "problems", "evidence_agree", "cv_reliable", "skipped", "seconds", "verdict", "flags",
               "multimodal", "modes", "unidentified",
               "p_loo", "n_high_k", "rhat_max", "ess_bulk_min", "n_params", "evidence_compared",
               "evidence_disagreement", "pareto_k_max", "loo_rows_scored", "loo_rows", "loo_subsampling_se",
               "loo_subsampled", "group_coverage_50", "group_coverage_90")
#: ``/checks`` variables besides the LOO-PIT values and band.
CHECKS = ("prior_implausible", "loo_pit_pvalue", "loo_pit_ok", "loo_pit_direction", "psense", "ci_prob", "checked")


def _name(w: xr.Dataset) -> str:
    return str(w.attrs["law"])


def _per_law(laws: Sequence[xr.Dataset], names: Sequence[str]) -> xr.Dataset:
    """The 0-d variables ``names`` of every law's result, over ``law``."""
    def value(w, k):
        return abs(float(w["evidence_difference"])) if k == "evidence_disagreement" else w[k].values.item()

    return xr.Dataset({k: ("law", [value(w, k) for w in laws]) for k in names},
                      coords={"law": [_name(w) for w in laws]})


def _padded(laws: Sequence[xr.Dataset], var: str, dim: str, shape: tuple[int, ...] = ()) -> np.ndarray:
    """``var`` of every law NaN-padded along its last dimension ``dim`` (empty where a law has none)."""
    arrays = [np.asarray(w[var].values, dtype=float) if var in w else np.zeros((*shape, 0)) for w in laws]
    width = max((a.shape[-1] for a in arrays), default=0)
    pad = [np.pad(a, [(0, 0)] * (a.ndim - 1) + [(0, width - a.shape[-1])], constant_values=math.nan) for a in arrays]
    return np.array(pad).reshape(len(laws), *shape, width)


def _diagnostics(laws: Sequence[xr.Dataset]) -> xr.Dataset:
    diag = _per_law(laws, DIAGNOSTICS)
    diag["flags"].attrs["description"] = "one line per problem found in the law's results"
    diag["n_high_k"].attrs["description"] = "PSIS-LOO points above the Pareto-k threshold; -1: no LOO"
    stages = list(dict.fromkeys(str(k) for w in laws for k in w["stage"].values))
    diag["timing"] = (("law", "stage"), np.array([[float(w["timing"].sel(stage=k)) if k in w["stage"].values
                                                   else math.nan for k in stages] for w in laws])
                      .reshape(len(laws), len(stages)))
    diag = diag.assign_coords(stage=stages)
    diag["timing"].attrs.update(units="s", description="wall seconds per stage computed in this run (NaN: reused)")
    return diag


def _checks(laws: Sequence[xr.Dataset]) -> xr.Dataset:
    chk = _per_law(laws, CHECKS)
    chk["pit"] = (("law", "pit_row"), _padded(laws, "pit", "pit_row"))
    chk["pit"].attrs["description"] = "LOO-PIT values of the rows the check read (NaN-padded)"
    chk["pit_band"] = (("law", "band_edge", "band_point"), _padded(laws, "pit_band", "band_point", (3,)))
    chk = chk.assign_coords(band_edge=["point", "lower", "upper"])
    chk["pit_band"].attrs["description"] = "the LOO-PIT ECDF's simultaneous band the check tested (NaN-padded)"
    if any(DIM in w.dims for w in laws):  # residual-structure tests over (law, structure_column), padded
        chk = chk.merge(stack_structure([(_name(w), w) for w in laws]))
    return chk


def _fits(laws: Sequence[xr.Dataset], fits: Mapping[str, xr.DataTree]) -> dict[str, xr.Dataset]:
    nodes = {}
    for w in laws:
        name, fit = _name(w), fits[_name(w)]
        attrs = {k: v for k, v in fit.attrs.items() if _attr_ok(v)} | {"fit_file": w.attrs["fit_file"]}
        nodes[f"fits/{name}"] = xr.Dataset(attrs=attrs)
        for group in FIT_GROUPS:
            if group in fit.children:
                nodes[f"fits/{name}/{group}"] = fit[group].to_dataset()
    return nodes


def _attr_ok(value) -> bool:
    return isinstance(value, str | int | float | np.number) and not isinstance(value, bool)


def _root_attrs(st: Study, data: xr.Dataset, schemes: Sequence[tuple], quick: bool,
                sensitivity: RankingSensitivity | None) -> dict:
    noise = st.noise.kind + (f", partial-pooled offsets per {st.noise.group}" if st.noise.group else "")
    return {"study": st.name, "dataset": str(data.attrs.get("name", "")),
            "data_hash": str(data.attrs.get("data_hash", "")), "bayesfric_version": __version__,
            "schemes": "; ".join(s[0] for s in schemes),
            "blocked_schemes": "; ".join(s[0] for s in schemes if s[2] == "blocked"), "quick": int(quick),
            "ranking_changed": int(sensitivity is not None and sensitivity.changed),
            "title": st.title, "question": st.question, "study_file": str(st.path),
            "study_file_exists": int(st.path.is_file()), "include_failed": int(st.include_failed),
            "failed_fits": st.failed_fits, "noise": noise, "sampler": str(st.sampler), "n_obs": int(data.sizes["obs"])
            } | {f"data_{k}": str(v) for k in DATA_ATTRS if (v := data.attrs.get(k)) is not None}


def _sensitivity(sens: RankingSensitivity | None) -> dict[str, xr.Dataset]:
    """``/ranking_sensitivity``: elpd_LOO, largest Pareto k̂ and place of each ranked law at each
    prior power α (:func:`bayesfric.compare.ranking_sensitivity`); none with fewer than two fits."""
    if sens is None:
        return {}
    alphas, laws = list(sens.ranking), list(sens.ranking[1.0])
    dims = ("alpha", "law")

    def grid(by_alpha) -> np.ndarray:
        return np.array([[float(by_alpha.get(a, {}).get(n, math.nan)) for n in laws] for a in alphas])

    place = np.array([[sens.ranking[a].index(n) + 1 if n in sens.ranking[a] else -1 for n in laws] for a in alphas])
    node = xr.Dataset({"elpd": (dims, grid(sens.elpd)), "max_pareto_k": (dims, grid(sens.max_pareto_k)),
                       "place": (dims, place)}, coords={"alpha": alphas, "law": laws},
                      attrs={"changed": int(sens.changed), "pareto_k_reliable": PARETO_K_RELIABLE,
                             "description": "PSIS-LOO under every prior power-scaled by alpha (no refits)"})
    node["place"].attrs["description"] = "1: best elpd_loo at this alpha"
    return {"ranking_sensitivity": node}


def sensitivity_of(tree: xr.DataTree) -> RankingSensitivity | None:
    """The ranking's prior sensitivity back from ``/ranking_sensitivity`` (None when the study
    did not compute it: fewer than two fits)."""
    if "ranking_sensitivity" not in tree.children:
        return None
    node = tree["ranking_sensitivity"]
    ranked = {str(n) for n in node["law"].values}  # the dicts in the study's order of the laws, as computed
    laws = [n for n in map(str, tree["scores"]["law"].values) if n in ranked]
    node = node.sel(law=laws)
    elpd, max_k, ranking = {}, {}, {}
    for a in node["alpha"].values:
        at = node.sel(alpha=a)
        elpd[float(a)] = dict(zip(laws, map(float, at["elpd"].values), strict=True))
        max_k[float(a)] = dict(zip(laws, map(float, at["max_pareto_k"].values), strict=True))
        place = {n: int(p) for n, p in zip(laws, at["place"].values, strict=True) if p > 0}
        ranking[float(a)] = sorted(place, key=place.__getitem__)
    return RankingSensitivity(elpd, ranking, max_k, bool(node.attrs["changed"]))


def _quick(quick: QuickRun | None) -> dict[str, xr.Dataset]:
    """``/quick``: the settings a ``--quick`` run capped (none otherwise)."""
    if quick is None:
        return {}
    asked, used = quick.kfold
    attrs = {k: v for k, v in quick.config.settings().items() if k in QUICK_SETTINGS}
    return {"quick": xr.Dataset(attrs=attrs | {"kfold_asked": int(asked), "kfold_used": int(used)})}


def data_attrs(tree: xr.DataTree) -> dict[str, str]:
    """The data set's attributes the tree keeps (:data:`DATA_ATTRS`, ``data_hash``) under their own names."""
    out = {k: str(tree.attrs[f"data_{k}"]) for k in DATA_ATTRS if f"data_{k}" in tree.attrs}
    return out | {"data_hash": str(tree.attrs.get("data_hash", ""))}


def run_attrs(seconds: float, unit_seconds: UnitSeconds | None) -> dict[str, float | int]:
    """Root attrs of a finished run: its wall ``seconds`` and, when known, what its units cost
    (``units_computed_s``, ``units_reused``, ``units_saved_s``, ``units_unknown``)."""
    attrs: dict[str, float | int] = {"seconds": float(seconds)}
    if unit_seconds is not None:
        attrs |= {"units_computed_s": float(unit_seconds.computed), "units_reused": int(unit_seconds.reused),
                  "units_saved_s": float(unit_seconds.saved), "units_unknown": int(unit_seconds.unknown)}
    return attrs


def study_tree(study: Study, data: xr.Dataset, schemes: Sequence[tuple], laws: Sequence[xr.Dataset],
               fits: Mapping[str, xr.DataTree], *, sensitivity: RankingSensitivity | None = None,
               weight_errors: Sequence[tuple[str, str]] = (), quick: QuickRun | None = None,
               identifiability: xr.Dataset | None = None) -> xr.DataTree:
    """The study's results as one DataTree (layout in the module docstring).

    Parameters
    ----------
    study : Study
        The study as run.
    data : xarray.Dataset
        Its selected data.
    schemes : sequence of tuple
        Its cross-validation schemes, ``(label, folds, kind)`` in display order
        (:func:`bayesfric.study.plan.cv_schemes`).
    laws : sequence of xarray.Dataset
        Each law's results after its weights (:func:`bayesfric.study.lawresult.law_result`).
    fits : mapping
        Law -> its full fit.
    sensitivity : RankingSensitivity, optional
        The LOO ranking under power-scaled priors (two or more fits).
    weight_errors : sequence of (str, str)
        The weightings not computed, and why.
    quick : QuickRun, optional
        The capped settings of a ``--quick`` run.
    identifiability : xarray.Dataset, optional
        The laws' identifiability checks (:func:`bayesfric.identifiability.checks_dataset`);
        a node only where some law has one.

    Returns
    -------
    xarray.DataTree
        ``/``, ``/scores``, ``/criteria``, ``/pointwise``, :data:`LAW_NODES`, ``/ranking_sensitivity``,
        ``/quick`` and ``/fits/<law>``.
    """
    blocked = [s[0] for s in schemes if s[2] == "blocked"]
    table = score_table(laws, blocked, study.include_failed)
    axes = {label: b.axis for label, b in zip(blocked, study.blocked, strict=False)}
    nodes = {"/": xr.Dataset(attrs=_root_attrs(study, data, schemes, quick is not None, sensitivity)),
             "scores": _scores(table, [_name(w) for w in laws]),
             "criteria": _criteria(criteria(study, [s[0] for s in schemes], blocked, laws)),
             "pointwise": _pointwise(laws, int(data.sizes["obs"]), schemes, axes),
             "weights": _weights(laws, weight_errors), "diagnostics": _diagnostics(laws), "checks": _checks(laws),
             "sizing_basis": basis_node(laws, schemes_of(study, data, blocked),
                                        grouped=[s[0] for s in schemes if s[2] == "grouped"])}
    nodes |= _sensitivity(sensitivity) | _quick(quick) | _fits(laws, fits) | mode_node(laws)
    if identifiability is not None and identifiability.sizes.get("requirement", 0):
        nodes["identifiability"] = identifiability
    return xr.DataTree.from_dict(nodes)
