"""Posterior recovery of GMS and elasto-plastic on SIMULATED loops with default priors, and the
GMS-loops case of issue 13 (deliverable 8): the true law wins under evidence and PSIS-LOO against
the rate-independent Maxwell-slip with the same number of elements."""

from __future__ import annotations

import numpy as np
import pytest

from bayesfric.compare.evidence import bridge_log_evidence
from bayesfric.compare.loo import psis_loo
from bayesfric.inference import check, fit
from bayesfric.laws import get_law
from bayesfric.model import build_program

GMS_TRUTH = dict(F_c=1.0, dF_s=0.5, v_s=0.01, sigma2=2.0, C=200.0,
                 w=np.array([1.0, 1.0]), dx=np.array([0.5e-3, 1.5e-3]))
EP_TRUTH = dict(sigma0=1e3, beta=0.4, sigma2=2.0, F_c=1.0, dF_s=0.5, v_s=0.01)


def loops(simulator, law, truth, *, seed):
    """Two sinusoidal velocity cycles of each of two amplitudes (±0.02 and ±0.05 rad/s, 2 s
    period), 150 samples per cycle: reversals sampled inside the pre-sliding range and sliding
    across the Stribeck curve. Noise 1 % of F_c. Inputs for velocity, time and angle laws."""
    per = 150
    t = np.arange(2 * per) * (2.0 / per)
    runs, vs = [], []
    for k, amp in enumerate((0.02, 0.05)):
        vs.append(amp * np.sin(2 * np.pi * t / 2.0))
        runs.append(np.full(t.size, k))
    v, run = np.concatenate(vs), np.concatenate(runs)
    time = np.tile(t, 2)
    angle = np.concatenate([np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))]) for x in vs])
    return simulator(law, {"velocity": v, "time": time, "angle": angle}, truth, sigma=0.01, seed=seed,
                     groups={"run": run}, trajectory="run")


def in_interval(dt, name, value, transform=None):
    draws = np.asarray(dt["posterior"][name].values)
    draws = draws.reshape(-1, *draws.shape[2:])
    if transform is not None:
        draws = transform(draws)
    lo, hi = np.quantile(draws, [0.05, 0.95], axis=0)
    assert np.all((lo <= value) & (value <= hi)), f"{name}: truth {value} outside 90 % [{lo}, {hi}]"


@pytest.mark.slow
def test_gms_recovered_and_preferred_over_maxwell_slip(simulator):
    law = get_law("gms_n2")
    ds = loops(simulator, law, GMS_TRUTH, seed=3)
    dt = fit(law, ds, draws=300, tune=400, chains=2, seed=0)
    verdict = check(dt)
    assert verdict.passed, str(verdict)
    for name in ("F_c", "dF_s", "v_s", "sigma2"):
        in_interval(dt, name, GMS_TRUTH[name])
    w = GMS_TRUTH["w"]
    in_interval(dt, "w", w / w.sum(), transform=lambda d: d / d.sum(axis=-1, keepdims=True))
    in_interval(dt, "dx", np.cumsum(GMS_TRUTH["dx"]), transform=lambda d: np.cumsum(d, axis=-1))
    rival = get_law("maxwell_slip_n2")
    dt_rival = fit(rival, ds, draws=300, tune=400, chains=2, seed=0)
    z_true = bridge_log_evidence(build_program(law, ds), dt)
    z_rival = bridge_log_evidence(build_program(rival, ds), dt_rival)
    assert z_true.log_z - z_rival.log_z > 5 * (z_true.error + z_rival.error + 1.0)
    loo_true, loo_rival = psis_loo(dt, ds), psis_loo(dt_rival, ds)
    assert loo_true.elpd - loo_rival.elpd > 4 * np.hypot(loo_true.se, loo_rival.se)


@pytest.mark.slow
def test_elastoplastic_posterior_recovery(simulator):
    law = get_law("elastoplastic")
    ds = loops(simulator, law, EP_TRUTH, seed=4)
    dt = fit(law, ds, draws=300, tune=400, chains=2, seed=0)
    verdict = check(dt)
    assert verdict.passed, str(verdict)
    for name, value in EP_TRUTH.items():
        in_interval(dt, name, value)
