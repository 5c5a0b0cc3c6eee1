"""The simulated GMS case of issue 13 (studies/examples/gms_loops.toml, data/gms_loops/): the study
ranks the true law and element count first under LOO and both evidence estimators, and the fit
recovers the truth. SIMULATED data, known truth (data/gms_loops/generate.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from bayesfric.inference.diagnostics import verdict_of
from bayesfric.pipeline.runner import run_study
from bayesfric.study import STUDIES_DIR
from bayesfric.study import scores as sc

STUDY = STUDIES_DIR / "examples" / "gms_loops.toml"


GENERATOR = Path(__file__).parents[1] / "data" / "gms_loops" / "generate.py"


def _truth() -> dict:
    """The generator's TRUTH: one place for the numbers the data were simulated from."""
    spec = importlib.util.spec_from_file_location("gms_generate", GENERATOR)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.TRUTH


@pytest.mark.slow
def test_gms_loops_study_ranks_two_element_gms_first_and_recovers_it(tmp_path):
    """Runs the whole example study (3 laws, ~10 min on 2 cores): gms_n2 beats gms_n1 (too few
    elements) and maxwell_slip_n2 (no Stribeck curve, no rate dependence) under PSIS-LOO and both
    log-evidence estimators, every score reliable; of the 11 coefficients (element shares α = w / Σw,
    since Σw is not identified) at most two miss their 90 % interval, none its 98 % interval."""
    truth = _truth()
    folder = run_study(STUDY, tmp_path)
    table = pd.read_csv(folder / "scores.csv", keep_default_na=False, na_values=[""])
    table["scheme"] = table["scheme"].fillna("")
    for metric, scheme in (("elpd_loo", ""), ("log_evidence", "bridge"), ("log_evidence", "importance")):
        assert sc.best(table, metric, scheme) == "gms_n2", (metric, scheme, table)
        assert sc.value(table, "gms_n2", metric, scheme)["reliable"], (metric, scheme)
    fit = xr.open_datatree(folder / "fits" / "gms_n2.nc")
    assert verdict_of(fit).passed, fit.attrs["diagnostics"]
    post = fit["posterior"]
    draws = {k: np.asarray(post[k].values).reshape(-1, *post[k].shape[2:]) for k in truth}
    w = draws.pop("w")
    draws["alpha"] = w / w.sum(axis=1, keepdims=True)
    expected = {k: np.asarray(v, dtype=float) for k, v in truth.items() if k != "w"}
    expected["alpha"] = np.asarray(truth["w"]) / np.sum(truth["w"])
    inside = {}
    for name, value in expected.items():
        for level, (lo, hi) in {90: (0.05, 0.95), 98: (0.01, 0.99)}.items():
            low, high = np.quantile(draws[name], [lo, hi], axis=0)
            for j, ok in enumerate(np.atleast_1d((low <= value) & (value <= high))):
                inside[name, j, level] = bool(ok)
    # 11 coefficients at 90 %: about one miss is expected by chance (measured: dx[0], truth 1.000 mrad,
    # interval 1.0003-1.0125 mrad); more than two, or any truth outside its 98 % interval, fails.
    misses = [k[:2] for k, ok in inside.items() if k[2] == 90 and not ok]
    assert len(misses) <= 2 and all(ok for k, ok in inside.items() if k[2] == 98), inside
