"""A tribometer's force-displacement loops in µN and mm (issue 13): the rotary-declared hysteresis
laws run on translational data with their default priors and pass the diagnostics gate.

The data are SIMULATED at tribometer scale (µm knee, sub-mN force), written as CSV in µN, mm,
mm/s and ms with a sidecar, and read by the loader (units converted by pint), exactly as a user's
file would be.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayesfric.compare import verdict_of
from bayesfric.datasets import load_dataset
from bayesfric.inference import fit
from bayesfric.laws import get_law
from bayesfric.laws.variants import vary

#: Dahl truth on the tribometer (SI): running friction 500 µN, knee 2 µm, exponent 1.5.
DAHL = {"F_c0": 5e-4, "x_c0": 2e-6, "i": 1.5}
#: LuGre truth (SI): pre-sliding deflection F_c/σ0 = 1 µm, Stribeck speed 20 µm/s.
#: F_ratio = F_c/F_s with F_s = 700 µN.
LUGRE = {"sigma0": 500.0, "rho1": 0.5, "sigma2": 0.5, "F_c": 5e-4, "F_ratio": 5e-4 / 7e-4, "v_s": 2e-5}
NOISE = 5e-6  # 5 µN, 1 % of the running friction


def _loops(per_cycle=60, cycles=2, runs=(10e-6, 20e-6, 30e-6), freq=1.0):
    """Sinusoidal strokes of the given amplitudes (m): displacement, velocity, time, run label."""
    t = np.arange(per_cycle * cycles) / (per_cycle * freq)
    x = np.concatenate([a * np.sin(2 * np.pi * freq * t) for a in runs])
    v = np.concatenate([a * 2 * np.pi * freq * np.cos(2 * np.pi * freq * t) for a in runs])
    return x, v, np.tile(t, len(runs)), np.repeat(np.arange(1, len(runs) + 1), t.size)


def _write(tmp_path, law, truth, seed):
    """Simulate ``law``'s translational form and write it as a tribometer CSV in µN and mm."""
    from bayesfric.laws.base import TRAJECTORY_START

    x, v, t, run = _loops()
    start = np.r_[True, run[1:] != run[:-1]]
    inputs = {"displacement": x, "linear_velocity": v, "time": t, TRAJECTORY_START: start}
    mean = np.asarray(law.mean({k: inputs[k] for k in law.inputs}, truth), dtype=float)
    force = mean + np.random.default_rng(seed).normal(0.0, NOISE, mean.size)
    rows = [f"{xi * 1e3:.9g},{vi * 1e3:.9g},{ti * 1e3:.9g},{r},{f * 1e6:.6g}"
            for xi, vi, ti, r, f in zip(x, v, t, run, force, strict=True)]
    (tmp_path / "tribo.csv").write_text("x_mm,v_mm_s,t_ms,run,F_uN\n" + "\n".join(rows) + "\n")
    (tmp_path / "tribo.toml").write_text(
        '[dataset]\nname = "tribo"\ntitle = "SIMULATED tribometer loops"\nprovenance = "simulated"\n'
        'source = "tests/test_tribometer.py"\ntrajectory = "run"\n'
        '[columns.x_mm]\nrole = "input"\nquantity = "displacement"\nunit = "mm"\n'
        '[columns.v_mm_s]\nrole = "input"\nquantity = "linear_velocity"\nunit = "mm/s"\n'
        '[columns.t_ms]\nrole = "input"\nquantity = "time"\nunit = "ms"\n'
        '[columns.run]\nrole = "group"\n'
        '[columns.F_uN]\nrole = "response"\nquantity = "force"\nunit = "uN"\n')
    return load_dataset(tmp_path / "tribo.csv")


def _within_90(dt, truth):
    post = dt["posterior"].to_dataset()
    for name, value in truth.items():
        low, high = np.quantile(np.asarray(post[name]).ravel(), [0.05, 0.95])
        assert low <= value <= high, f"{name}: truth {value:g} outside the 90 % interval [{low:g}, {high:g}]"


@pytest.mark.slow
def test_dahl_fits_tribometer_loops_with_default_priors(tmp_path):
    truth_law = vary(get_law("dahl"), without=["preload"], motion="translational")
    ds = _write(tmp_path, truth_law, DAHL, seed=3)
    assert ds.attrs["response"] == "force" and float(abs(ds["displacement"]).max()) == pytest.approx(30e-6)
    dt = fit(get_law("dahl"), ds, draws=500, tune=500, chains=4, seed=1)  # registered law, default priors
    verdict = verdict_of(dt)
    assert verdict.passed, verdict.problems
    assert dt.attrs["law_recipe"]  # stored as its translational variant without the preload factor
    _within_90(dt, DAHL)


@pytest.mark.slow
def test_lugre_fits_tribometer_loops_with_default_priors(tmp_path):
    truth_law = vary(get_law("lugre"), without=["preload"], motion="translational")
    ds = _write(tmp_path, truth_law, LUGRE, seed=4)
    dt = fit(get_law("lugre"), ds, seed=1)  # the default 4 × (1000 + 1000): 500 draws left R-hat at 1.011
    verdict = verdict_of(dt)
    assert verdict.passed, verdict.problems
    _within_90(dt, {k: LUGRE[k] for k in ("F_c", "sigma0")})


@pytest.mark.slow
def test_lugre_passes_gate_on_dahl_loops(tmp_path):
    # issue 29: a stateful law fitted to loops simulated from *another* law (Dahl, the tribo_loops
    # design and scale), default priors and sampler settings but 2 chains: the gate must pass
    truth_law = vary(get_law("dahl"), without=["preload"], motion="translational")
    ds = _write(tmp_path, truth_law, DAHL, seed=3)
    dt = fit(get_law("lugre"), ds, draws=1000, tune=1000, chains=2, seed=1)
    verdict = verdict_of(dt)
    assert verdict.passed, verdict.problems


@pytest.mark.slow
def test_maxwell_slip_passes_gate_on_dahl_loops(tmp_path):
    # issue 29: as LuGre's above, Maxwell-slip (N = 4) on the same Dahl loops, with the default
    # 4 × (1000 + 1000): its element deflections mix slowly on these rate-independent loops
    # (residuals ~12× the noise, 74 leapfrog steps per draw), 2 chains left bulk ESS at 323
    truth_law = vary(get_law("dahl"), without=["preload"], motion="translational")
    ds = _write(tmp_path, truth_law, DAHL, seed=3)
    dt = fit(get_law("maxwell_slip"), ds, seed=1)
    verdict = verdict_of(dt)
    assert verdict.passed, verdict.problems
