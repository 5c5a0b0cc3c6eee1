"""Posterior recovery for the seed-004 laws and NUTS/emcee agreement (slow statistical tests).

Recovery criterion: simulate from each law with known parameters on a Stribeck-curve design
(both directions, 0.002–4 rad/s, log-spaced, 60 points), fit with NUTS (default settings: 4 chains
× 1000 draws) over 8 simulated data sets, and require

1. no gross miss: every true value within 3.5 posterior sd of the posterior mean, in every seed
   (false-alarm rate per check ≈ 5e-4 for a near-Gaussian calibrated posterior), and
2. calibration: at least 60 % of the (parameter, seed) pairs have the true value inside the 90 %
   equal-tailed interval (a calibrated interval covers 90 %; for the 1-parameter law, 8 pairs,
   the false-alarm rate is P(Binomial(8, 0.9) ≤ 4) < 0.1 %).

Measured for ``stribeck`` on these 8 data sets (2026-11-21): 24/32 pairs covered (75 %), RMS of the
z-scores 1.35 (1.0 for a perfectly calibrated posterior), largest |z| 2.74 — somewhat
overconfident on the correlated (dT_s, v_s, delta) ridge; noted as an open item. An earlier
criterion (all parameters covered in ≥ 2 of 3 seeds, 500 draws) had a false-alarm rate of ≈ 27 %
for 4 parameters and was replaced; with 3 seeds the coverage estimate was too noisy to judge.
"""

import subprocess
import sys

import arviz as az
import numpy as np
import pytest
import xarray as xr

from bayesfric.datasets.synthetic import simulate
from bayesfric.inference import fit, release_compiled_code, verdict_of
from bayesfric.laws import get_law

SPEEDS = np.geomspace(0.002, 4.0, 30)
VELOCITY = np.concatenate([-SPEEDS[::-1], SPEEDS])
TRUTHS = {
    "coulomb": {"T_C": 10.0},
    "coulomb_viscous": {"T_C": 10.0, "c_v": 2.0},
    "stribeck": {"T_C": 10.0, "dT_s": 4.0, "v_s": 0.05, "delta": 0.8},
    "armstrong_helouvry": {"T_C": 10.0, "dT_s": 4.0, "v_s": 0.05, "delta": 0.8, "c_v": 2.0},
    "joint_tribological": {"T_a0": 12.0, "v_s": 0.05, "delta_a": 0.7, "c_v": 6.0, "delta_v": 0.4},
    "prestressed_roller_bearing": {"T_a0": 12.0, "v_s": 0.05, "delta": 0.8, "T_l": 6.0, "v_l": 0.5},
    "helical_gear": {"T_a0": 12.0, "v_s": 0.05, "delta": 0.5, "c_v": 6.0},
}


def covered(dt, truth):
    post = dt["posterior"]
    return {k: bool(np.quantile(post[k].values, 0.05) <= v <= np.quantile(post[k].values, 0.95))
            for k, v in truth.items()}


def z_scores(dt, truth):
    post = dt["posterior"]
    return {k: abs(float(post[k].mean()) - v) / float(post[k].std()) for k, v in truth.items()}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TRUTHS))
def test_posterior_recovery(name):
    law = get_law(name)
    inside, pairs = 0, 0
    for seed in range(8):
        ds = simulate(law, {"velocity": VELOCITY}, TRUTHS[name], sigma=0.2, seed=100 + seed)
        dt = fit(law, ds, seed=1)
        release_compiled_code()  # 56 fits in this module would otherwise near vm.max_map_count
        worst = max(z_scores(dt, TRUTHS[name]).items(), key=lambda kv: kv[1])
        assert worst[1] <= 3.5, f"{name}, seed {seed}: {worst[0]} is {worst[1]:.1f} posterior sd from the truth"
        hits = covered(dt, TRUTHS[name])
        inside += sum(hits.values())
        pairs += len(hits)
    assert inside >= 0.6 * pairs, f"{name}: only {inside}/{pairs} true values inside their 90 % intervals"


@pytest.mark.slow
def test_nuts_and_emcee_agree():
    """Posterior means agree within 4 combined Monte Carlo standard errors (z = 4, per parameter)."""
    law = get_law("stribeck")
    ds = simulate(law, {"velocity": VELOCITY}, TRUTHS["stribeck"], sigma=0.2, seed=7)
    a = fit(law, ds, sampler="nuts", seed=1)
    b = fit(law, ds, sampler="emcee", seed=1)
    assert verdict_of(a).passed and verdict_of(b).passed
    for name in ("T_C", "dT_s", "v_s", "delta", "sigma"):
        mean_a, mean_b = float(a["posterior"][name].mean()), float(b["posterior"][name].mean())
        mcse_a = float(az.mcse(a["posterior"].to_dataset()[[name]])[name])
        mcse_b = float(az.mcse(b["posterior"].to_dataset()[[name]])[name])
        tolerance = 4.0 * np.hypot(mcse_a, mcse_b)
        assert abs(mean_a - mean_b) <= tolerance, (name, mean_a, mean_b, tolerance)


@pytest.mark.slow
def test_cli_fit_stribeck_csv_in_rpm(tmp_path):
    """Acceptance: `bayesfric fit` on a CSV in rpm and N·m passes the gate and writes a fit arviz opens."""
    law = get_law("stribeck")
    ds = simulate(law, {"velocity": VELOCITY}, TRUTHS["stribeck"], sigma=0.2, seed=11)
    rpm = ds["velocity"].values * 60 / (2 * np.pi)
    lines = ["speed_rpm,torque_Nm"] + [f"{s:.10g},{t:.10g}" for s, t in zip(rpm, ds["torque"].values, strict=True)]
    (tmp_path / "stribeck.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "stribeck.toml").write_text(
        '[dataset]\nprovenance = "simulated"\nsource = "test"\n'
        '[columns.speed_rpm]\nrole = "input"\nquantity = "velocity"\nunit = "rpm"\n'
        '[columns.torque_Nm]\nrole = "response"\nquantity = "torque"\nunit = "N*m"\n')
    out = tmp_path / "fit.nc"
    proc = subprocess.run([sys.executable, "-m", "bayesfric", "fit", str(tmp_path / "stribeck.csv"), "stribeck",
                           "--out", str(out), "--quiet"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "diagnostics: PASSED" in proc.stdout
    dt = xr.open_datatree(out)
    assert {"T_C", "dT_s", "v_s", "delta"} <= set(az.summary(dt).index)
