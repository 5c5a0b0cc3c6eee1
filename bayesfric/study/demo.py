"""Interim main job: simulate a Stribeck curve from a known law, fit it, print the report."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bayesfric.datasets.synthetic import simulate
from bayesfric.inference import fit, save_fit
from bayesfric.laws import get_law
from bayesfric.report.tables import fit_report

TRUE = {"T_C": 12.0, "dT_s": 5.0, "v_s": 0.04, "delta": 0.7, "c_v": 3.0}


def run_flagship(out_root: str | Path = "reports", quick: bool = False) -> Path:
    """Simulate (label: *simulated*) an Armstrong-Hélouvry Stribeck curve, fit it with NUTS, report."""
    law = get_law("armstrong_helouvry")
    speeds = np.geomspace(0.002, 4.0, 40)
    velocity = np.concatenate([-speeds[::-1], speeds])
    ds = simulate(law, {"velocity": velocity}, TRUE, sigma=0.3, seed=2026, name="simulated_stribeck")
    print(f"SIMULATED data: {ds.attrs['source']}")
    dt = fit(law, ds, sampler="nuts", draws=500 if quick else 1000, tune=500 if quick else 1000, seed=1,
             progress=True)
    print(fit_report(dt, law))
    print("true values: " + ", ".join(f"{k}={v}" for k, v in TRUE.items()))
    out = save_fit(dt, Path(out_root) / "simulated_stribeck" / "fit_armstrong_helouvry.nc")
    print(f"fit written to {out}")
    return out
