"""Stateful laws sized by their steady state (issue 50 item 4).

(a) Each trajectory law's declared steady state (:func:`bayesfric.laws.steady_state`) equals the
law's own trajectory run long at constant speed (its last value, once the transient has settled),
for random parameter draws and both directions; a coast-down's equals −J dω/dt along its own
coast-down at that speed (the torque that would hold the speed constant). Variants carry through.
(b) Sizing a LuGre fit and a Dahl fit (tiny NUTS fits on simulated loops) at a constant speed
gives, per posterior draw, the law simulated long at that speed with that draw; the sized
quantiles are those of the simulated values, and the noisy ones within Monte Carlo error.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bayesfric import sizing
from bayesfric.laws import get_law, steady_state
from bayesfric.laws.base import TRAJECTORY_START, Param, declare
from bayesfric.laws.steady import STEADY_NOTE
from bayesfric.laws.variants import vary
from bayesfric.priors import Prior

SPEEDS = np.array([-2.0, -0.05, 0.01, 0.3, 4.0])
DRAWS = 4
rng = np.random.default_rng(50)


def _log_uniform(lo, hi):
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _run(law, velocity, extra, n=400, span=1e12):
    """The inputs of one constant-speed run from rest, time on a geometric grid up to ``span`` s
    (far beyond every transient: each law's step update is exact or capped, however long the step)."""
    t = np.concatenate([[0.0], np.geomspace(1e-6, span, n - 1)])
    inputs = {"velocity": np.full(n, velocity), "time": t, "angle": velocity * t,
              TRAJECTORY_START: np.arange(n) == 0} | {k: np.full(n, v) for k, v in extra.items()}
    return inputs


def _check(name, params, extra=None, constants=None, rtol=1e-9):
    """The declared steady state against the law run long at every speed of SPEEDS; the worst
    relative difference."""
    law = get_law(name)
    steady = steady_state(law)
    extra = extra or {}
    worst = 0.0
    for v in SPEEDS:
        inputs = _run(law, v, extra)
        simulated = float(np.asarray(law.mean({k: inputs[k] for k in law.inputs}, params, constants))[-1])
        at = {"velocity": np.array([v])} | {k: np.array([x]) for k, x in extra.items()}
        predicted = float(np.asarray(steady.mean({k: at[k] for k in steady.inputs}, params, constants))[0])
        assert np.sign(predicted) == np.sign(v)
        np.testing.assert_allclose(predicted, simulated, rtol=rtol, atol=1e-12, err_msg=f"{name} at v = {v}")
        worst = max(worst, abs(predicted - simulated) / abs(simulated))
    return worst


@pytest.mark.parametrize("draw", range(DRAWS))
def test_lugre_steady_state_is_its_long_run(draw):
    params = {"sigma0": _log_uniform(1e2, 1e4), "rho1": rng.uniform(0, 1), "sigma2": rng.uniform(0, 0.5),
              "F_c": rng.uniform(0.5, 2), "F_ratio": rng.uniform(0.3, 0.9), "v_s": _log_uniform(0.05, 2),
              "gamma": rng.uniform(0.5, 1.5)}
    start = float(rng.choice([0.0, 1.0, -1.0]))
    _check("lugre", params, {"preload": rng.uniform(50, 150)}, {"F_start": start})


@pytest.mark.parametrize("name", ["dahl", "dahl_xc_preload"])
@pytest.mark.parametrize("draw", range(DRAWS))
def test_dahl_steady_state_is_its_long_run(name, draw):
    params = {"F_c0": rng.uniform(0.2, 2), "gamma": rng.uniform(0.5, 1.5), "x_c0": _log_uniform(1e-3, 1e-2),
              "i": rng.uniform(0.7, 2.0)} | ({"kappa": rng.uniform(-0.5, 0.5)} if name.endswith("preload") else {})
    # i = 2: u = 1 − F/F_c falls as x_c/x, so the run goes 1e12 knees (one exact step per sample)
    _check(name, params, {"preload": rng.uniform(50, 150)}, {"F_start": float(rng.choice([0.0, 1.0]))})


@pytest.mark.parametrize("n", [1, 4])
@pytest.mark.parametrize("draw", range(DRAWS))
def test_maxwell_slip_steady_state_is_every_element_sliding(n, draw):
    name = "maxwell_slip" if n == 4 else f"maxwell_slip_n{n}"
    params = {"F_c": rng.uniform(0.2, 2), "w": rng.gamma(2.0, size=n), "dx": np.exp(rng.uniform(-8, -3, size=n))}
    _check(name, params)


@pytest.mark.parametrize("draw", range(DRAWS))
def test_gms_steady_state_is_its_stribeck_curve(draw):
    params = {"F_c": rng.uniform(0.2, 2), "dF_s": rng.uniform(0, 1), "v_s": _log_uniform(0.05, 2),
              "sigma2": rng.uniform(0, 0.5), "C": _log_uniform(1, 1e3), "w": rng.gamma(2.0, size=4),
              "dx": np.exp(rng.uniform(-8, -3, size=4))}
    _check("gms", params, constants={"F_start": float(rng.choice([0.0, 1.0, -1.0]))})


@pytest.mark.parametrize("draw", range(DRAWS))
def test_elastoplastic_steady_state_is_its_long_run(draw):
    params = {"sigma0": _log_uniform(1e2, 1e4), "beta": rng.uniform(0.05, 0.95), "F_c": rng.uniform(0.2, 2),
              "F_ratio": rng.uniform(0.3, 0.95), "v_s": _log_uniform(0.05, 2), "sigma2": rng.uniform(0, 0.5)}
    _check("elastoplastic", params, constants={"F_start": float(rng.choice([0.0, 1.0]))})


COASTDOWNS = {
    "coastdown_coulomb_viscous_closed_form": lambda: {"T_C": rng.uniform(0.2, 2), "c_v": _log_uniform(1e-4, 1e-2)},
    "coastdown_oring_closed_form": lambda: {"T_C": rng.uniform(0.2, 2), "c_v": _log_uniform(1e-4, 1e-2)},
    "coastdown_coulomb_closed_form": lambda: {"T_C": rng.uniform(0.2, 2)},
    "coastdown_coulomb_viscous": lambda: {"T_C": rng.uniform(0.2, 2), "c_v": _log_uniform(1e-4, 1e-2)},
    "coastdown_stribeck": lambda: {"T_C": rng.uniform(0.2, 1), "dT_s": rng.uniform(0, 0.5),
                                   "v_s": _log_uniform(1, 20), "delta": rng.uniform(1, 2)},
}


@pytest.mark.parametrize("name", list(COASTDOWNS))
def test_coastdown_steady_state_is_the_torque_its_coastdown_decelerates_by(name):
    """J dω/dt = −T_f(ω): along the law's own coast-down, −J dω/dt at a speed is its steady state
    there (closed forms: dω/dt by autodiff; diffrax: a central difference)."""
    law, worst = get_law(name), 0.0
    steady = steady_state(law)
    assert steady.response == "torque" and steady.inputs == ("velocity",) and law.response == "velocity"
    J = law.constants["J"].value
    for _ in range(DRAWS):
        params = COASTDOWNS[name]()
        for w0 in (-60.0, 15.0, 80.0):
            t = np.array([0.0, 0.5, 2.0]) * (J * abs(w0) / params["T_C"]) / 4  # before the stop
            if name.endswith("closed_form"):
                def omega(time, w0=w0, params=params):
                    return law.mean({"time": time, "initial_velocity": w0, TRAJECTORY_START: True},
                                    params)
                rate = np.array([jax.grad(omega)(ti) for ti in t])
            else:
                h = 1e-4 * t.max()
                ahead, behind = ({"time": t + s, "initial_velocity": np.full(3, w0), TRAJECTORY_START: t == 0}
                                 for s in (h, -h))
                ahead["time"][0], behind["time"][0] = 2 * h, 0.0  # forward difference at the release
                rate = (np.asarray(law.mean(ahead, params)) - np.asarray(law.mean(behind, params))) / (
                    ahead["time"] - behind["time"])
            speed = np.asarray(law.mean({"time": t, "initial_velocity": np.full(3, w0),
                                         TRAJECTORY_START: t == 0}, params))
            torque = np.asarray(steady.mean({"velocity": speed}, params))
            tolerance = 1e-10 if name.endswith("closed_form") else 1e-4
            np.testing.assert_allclose(torque, -J * rate, rtol=tolerance)
            worst = max(worst, float(np.max(np.abs(torque + J * rate) / np.abs(torque))))
    assert worst < 1e-3


def test_variants_carry_through_to_the_steady_state():
    lugre = get_law("lugre")
    variant = vary(lugre, without=["preload"], motion="translational", add=["offset"], vary_by={"run": ["F_c"]})
    steady = steady_state(variant)
    assert steady.inputs == ("linear_velocity",) and steady.response == "force" and not steady.trajectory
    assert set(steady.params) == set(variant.params) and set(steady.constants) == set(variant.constants)
    assert steady.varying == {"F_c": "run"} and steady.steady_of == variant.name
    params = {"sigma0": 1e3, "rho1": 0.5, "sigma2": 0.2, "F_c": 1.0, "F_ratio": 0.5, "v_s": 0.1, "offset": 0.3}
    v = np.array([-1.0, 0.5])
    expected = (1.0 + 1.0 * np.exp(-((v / 0.1) ** 2))) * np.sign(v) + 0.2 * v + 0.3
    np.testing.assert_allclose(steady.mean({"linear_velocity": v}, params), expected, rtol=1e-12)
    # an alias (fixed i), a parameter fixed and a law added
    dahl = steady_state(vary(get_law("dahl_i1p5"), without=["preload"], fixed={"x_c0": 0.01}) + "viscous")
    assert dahl.inputs == ("velocity",) and set(dahl.params) == {"F_c0", "c_v"}
    np.testing.assert_allclose(dahl.mean({"velocity": v}, {"F_c0": 2.0, "c_v": 0.1}), 2 * np.sign(v) + 0.1 * v)
    assert steady_state(get_law("coulomb")) is get_law("coulomb")


def test_a_trajectory_law_without_a_steady_state_keeps_the_clear_refusal():
    def hold(velocity, time, trajectory_start, T_C):
        """A stateful law that declares no steady state."""
        return T_C * jnp.cumsum(velocity * time)

    law = declare(hold, name="held", family="test", inputs=("velocity", "time", TRAJECTORY_START),
                  response="torque", source="test", trajectory=True,
                  params={"T_C": Param("N*m", Prior("HalfNormal", scale=1.0), "torque", "test")})
    assert steady_state(law) is None
    with pytest.raises(sizing.SizingError, match="trajectory .stateful. law.*declares no steady state"):
        sizing.sizing_law(law)


# -- (b) sizing real fits --------------------------------------------------------------------------
def _loops(law, params, *, angle=False, sigma=0.02, seed=0):
    """Two runs of triangle-wave loops, at 0.3 and 1.2 rad/s (40 rows each), simulated from ``law``."""
    from bayesfric.datasets.synthetic import make_dataset

    t = np.linspace(0.0, 4.0, 40)
    v = np.concatenate([s * np.sign(np.sin(np.pi * t / 2 + 1e-9)) for s in (0.3, 1.2)])
    time = np.tile(t, 2)
    x = np.concatenate([np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
                        for w in (v[:40], v[40:])])
    inputs = {"angle": x} if angle else {"velocity": v, "time": time}
    start = np.tile(np.arange(40) == 0, 2)
    mu = np.asarray(law.mean(inputs | {TRAJECTORY_START: start}, params))
    y = mu + sigma * np.random.default_rng(seed).normal(size=mu.size)
    return make_dataset(inputs, y, groups={"run": np.repeat([1, 2], 40)}, trajectory="run")


def _long_runs(law, post, speed, extra_inputs):
    """The law run long at ``speed`` with every posterior draw: the last value per draw, (S,)."""
    names = [k for k in law.params]
    flat = {k: np.asarray(post[k].values).reshape((-1,) + post[k].shape[2:]) for k in names}
    n = 400
    t = np.concatenate([[0.0], np.geomspace(1e-6, 1e12, n - 1)])
    inputs = {"velocity": np.full(n, speed), "time": t, "angle": speed * t, TRAJECTORY_START: np.arange(n) == 0}
    inputs = {k: jnp.asarray(v) for k, v in (inputs | extra_inputs).items() if k in law.inputs}
    last = jax.jit(jax.vmap(lambda p: law.mean(inputs, p)[-1]))
    return np.asarray(last({k: jnp.asarray(v) for k, v in flat.items()}))


@pytest.mark.parametrize(("name", "truth", "angle"), [
    ("lugre", {"sigma0": 20.0, "rho1": 0.3, "sigma2": 0.2, "F_c": 1.0, "F_ratio": 0.7, "v_s": 0.5, "gamma": 1.0},
     False),
    ("dahl", {"F_c0": 1.0, "gamma": 1.0, "x_c0": 0.05, "kappa": 0.0, "i": 1.5}, True),
])
def test_sizing_a_stateful_fit_answers_its_long_run_at_that_speed(name, truth, angle):
    import bayesfric
    from bayesfric.laws.variants import law_of_fit

    law = get_law(name)
    data = _loops(vary(law, without=["preload"]), {k: v for k, v in truth.items() if k not in ("gamma", "kappa")},
                  angle=angle)
    fit = bayesfric.fit(name, data, draws=200, tune=200, chains=2, seed=1)
    fitted = law_of_fit(fit.attrs)  # as it ran on the data: without preload
    speeds = np.array([-0.8, 0.5, 1.5])
    draws = sizing.predict(fit, {"velocity": speeds})
    assert draws.steady == STEADY_NOTE
    post = fit["posterior"].to_dataset()
    simulated = np.stack([_long_runs(fitted, post, v, {}) for v in speeds], axis=-1)  # (S, points)
    np.testing.assert_allclose(draws.mu.reshape(-1, speeds.size), simulated, rtol=1e-8, atol=1e-12)

    result = bayesfric.size(fit, at={"velocity": (0.5, "rad/s")}, confidence=0.9)
    a = result.dataset.sel(law=fitted.name, point=0)
    assert a["steady_state"].item() == STEADY_NOTE and result.dataset.attrs["steady_state"] == STEADY_NOTE
    sim = np.abs(_long_runs(fitted, post, 0.5, {}))
    for level in (0.05, 0.5, 0.9, 0.95):  # the same draws: the curve's quantiles are the simulated ones'
        np.testing.assert_allclose(a["mean_fn"].sel(quantile=level), np.quantile(sim, level), rtol=1e-8)
    # with noise: the fraction of (simulated value + the draw's noise) below each sized quantile is
    # its level, within Monte Carlo error (many noise replicates per draw; S draws sized)
    sigma = np.asarray(post["sigma"].values).reshape(-1)
    replicate = np.abs(sim[:, None] * np.sign(0.5) + sigma[:, None] * rng.normal(size=(sim.size, 400)))
    for level in (0.05, 0.5, 0.9):
        below = float(np.mean(replicate <= float(a["noisy"].sel(quantile=level))))
        assert abs(below - level) < 5 * math.sqrt(level * (1 - level) / sim.size), (level, below)
    text = sizing_text(result)
    assert "steady state" in text and STEADY_NOTE in text
    from bayesfric.report.sizing import records

    assert {r["steady_state"] for r in records(result)} == {STEADY_NOTE}


def sizing_text(result) -> str:
    from bayesfric.report.sizing import text_report

    return text_report(result)


@pytest.mark.parametrize(("study", "at", "inputs", "response"), [
    ("dahl_duplex", {"velocity": "0.1 rad/s", "preload": "30 lbf"}, {"velocity", "preload"}, "torque"),
    ("drum_rollout", {"velocity": "1400 rpm"}, {"velocity"}, "torque"),
])
def test_a_studys_questions_are_asked_of_its_stateful_laws_steady_state(study, at, inputs, response):
    """A study of stateful laws takes questions at the steady inputs (the velocity, which Dahl's
    data do not hold; a coast-down's speed is its response) and a capacity of the quantity sized."""
    from bayesfric.study import STUDIES_DIR, StudyError, load_study
    from bayesfric.study.plan import load_study_data, sizing_questions

    spec = load_study(STUDIES_DIR / f"{study}.toml")
    ds = load_study_data(spec)
    (q,) = sizing_questions(spec, ds, [sizing.make_question(at, 0.99, capacity="5 N*m")])
    assert set(q.at) == inputs and q.capacity.quantity == response
    with pytest.raises(StudyError, match="give a value for every input the laws read"):
        sizing_questions(spec, ds, [sizing.make_question({"time": "1 s"} if study == "dahl_duplex" else
                                                         {"initial_velocity": "10 rad/s"}, 0.99)])


def test_a_coastdown_fit_is_sized_in_torque_with_parameter_uncertainty_only():
    import bayesfric
    from tests.sizing_helpers import hand_fit

    draws = {"T_C": np.array([[0.8, 1.0, 1.2]]), "c_v": np.array([[1e-3, 2e-3, 3e-3]]),
             "sigma": np.array([[0.5, 0.5, 0.5]])}
    fit = hand_fit("coastdown_coulomb_viscous_closed_form", draws,
                   {"time": np.linspace(0, 20, 6), "initial_velocity": np.full(6, 120.0)})
    result = bayesfric.size(fit, at={"velocity": (1400, "rpm")}, capacity=(1.8, "N*m"), confidence=0.9)
    (name,) = [str(k) for k, r in zip(result["law"].values, result["role"].values, strict=True) if r == "law"]
    a = result.dataset.sel(law=name, point=0)
    w = 1400 * 2 * np.pi / 60
    torque = draws["T_C"][0] + draws["c_v"][0] * w
    steady = a["steady_state"].item()
    assert result.response == "torque" and steady.startswith(STEADY_NOTE) and "parameter uncertainty only" in steady
    np.testing.assert_allclose(np.nanmean(result["draws_mean_fn"].sel(component=name, point=0)), torque.mean(),
                               rtol=1e-12)
    np.testing.assert_allclose(a["noisy"].sel(quantile=0.5), a["mean_fn"].sel(quantile=0.5))  # no speed noise
    np.testing.assert_allclose(a["p_exceed"], np.mean(torque > 1.8))
    assert a["distance_velocity"] > 0  # the measured speeds are its tested range
