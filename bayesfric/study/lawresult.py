"""One law's results in a study as one ``xarray.Dataset``, built once from its scorers' results.

A study's units (:mod:`bayesfric.study.units`) return Datasets; the runner rebuilds them into the
compare layer's objects (:func:`bayesfric.study.rebuild.rebuild`), weighs the laws with them, and
flattens each law into the Dataset :func:`law_result` returns. The study's result tree
(:mod:`bayesfric.study.tree`), its score table (:func:`bayesfric.study.scores.score_table`) and its
sizing basis (:func:`bayesfric.sizing.store.basis_node`) read these Datasets, nothing else.

Variables (0-d unless a dimension is named; attrs ``law``, ``fit_file``, ``failed_fits``):

- the gate: ``passed``, ``problems``, ``verdict`` (as the report writes it), ``rhat_max``,
  ``ess_bulk_min``, ``n_params``, ``skipped`` (stages not run), ``flags`` (one line per problem);
  ``multimodal`` and ``modes`` (``"multimodal: k modes, stacking weights …"``, or ``""``): a fit
  whose chains found separate modes, used as their stacked combination
  (:mod:`bayesfric.inference.modes`), and then over ``mode``: ``mode_weight``, ``mode_chains``,
  and over ``(mode, mode_parameter)`` each posterior variable's range ``mode_q05``, ``mode_q95``;
- PSIS-LOO (``loo_computed``): ``elpd_loo``, ``elpd_loo_se``, ``p_loo``, ``loo_reliable``,
  ``loo_fit_passed``, ``loo_refitted``, ``loo_handling``, ``n_high_k`` (−1: no LOO),
  ``pareto_k_max``, ``loo_rows_scored``/``loo_rows``/``loo_subsampling_se``/``loo_subsampled``
  (a subsampled LOO; −1, NaN, ``""`` otherwise); over ``obs``: ``elpd_loo_i``, ``pareto_k``
  (NaN where not scored), ``loo_scored``;
- cross-validation over ``scheme`` (the law's schemes in the order its units ran): ``cv_elpd``,
  ``cv_se``, ``cv_ok``, ``cv_failure``, ``cv_elpd_i`` over ``(scheme, obs)``; ``penalty``,
  ``penalty_se``, ``penalty_computed`` (blocked schemes with LOO); ``cv_reliable`` (every fold of
  every scheme passed the gate);
- evidence over ``estimator``: ``log_z``, ``log_z_error``; ``evidence_compared``,
  ``evidence_agree``, ``evidence_difference`` (bridge − importance, nats);
- weights over ``weighting``: ``weight``, ``weight_excluded`` (why the weighting left the law out);
- checks (``checked``): ``prior_implausible``, ``loo_pit_pvalue``, ``loo_pit_ok``,
  ``loo_pit_direction``, ``psense``, ``ci_prob``; ``pit`` over ``pit_row``, ``pit_band`` over
  ``(band_edge, band_point)``; the residual-structure tests ``structure_*`` over
  ``structure_column`` (:mod:`bayesfric.compare.structure`; a flagged column adds a flag line);
- the measured misses over ``miss_scheme`` (:mod:`bayesfric.sizing.calibration`): ``miss_rate``,
  ``miss_beta``, ``miss_se``, ``miss_reach``, ``miss_n``;
- ``timing`` over ``stage`` (seconds computed in this run) and their sum ``seconds``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from bayesfric.compare.pit import pit_shape
from bayesfric.compare.structure import DIM, checks_of
from bayesfric.sizing.store import MISS_FIELDS

if TYPE_CHECKING:
    from bayesfric.compare import CVResult, EstimatorAgreement, Evidence, LooResult, Penalty
    from bayesfric.inference.diagnostics import Verdict
    from bayesfric.laws.base import Law
    from bayesfric.sizing.calibration import Miss

__all__ = ["Weight", "law_result", "mode_node"]


@dataclass(frozen=True)
class Weight:
    """A law's weight under one weighting, or why the weighting left it out (weight 0)."""

    value: float
    excluded: str = ""


def _gate(verdict: Verdict, law: Law, skipped: Sequence[str]) -> dict:
    return {"passed": bool(verdict.passed), "problems": "; ".join(verdict.problems), "verdict": str(verdict),
            "rhat_max": float(verdict.rhat_max), "ess_bulk_min": float(verdict.ess_bulk_min),
            "n_params": sum(max(1, math.prod(p.shape)) for p in law.params.values()), "skipped": ", ".join(skipped),
            "multimodal": bool(verdict.multimodal), "modes": verdict.mode_summary,
            "unidentified": ", ".join(verdict.unidentified)} | _modes(verdict)


def _modes(verdict: Verdict) -> dict:
    """A multimodal fit's modes (:mod:`bayesfric.inference.modes`): stacking weight per ``mode``,
    each variable's 5-95 % range per (``mode``, ``mode_parameter``); nothing for one mode."""
    if not verdict.multimodal:
        return {}
    ranges = np.array(list(verdict.mode_ranges.values()), dtype=float).reshape(len(verdict.mode_ranges), -1, 2)
    return {"mode_weight": ("mode", np.asarray(verdict.weights, dtype=float)),
            "mode_chains": ("mode", np.array([",".join(map(str, m)) for m in verdict.modes], dtype=str)),
            "mode_q05": (("mode", "mode_parameter"), ranges[..., 0].T),
            "mode_q95": (("mode", "mode_parameter"), ranges[..., 1].T)}


def _mode_line(verdict: Verdict, most: int = 6) -> str:
    """The flag of a multimodal fit: its modes, weights and the ranges of the variables (at most
    ``most``) whose 5-95 % ranges do not overlap between some two modes."""
    apart = [name for name, r in verdict.mode_ranges.items()
             if max(lo for lo, _ in r) > min(hi for _, hi in r)][:most]
    ranges = "; ".join(f"mode {k + 1}: " + ", ".join(f"{name} {verdict.mode_ranges[name][k][0]:.3g}…"
                                                      f"{verdict.mode_ranges[name][k][1]:.3g}" for name in apart)
                       for k in range(len(verdict.modes))) if apart else ""
    return (f"{verdict.mode_summary}; used as their stacked combination (5–95 % ranges: {ranges})" if ranges
            else f"{verdict.mode_summary}; used as their stacked combination")


def _loo(loo: LooResult | None) -> dict:
    if loo is None:
        return {"loo_computed": False, "p_loo": math.nan, "n_high_k": -1, "pareto_k_max": math.nan,
                "loo_rows_scored": -1, "loo_rows": -1, "loo_subsampling_se": math.nan, "loo_subsampled": ""}
    n = np.size(loo.elpd_i)
    k = np.asarray(loo.pareto_k, dtype=float).ravel()
    sub = loo.subsample
    return {
        "loo_computed": True, "elpd_loo": float(loo.elpd), "elpd_loo_se": float(loo.se), "p_loo": float(loo.p_loo),
        "loo_reliable": bool(loo.reliable), "loo_fit_passed": bool(loo.fit_passed),
        "loo_refitted": bool(loo.refitted), "loo_handling": loo.handling, "n_high_k": int(loo.n_high_k),
        "pareto_k_max": float(np.nanmax(k)) if np.isfinite(k).any() else math.nan,
        "loo_rows_scored": int(sub.size) if sub is not None else -1, "loo_rows": int(sub.n_rows) if sub else -1,
        "loo_subsampling_se": float(loo.subsampling_se) if sub is not None else math.nan,
        "loo_subsampled": loo.subsampled if sub is not None else "",
        "elpd_loo_i": ("obs", np.asarray(loo.elpd_i, dtype=float)),
        # a subsampled LOO has k̂ on its subsample only: NaN for every row then
        "pareto_k": ("obs", k if k.size == n else np.full(n, math.nan)),
        "loo_scored": ("obs", np.ones(n, dtype=bool) if sub is None else np.isin(np.arange(n), sub.rows)),
    }


def _cv(cv: Mapping[str, CVResult], penalty: Mapping[str, Penalty], n: int) -> dict:
    labels = list(cv)
    covered = next((r.coverage for r in cv.values() if r.coverage), None)
    return {
        "cv_elpd": ("scheme", [float(r.elpd) for r in cv.values()]),
        "cv_se": ("scheme", [float(r.se) for r in cv.values()]),
        "cv_ok": ("scheme", np.array([bool(r.reliable) for r in cv.values()], dtype=bool)),
        "cv_failure": ("scheme", np.array([r.failure for r in cv.values()], dtype=str)),
        "cv_elpd_i": (("scheme", "obs"), np.array([np.asarray(r.elpd_i, dtype=float) for r in cv.values()])
                      .reshape(len(labels), n)),
        "penalty": ("scheme", [float(penalty[k].per_point) if k in penalty else math.nan for k in labels]),
        "penalty_se": ("scheme", [float(penalty[k].se) if k in penalty else math.nan for k in labels]),
        "penalty_computed": ("scheme", np.array([k in penalty for k in labels], dtype=bool)),
        "cv_reliable": all(r.reliable for r in cv.values()),
        # leave-one-group-out: how the answers for a new group held on the groups left out
        **{f"group_coverage_{k}": float(covered[k]) if covered else math.nan for k in ("50", "90")},
    }


def _evidence(evidence: Mapping[str, Evidence], agreement: EstimatorAgreement | None) -> dict:
    return {"log_z": ("estimator", [float(e.log_z) for e in evidence.values()]),
            "log_z_error": ("estimator", [float(e.error) for e in evidence.values()]),
            "evidence_compared": agreement is not None,
            "evidence_agree": agreement is None or bool(agreement.agree),
            "evidence_difference": float(agreement.difference) if agreement is not None else math.nan}


def _checks(checks: xr.Dataset | None) -> dict:
    if checks is None:
        return {"checked": False, "prior_implausible": math.nan, "loo_pit_pvalue": math.nan, "loo_pit_ok": True,
                "loo_pit_direction": "", "psense": "", "ci_prob": math.nan}
    pit = checks["pit"].values if "pit" in checks else None
    a = checks.attrs
    out = {"checked": True, "prior_implausible": float(a["prior_implausible"]),
           "loo_pit_pvalue": float(a["loo_pit_pvalue"]), "loo_pit_ok": bool(a["loo_pit_ok"]),
           "loo_pit_direction": pit_shape(pit).label if pit is not None else "",
           "psense": ", ".join(json.loads(a["psense"])), "ci_prob": float(a["ci_prob"])}
    if pit is not None:
        out["pit"] = ("pit_row", np.asarray(pit, dtype=float))
    if "pit_band" in checks:
        out["pit_band"] = (("band_edge", "band_point"), np.asarray(checks["pit_band"].values, dtype=float))
    out |= {k: (DIM, checks[k].values) for k in checks.data_vars if str(k).startswith("structure_")}
    return out


def _misses(misses: Mapping[str, Miss | None]) -> dict:
    labels = list(misses)
    out = {f"miss_{k}": ("miss_scheme", [float(getattr(m, k)) if m is not None else math.nan
                                         for m in misses.values()]) for k in MISS_FIELDS}
    out["miss_n"] = ("miss_scheme", np.array([m.n if m is not None else -1 for m in misses.values()],
                                             dtype=np.int64).reshape(len(labels)))
    return out


def _flags(values: dict, verdict: Verdict, loo: LooResult | None, cv: Mapping[str, CVResult],
           agreement: EstimatorAgreement | None, failed_fits: str) -> list[str]:
    """One line per problem found in the law's results, in the order the stages ran."""
    out = [_mode_line(verdict)] if verdict.multimodal else []
    out += [verdict.unidentified_summary] if verdict.unidentified else []
    if not verdict.passed:
        note = verdict.predictions_note
        out.append("diagnostics FAILED: " + "; ".join(verdict.problems) + (f" ({note})" if note else ""))
    if values["skipped"]:
        out.append(f"{values['skipped']} skipped: the full fit failed the diagnostics gate "
                   f"([compare] failed_fits = \"{failed_fits}\"; \"run\" computes them anyway)")
    if loo is not None and not loo.reliable:
        why = "the full fit failed the gate" if not loo.fit_passed else loo.handling
        if not loo.fit_passed and not loo.refitted:  # failed_fits = "skip": no exact refit was spent
            why += f"; PSIS only, {loo.n_high_k} high-k point(s) not refitted ([compare] failed_fits = \"skip\")"
        out.append(f"LOO unreliable ({why})")
    out += [f"{label}: {r.failure}" for label, r in cv.items() if not r.reliable]  # scores.fold_failure
    out += [f"{label}: a fold's chains did not mix along {', '.join(r.unidentified)} but agree on every row "
            "(used, as a full fit would be)" for label, r in cv.items() if r.reliable and r.unidentified]
    out += [f"{label}: {r.modes_note}; scored by the combined draws" for label, r in cv.items()
            if r.reliable and r.modes_note]
    if agreement is not None and not agreement.agree:
        importance = agreement.b
        why = (f"importance sampling {importance.diagnostics['multimodal']}" if "multimodal" in importance.diagnostics
               else f"importance weights heavy-tailed (Pareto k = {importance.diagnostics['pareto_k']:.2f})"
               if not importance.diagnostics.get("reliable", True) else f"> {agreement.threshold:.2f} nat")
        out.append(f"evidence estimators disagree by {abs(agreement.difference):.2f} nat ({why}); "
                   "not ranked by evidence")
    if values["checked"] and not values["loo_pit_ok"]:
        p = values["loo_pit_pvalue"]
        ks = "< 0.001" if p < 1e-3 else f"= {p:.2g}"
        shape = values["loo_pit_direction"]
        out.append(f"LOO-PIT outside the {values['ci_prob']:.0%} band (KS p {ks}): miscalibrated"
                   + (f", {shape}" if shape else ""))
    return out


def law_result(law: Law, fit_file: str, verdict: Verdict, *, loo: LooResult | None = None,
               cv: Mapping[str, CVResult] | None = None, penalty: Mapping[str, Penalty] | None = None,
               evidence: Mapping[str, Evidence] | None = None, agreement: EstimatorAgreement | None = None,
               checks: xr.Dataset | None = None, misses: Mapping[str, Miss | None] | None = None,
               weights: Mapping[str, Weight] | None = None, skipped: Sequence[str] = (),
               failed_fits: str = "skip", timings: Mapping[str, float] | None = None) -> xr.Dataset:
    """One law's results in a study as one Dataset (layout in the module docstring).

    Parameters
    ----------
    law : Law
        The law as it ran (a variant included), named by the study's entry.
    fit_file : str
        Its fit's file in the report folder (``fits/<law>.nc``).
    verdict : Verdict
        The full fit's diagnostics gate.
    loo, cv, penalty, evidence, agreement
        The compare layer's results (:func:`bayesfric.study.rebuild.rebuild`): PSIS-LOO, each
        cross-validation scheme by label, each blocked scheme's extrapolation penalty, each
        log-evidence estimate, and whether bridge sampling and importance sampling agree.
    checks : xarray.Dataset, optional
        The checks unit's Dataset (:func:`bayesfric.study.units.checks_dataset`).
    misses : mapping, optional
        Sizing scheme label -> the law's measured miss there, or None where none was measured.
    weights : mapping, optional
        Weighting -> the law's :class:`Weight`.
    skipped : sequence of str
        Stages not run because the full fit failed the gate; ``failed_fits`` the study's setting.
    timings : mapping, optional
        Stage -> wall seconds computed in this run.

    Returns
    -------
    xarray.Dataset
    """
    cv, evidence, weights, timings = cv or {}, evidence or {}, weights or {}, timings or {}
    values = _gate(verdict, law, skipped) | _loo(loo) | _checks(checks)
    n = np.size(loo.elpd_i) if loo is not None else next((np.size(r.elpd_i) for r in cv.values()), 0)
    values |= _cv(cv, penalty or {}, n) | _evidence(evidence, agreement) | _misses(misses or {})
    values["weight"] = ("weighting", [float(w.value) for w in weights.values()])
    values["weight_excluded"] = ("weighting", np.array([w.excluded for w in weights.values()], dtype=str))
    values["timing"] = ("stage", [float(s) for s in timings.values()])
    values["seconds"] = float(sum(timings.values()))
    structure = [f"residual structure: {c.sentence()}" for c in checks_of(checks) if c.flagged] if checks else []
    values["flags"] = "\n".join(_flags(values, verdict, loo, cv, agreement, failed_fits) + structure)
    coords = {"scheme": list(cv), "estimator": list(evidence), "weighting": list(weights), "stage": list(timings),
              "miss_scheme": list(misses or {})}
    if verdict.multimodal:
        coords |= {"mode": [str(k + 1) for k in range(len(verdict.modes))], "mode_parameter": list(verdict.mode_ranges)}
    if checks is not None and DIM in checks.dims:
        coords[DIM] = [str(c) for c in checks[DIM].values]
    ds = xr.Dataset(values, coords={k: np.array(v, dtype=str) for k, v in coords.items()},
                    attrs={"law": law.name, "fit_file": fit_file, "failed_fits": failed_fits})
    if "pit_band" in ds:
        ds = ds.assign_coords(band_edge=["point", "lower", "upper"])
    return ds


def mode_node(laws: Sequence[xr.Dataset]) -> dict[str, xr.Dataset]:
    """The result tree's ``/modes`` node: one row per multimodal law, mode and posterior variable
    (``law``, ``mode``, ``parameter``, ``weight``, ``chains``, ``q05``, ``q95``); none without one."""
    rows = [(str(w.attrs["law"]), str(m), str(p), float(w["mode_weight"].sel(mode=m)),
             str(w["mode_chains"].sel(mode=m).values), float(w["mode_q05"].sel(mode=m, mode_parameter=p)),
             float(w["mode_q95"].sel(mode=m, mode_parameter=p)))
            for w in laws if "mode_weight" in w for m in w["mode"].values for p in w["mode_parameter"].values]
    if not rows:
        return {}
    names = ("law", "mode", "parameter", "weight", "chains", "q05", "q95")
    columns = dict(zip(names, zip(*rows, strict=True), strict=True))
    node = xr.Dataset({k: ("mode_row", np.array(v, dtype=float if k in ("weight", "q05", "q95") else str))
                       for k, v in columns.items()})
    node.attrs["description"] = "modes of multimodal fits: stacking weight and 5-95 % range of each variable"
    return {"modes": node}
