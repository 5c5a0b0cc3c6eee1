"""Registry-wide contract test: every registered law satisfies the same declaration contract.

For each law: units parse, every parameter has a prior/meaning/source, the mean function is
jit-able and differentiable with finite values and gradients over draws from the prior, it
broadcasts over input shapes, and its prior-predictive mean has the physically right sign
(friction opposes motion; load-only laws are non-negative; coast-down speeds are non-negative).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from numpyro.infer import Predictive

from bayesfric.datasets.synthetic import make_dataset
from bayesfric.laws import all_laws
from bayesfric.laws.base import TRAJECTORY_START
from bayesfric.model import build_program
from bayesfric.quantities import parse_unit

LAWS = all_laws()
N_DRAWS = 64


def _design(law, n_traj: int = 3, per_traj: int = 40) -> dict[str, np.ndarray]:
    """A generic operating envelope in SI units for the quantities the law reads."""
    n = n_traj * per_traj
    rng = np.random.default_rng(0)
    k = np.arange(per_traj)
    out: dict[str, np.ndarray] = {}
    for q in law.inputs:
        if q == TRAJECTORY_START:
            continue
        if q == "velocity":
            speeds = np.geomspace(0.005, 4.0, n)
            out[q] = np.where(np.arange(n) % 2 == 0, speeds, -speeds)
        elif q == "angle":  # triangular drive ±0.2 rad, one loop per trajectory
            tri = 0.2 * (1 - 4 * np.abs(((k / per_traj) + 0.25) % 1 - 0.5))
            out[q] = np.tile(tri, n_traj)
        elif q == "displacement":
            tri = 1e-3 * (1 - 4 * np.abs(((k / per_traj) + 0.25) % 1 - 0.5))
            out[q] = np.tile(tri, n_traj)
        elif q == "time":
            out[q] = np.tile(np.linspace(0.0, 20.0, per_traj), n_traj)
        elif q == "initial_velocity":
            out[q] = np.repeat(np.linspace(50.0, 150.0, n_traj), per_traj)
        elif q == "temperature":
            out[q] = rng.uniform(292.0, 311.0, n)
        elif q == "bending_moment":
            out[q] = np.tile(np.linspace(0.0, 6e6, per_traj), n_traj)
        elif q in ("axial_force", "radial_force"):
            out[q] = rng.uniform(0.0, 2e5, n)
        elif q == "preload":
            out[q] = np.repeat(np.linspace(27.0, 160.0, n_traj), per_traj)
        elif q == "linear_velocity":
            out[q] = np.linspace(-0.5, 0.5, n)
        else:  # pragma: no cover - a new vocabulary entry needs a design here
            raise AssertionError(f"contract test has no design for input {q!r}")
    return out


def _dataset(law):
    design = _design(law)
    n = len(next(iter(design.values())))
    groups = {"run": np.repeat(np.arange(3), n // 3)} if law.trajectory else None
    scale = 100.0 if law.response == "velocity" else 10.0
    # a response of the right sign and size: only its scale matters for data-scaled priors
    return make_dataset(design, np.full(n, scale), response_quantity=law.response, groups=groups,
                        trajectory="run" if law.trajectory else None)


def _prior_draws(law, ds):
    program = build_program(law, ds)
    predictive = Predictive(program.model, num_samples=N_DRAWS)
    draws = predictive(jax.random.PRNGKey(0), **dict(program.model_kwargs, response=None))
    return program, {k: draws[k] for k in law.params}


@pytest.fixture(scope="module", params=LAWS, ids=[w.name for w in LAWS])
def law_case(request):
    law = request.param
    ds = _dataset(law)
    program, params = _prior_draws(law, ds)
    return law, program, params


def test_registry_is_populated():
    assert len(LAWS) >= 7
    assert {"coulomb", "coulomb_viscous", "stribeck", "armstrong_helouvry", "joint_tribological",
            "prestressed_roller_bearing", "helical_gear"} <= {w.name for w in LAWS}


def test_declaration_complete(law_case):
    law, _, _ = law_case
    assert law.summary and law.source and law.family
    for name, p in law.params.items():
        parse_unit(p.unit)
        assert p.meaning and p.source, name
        assert str(p.prior)
    for c in law.constants.values():
        parse_unit(c.unit)


def test_mean_finite_and_jittable(law_case):
    law, program, params = law_case
    consts = program.constants

    @jax.jit
    def batch(ps):
        return jax.vmap(lambda p: law.mean(program.inputs, p, consts))(ps)

    out = np.asarray(batch(params))
    assert out.shape == (N_DRAWS, program.n_obs)
    assert np.all(np.isfinite(out)), f"{law.name}: non-finite mean for prior draws"
    eager = np.asarray(law.mean(program.inputs, {k: v[0] for k, v in params.items()}, consts))
    np.testing.assert_allclose(eager, out[0], rtol=1e-9, atol=1e-12)


def test_gradient_finite(law_case):
    law, program, params = law_case

    def loss(p):
        return jnp.sum(law.mean(program.inputs, p, program.constants) ** 2)

    grad = jax.jit(jax.vmap(jax.grad(loss)))(params)
    for name, g in grad.items():
        assert np.all(np.isfinite(np.asarray(g))), f"{law.name}: non-finite gradient wrt {name}"


def test_broadcasting(law_case):
    law, program, params = law_case
    if law.trajectory:
        pytest.skip("trajectory laws scan along one ordered axis; batching is by vmap (tested above)")
    p0 = {k: v[0] for k, v in params.items()}
    flat = np.asarray(law.mean(program.inputs, p0, program.constants))
    n = program.n_obs
    reshaped = {k: np.asarray(v).reshape(n // 2, 2) for k, v in program.inputs.items()}
    grid = np.asarray(law.mean(reshaped, p0, program.constants))
    assert grid.shape == (n // 2, 2)
    np.testing.assert_allclose(grid.ravel(), flat, rtol=1e-12)


def test_prior_predictive_sign(law_case):
    law, program, params = law_case
    out = np.asarray(jax.vmap(lambda p: law.mean(program.inputs, p, program.constants))(params))
    if not law.sign_definite:
        assert law.notes, f"{law.name} is not sign-definite and must say why in its notes"
        return
    if law.response == "velocity":
        bad = out < -1e-9
    elif law.trajectory:
        pytest.skip("hysteresis torque follows the loop, not the instantaneous velocity sign")
    elif "velocity" in law.inputs:
        v = program.inputs["velocity"]
        bad = np.sign(out) * np.sign(v) < 0
    else:
        bad = out < -1e-9
    assert not bad.any(), f"{law.name}: {bad.mean():.1%} of prior-predictive means have the wrong sign"


def test_odd_in_velocity(law_case):
    law, program, params = law_case
    if "velocity" not in law.inputs or law.trajectory or law.response != "torque":
        pytest.skip("only steady-state velocity laws are odd in velocity")
    p0 = {k: v[0] for k, v in params.items()}
    flipped = dict(program.inputs, velocity=-program.inputs["velocity"])
    a = np.asarray(law.mean(program.inputs, p0, program.constants))
    b = np.asarray(law.mean(flipped, p0, program.constants))
    np.testing.assert_allclose(a, -b, rtol=1e-12, atol=1e-12)
