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
    it), the law's ``flags`` (one line each), ``p_loo``, ``n_high_k``, ``cv_reliable`` (every fold
    passed), ``seconds`` and ``timing`` over ``(law, stage)``; the checks unit's LOO-PIT (``pit``
    over ``(law, pit_row)``, its ECDF band ``pit_band``, p-value, band coverage ``ci_prob``,
    direction) and prior checks
    (``checked``: the unit ran).
``/quick``
    only in a ``--quick`` run: the capped sampler settings and K-fold's folds asked and used.
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

The report's content model (ranking, findings, checks, law sections, data lines, footer) reads
this tree alone, with the claims' results and the sizing result (:mod:`bayesfric.report.content`).
What is not yet true (issue 31 item 1): the tree is built from the in-memory
:class:`~bayesfric.study.outcome.StudyOutcome`, not by the scorers themselves, and the report's
figures are still drawn from that outcome.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from bayesfric._version import __version__
from bayesfric.compare.checks import PARETO_K_RELIABLE, RankingSensitivity
from bayesfric.sizing.store import basis_node
from bayesfric.study.scores import criteria

if TYPE_CHECKING:
    from bayesfric.study.outcome import StudyOutcome, UnitSeconds

__all__ = ["study_tree", "law_nodes", "criterion_name", "FIT_GROUPS", "LAW_NODES", "DATA_ATTRS", "data_attrs",
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


def _criteria(outcome: StudyOutcome) -> xr.Dataset:
    """``/criteria``: the study's ranking criteria in display order (:func:`bayesfric.study.scores.criteria`)."""
    crits = criteria(outcome)
    return xr.Dataset({"metric": ("rank", [c.metric for c in crits]), "scheme": ("rank", [c.scheme for c in crits]),
                       "kind": ("rank", [c.kind for c in crits])}, coords={"rank": np.arange(len(crits))},
                      attrs={"description": "ranking criteria in display order: the first ranks the laws"})


def _scores(outcome: StudyOutcome) -> xr.Dataset:
    table = outcome.table
    laws = [w.name for w in outcome.laws]
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


def _pointwise(outcome: StudyOutcome) -> xr.Dataset:
    n = int(outcome.data.sizes["obs"])
    laws = [w.name for w in outcome.laws]
    crit = ["elpd_loo"] + [criterion_name("elpd_cv", s) for s in outcome.schemes]
    elpd = np.full((len(crit), len(laws), n), np.nan)
    pareto_k = np.full((len(laws), n), np.nan)
    for i, w in enumerate(outcome.laws):
        if w.loo is not None:
            elpd[0, i] = np.asarray(w.loo.elpd_i, dtype=float)
            if np.size(w.loo.pareto_k) == n:  # every row scored (a subsampled LOO has k̂ on its subsample only)
                pareto_k[i] = np.asarray(w.loo.pareto_k, dtype=float)
        for j, scheme in enumerate(outcome.schemes, start=1):
            cv = w.cv.get(scheme)
            if cv is not None:
                elpd[j, i] = np.asarray(cv.elpd_i, dtype=float)
    scored = np.zeros((len(laws), n), dtype=bool)  # rows PSIS-LOO scored exactly (a subsample's rows)
    for i, w in enumerate(outcome.laws):
        if w.loo is not None:
            scored[i] = True if w.loo.subsample is None else np.isin(np.arange(n), w.loo.subsample.rows)
    schemes = list(outcome.heldout)
    axes = {label: b.axis for label, b in zip(outcome.blocked, outcome.study.blocked, strict=False)}
    heldout = np.array([np.asarray(outcome.heldout[s], dtype=bool) for s in schemes]).reshape(len(schemes), n)
    node = xr.Dataset({"elpd": (("criterion", "law", "obs"), elpd), "heldout": (("scheme", "obs"), heldout),
                       "pareto_k": (("law", "obs"), pareto_k), "loo_scored": (("law", "obs"), scored)},
                      coords={"criterion": crit, "law": laws, "scheme": schemes, "obs": np.arange(n),
                              "blocked": ("scheme", [s in outcome.blocked for s in schemes]),
                              "axis": ("scheme", [axes.get(s, "") for s in schemes])})
    node["loo_scored"].attrs["description"] = "rows PSIS-LOO scored exactly (all but a subsample's others)"
    return node


def _weights(outcome: StudyOutcome) -> xr.Dataset:
    laws = [w.name for w in outcome.laws]
    names = list(dict.fromkeys(k for w in outcome.laws for k in w.weights))
    value = np.full((len(laws), len(names)), np.nan)
    excluded = np.full((len(laws), len(names)), "", dtype=object)
    for i, w in enumerate(outcome.laws):
        for j, k in enumerate(names):
            if k in w.weights:
                value[i, j], excluded[i, j] = w.weights[k].value, w.weights[k].excluded
    dims = ("law", "weighting")
    failed = [label for label, _ in outcome.weight_errors]
    node = xr.Dataset({"weight": (dims, value), "excluded": (dims, excluded.astype(str)),
                       "not_computed": ("failed_weighting", np.array([why for _, why in outcome.weight_errors],
                                                                     dtype=object).astype(str))},
                      coords={"law": laws, "weighting": names, "failed_weighting": np.array(failed, dtype=str)})
    node["not_computed"].attrs["description"] = "why a weighting was not computed at all (none when all were)"
    return node


def weight_errors(tree: xr.DataTree) -> list[tuple[str, str]]:
    """The weightings a study could not compute, and why (``/weights`` ``not_computed``)."""
    node = tree["weights"]
    if "not_computed" not in node:
        return []
    return [(str(k), str(v)) for k, v in zip(node["failed_weighting"].values, node["not_computed"].values,
                                             strict=True)]


def _diagnostics(outcome: StudyOutcome) -> xr.Dataset:
    laws = [w.name for w in outcome.laws]
    diag = xr.Dataset({
        "passed": ("law", [bool(w.verdict.passed) for w in outcome.laws]),
        "problems": ("law", ["; ".join(w.verdict.problems) for w in outcome.laws]),
        "evidence_agree": ("law", [bool(w.evidence_agree) for w in outcome.laws]),
        "cv_reliable": ("law", [bool(w.cv_reliable) for w in outcome.laws]),
        "skipped": ("law", [", ".join(w.skipped) for w in outcome.laws]),
        "seconds": ("law", [float(w.seconds) for w in outcome.laws]),
        "verdict": ("law", [str(w.verdict) for w in outcome.laws]),
        "flags": ("law", ["\n".join(w.flags) for w in outcome.laws]),
        "p_loo": ("law", [float(w.loo.p_loo) if w.loo is not None else math.nan for w in outcome.laws]),
        "n_high_k": ("law", [int(w.loo.n_high_k) if w.loo is not None else -1 for w in outcome.laws]),
        "rhat_max": ("law", [float(w.verdict.rhat_max) for w in outcome.laws]),
        "ess_bulk_min": ("law", [float(w.verdict.ess_bulk_min) for w in outcome.laws]),
        "n_params": ("law", [sum(max(1, math.prod(p.shape)) for p in w.law.params.values()) for w in outcome.laws]),
        "evidence_compared": ("law", [w.agreement is not None for w in outcome.laws]),
        "evidence_disagreement": ("law", [abs(w.agreement.difference) if w.agreement is not None else math.nan
                                          for w in outcome.laws]),
    } | _loo_fields(outcome.laws), coords={"law": laws})
    diag["flags"].attrs["description"] = "one line per problem found in the law's results (LawOutcome.flags)"
    diag["n_high_k"].attrs["description"] = "PSIS-LOO points above the Pareto-k threshold; -1: no LOO"
    stages = list(dict.fromkeys(k for w in outcome.laws for k in w.timings))
    diag["timing"] = (("law", "stage"), np.array([[float(w.timings.get(k, math.nan)) for k in stages]
                                                  for w in outcome.laws]).reshape(len(laws), len(stages)))
    diag = diag.assign_coords(stage=stages)
    diag["timing"].attrs.update(units="s", description="wall seconds per stage computed in this run (NaN: reused)")
    return diag


def _loo_fields(laws: list) -> dict[str, tuple]:
    """Per law: the largest Pareto k̂ of its PSIS-LOO, and where LOO was subsampled, how."""
    def k_max(loo) -> float:
        k = np.asarray(loo.pareto_k, dtype=float) if loo is not None else np.zeros(0)
        return float(np.nanmax(k)) if np.isfinite(k).any() else math.nan

    subs = [w.loo.subsample if w.loo is not None else None for w in laws]
    return {
        "pareto_k_max": ("law", [k_max(w.loo) for w in laws]),
        "loo_rows_scored": ("law", [int(s.size) if s is not None else -1 for s in subs]),
        "loo_rows": ("law", [int(s.n_rows) if s is not None else -1 for s in subs]),
        "loo_subsampling_se": ("law", [float(w.loo.subsampling_se) if s is not None else math.nan
                                       for w, s in zip(laws, subs, strict=True)]),
        "loo_subsampled": ("law", [w.loo.subsampled if s is not None else "" for w, s in zip(laws, subs, strict=True)]),
    }


def _checks(outcome: StudyOutcome) -> xr.Dataset:
    checks = [w.checks for w in outcome.laws]
    nan = math.nan
    chk = xr.Dataset({
        "prior_implausible": ("law", [c.prior_implausible if c else nan for c in checks]),
        "loo_pit_pvalue": ("law", [c.loo_pit_pvalue if c else nan for c in checks]),
        "loo_pit_ok": ("law", [bool(c.loo_pit_ok) if c else True for c in checks]),
        "loo_pit_direction": ("law", [c.pit_shape.label if c and c.pit_shape is not None else "" for c in checks]),
        "psense": ("law", [", ".join(c.psense) if c else "" for c in checks]),
        "ci_prob": ("law", [c.ci_prob if c else nan for c in checks]),
        "checked": ("law", [c is not None for c in checks]),
    }, coords={"law": [w.name for w in outcome.laws]})
    pits = [np.asarray(c.pit, dtype=float).ravel() if c is not None and c.pit is not None else np.zeros(0)
            for c in checks]
    width = max((len(p) for p in pits), default=0)
    chk["pit"] = (("law", "pit_row"), np.array([np.pad(p, (0, width - len(p)), constant_values=nan) for p in pits])
                  .reshape(len(checks), width))
    chk["pit"].attrs["description"] = "LOO-PIT values of the rows the check read (NaN-padded)"
    bands = [np.asarray(c.pit_band, dtype=float).reshape(3, -1) if c is not None and c.pit_band is not None
             else np.zeros((3, 0)) for c in checks]
    width = max((b.shape[1] for b in bands), default=0)
    chk["pit_band"] = (("law", "band_edge", "band_point"),
                       np.array([np.pad(b, ((0, 0), (0, width - b.shape[1])), constant_values=nan) for b in bands])
                       .reshape(len(checks), 3, width))
    chk = chk.assign_coords(band_edge=["point", "lower", "upper"])
    chk["pit_band"].attrs["description"] = "the LOO-PIT ECDF's simultaneous band the check tested (NaN-padded)"
    return chk


def law_nodes(outcome: StudyOutcome) -> dict[str, xr.Dataset]:
    """The per-law nodes ``/weights``, ``/diagnostics``, ``/checks`` and ``/sizing_basis``
    (:func:`bayesfric.sizing.store.basis_node`) of a study's outcome after its weights."""
    return {"weights": _weights(outcome), "diagnostics": _diagnostics(outcome), "checks": _checks(outcome),
            "sizing_basis": basis_node(outcome)}


def _fits(outcome: StudyOutcome) -> dict[str, xr.Dataset]:
    nodes = {}
    for w in outcome.laws:
        attrs = {k: v for k, v in w.fit.attrs.items() if _attr_ok(v)} | {"fit_file": f"fits/{w.fit_file.name}"}
        nodes[f"fits/{w.name}"] = xr.Dataset(attrs=attrs)
        for group in FIT_GROUPS:
            if group in w.fit.children:
                nodes[f"fits/{w.name}/{group}"] = w.fit[group].to_dataset()
    return nodes


def _attr_ok(value) -> bool:
    return isinstance(value, str | int | float | np.number) and not isinstance(value, bool)


def _root_attrs(outcome: StudyOutcome) -> dict:
    st, data = outcome.study, outcome.data
    noise = st.noise.kind + (f", partial-pooled offsets per {st.noise.group}" if st.noise.group else "")
    return {"study": st.name, "dataset": str(data.attrs.get("name", "")),
            "data_hash": str(data.attrs.get("data_hash", "")), "bayesfric_version": __version__,
            "schemes": "; ".join(outcome.schemes), "blocked_schemes": "; ".join(outcome.blocked),
            "quick": int(outcome.quick is not None),
            "ranking_changed": int(outcome.sensitivity is not None and outcome.sensitivity.changed),
            "title": st.title, "question": st.question, "study_file": str(st.path),
            "study_file_exists": int(st.path.is_file()), "include_failed": int(st.include_failed),
            "failed_fits": st.failed_fits, "noise": noise, "sampler": str(st.sampler), "n_obs": int(data.sizes["obs"])
            } | {f"data_{k}": str(v) for k in DATA_ATTRS if (v := data.attrs.get(k)) is not None}


def _sensitivity(outcome: StudyOutcome) -> dict[str, xr.Dataset]:
    """``/ranking_sensitivity``: elpd_LOO, largest Pareto k̂ and place of each ranked law at each
    prior power α (:func:`bayesfric.compare.ranking_sensitivity`); none with fewer than two fits."""
    sens = outcome.sensitivity
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


def _quick(outcome: StudyOutcome) -> dict[str, xr.Dataset]:
    """``/quick``: the settings a ``--quick`` run capped (none otherwise)."""
    if outcome.quick is None:
        return {}
    asked, used = outcome.quick.kfold
    attrs = {k: v for k, v in outcome.quick.settings.items() if k in QUICK_SETTINGS}
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


def study_tree(outcome: StudyOutcome) -> xr.DataTree:
    """The study's results as one DataTree (layout in the module docstring), from its outcome
    after the weights and the score table (``outcome.table``).

    Parameters
    ----------
    outcome : StudyOutcome
        Every law's results, weights and the law × metric table.

    Returns
    -------
    xarray.DataTree
        ``/``, ``/scores``, ``/pointwise``, :data:`LAW_NODES` and ``/fits/<law>``.
    """
    nodes = {"/": xr.Dataset(attrs=_root_attrs(outcome)), "scores": _scores(outcome),
             "criteria": _criteria(outcome), "pointwise": _pointwise(outcome)}
    nodes |= law_nodes(outcome) | _sensitivity(outcome) | _quick(outcome) | _fits(outcome)
    return xr.DataTree.from_dict(nodes)
