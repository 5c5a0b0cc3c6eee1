"""A law's unit Datasets, fresh or read from the run store, rebuilt as the compare layer's
objects (:class:`Scored`): what the runner weighs the laws with (:mod:`bayesfric.study.runner`).
The Datasets are written by :mod:`bayesfric.study.units`; this module reads them back.
"""

from __future__ import annotations

import json
from typing import NamedTuple

import numpy as np
import xarray as xr

from bayesfric import compare
from bayesfric.compare.heldout import HeldOut
from bayesfric.compare.loo import loo_from_values
from bayesfric.inference.diagnostics import Verdict
from bayesfric.study.store import Result
from bayesfric.study.units import Unit

__all__ = ["Scored", "rebuild"]


# -- rebuilding the compare layer's results -------------------------------------------------------
class Scored(NamedTuple):
    """One law's results as the compare layer's objects, rebuilt from its units' Datasets
    (:func:`rebuild`). Transient: the runner weighs the laws with them and flattens each into the
    law's result Dataset (:func:`bayesfric.study.lawresult.law_result`); they are not kept."""

    loo: compare.LooResult | None
    cv: dict[str, compare.CVResult]
    penalty: dict[str, compare.Penalty]
    evidence: dict[str, compare.Evidence]
    agreement: compare.EstimatorAgreement | None
    checks: xr.Dataset | None


def _evidence(ds: xr.Dataset) -> compare.Evidence:
    a = ds.attrs
    return compare.Evidence(float(a["log_z"]), float(a["error"]), str(a["method"]), json.loads(a["diagnostics"]))


def rebuild(fit: xr.DataTree, units: list[Unit], results: dict[str, Result], kinds: dict[str, str]) -> Scored:
    """The :class:`Scored` results of a law from its fit and its units' Datasets (fresh or stored).

    ``kinds`` maps a CV label to its scheme kind (kfold, grouped, blocked): a blocked scheme's
    extrapolation penalty is computed here from LOO and its pointwise elpd.
    """
    by_label = {u.label: results[u.key] for u in units if u.key in results}
    loo = None
    if "loo" in by_label:
        ds = by_label["loo"]
        loo = loo_from_values(fit, ds["elpd_i"].values, str(ds.attrs["handling"]),
                              [int(i) for i in ds["refit_failed"].values], bool(ds.attrs["refitted"]))
    cv = {u.label: _cv(results[u.key]) for u in units if u.stage == "cv" and u.key in results}
    penalty = {label: compare.extrapolation_penalty(loo, result) for label, result in cv.items()
               if kinds[label] == "blocked" and loo is not None}
    evidence = {name: _evidence(by_label[name]) for name in ("bridge", "importance", "SMC") if name in by_label}
    # Two estimators that share only the density (bench_evidence.py); never averaged.
    agreement = (compare.compare_estimators(evidence["bridge"], evidence["importance"])
                 if {"bridge", "importance"} <= set(evidence) else None)
    return Scored(loo, cv, penalty, evidence, agreement, by_label.get("checks"))


def _cv(ds: xr.Dataset) -> compare.CVResult:
    kept = (HeldOut(ds["heldout_index"].values.astype(int), ds["heldout_fold"].values.astype(int),
                    ds["heldout_mu"].values.astype(float), ds["heldout_noise_var"].values.astype(float))
            if "heldout_mu" in ds else None)
    a = ds.attrs
    return compare.CVResult(law=str(a["law"]), scheme=str(a["scheme"]), elpd=float(a["elpd"]), se=float(a["se"]),
                            elpd_i=ds["elpd_i"].values.astype(float), heldout=ds["heldout"].values.astype(bool),
                            verdicts=[Verdict.from_dict(v) for v in json.loads(a["verdicts"])],
                            seconds=float(a["seconds"]),
                            settings=json.loads(a["settings"]), predictive=kept,
                            coverage=json.loads(a["coverage"]) if "coverage" in a else None,
                            elpd_fold=_floats(a.get("elpd_fold", "null")),
                            elpd_new_group=_floats(a.get("elpd_new_group", "null")), too_few=str(a.get("too_few", "")))


def _floats(text: str) -> np.ndarray | None:
    """A JSON list of numbers as an array (``null``: None)."""
    values = json.loads(text)
    return None if values is None else np.asarray(values, dtype=float)
