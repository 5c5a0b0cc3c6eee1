"""Registry-wide contract test: every registered law satisfies the same declaration contract.

Every law runs once on rotary (torque) data and, unless it declares itself rotary-only, once
more on translational (force) data at tribometer scale (µm, µm/s, mN) as its translational
variant (:mod:`bayesfric.laws.variants`).

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
from bayesfric.laws.variants import TRANSLATIONAL, translation_problem
from bayesfric.model import build_program
from bayesfric.quantities import parse_unit

LAWS = all_laws()
N_DRAWS = 64
#: (law, motion kind) for every law on rotary data and every law that also runs translationally.
CASES = [(w, "rotary") for w in LAWS] + [(w, "translational") for w in LAWS if translation_problem(w) is None]
#: Tribometer scale of the translational design: rotary design values (rad, rad/s) times this.
TRIBO = 5e-5


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


def _dataset(law, motion: str = "rotary"):
    design = _design(law)
    n = len(next(iter(design.values())))
    groups = {"run": np.repeat(np.arange(3), n // 3)} if law.trajectory else None
    scale = 100.0 if law.response == "velocity" else 10.0
    response = law.response
    if motion == "translational":  # µm-scale loops, mN forces
        design = {TRANSLATIONAL.get(k, k): v * TRIBO if k in TRANSLATIONAL else v for k, v in design.items()}
        scale, response = 1e-3, TRANSLATIONAL[law.response]
    # a response of the right sign and size: only its scale matters for data-scaled priors
    return make_dataset(design, np.full(n, scale), response_quantity=response, groups=groups,
                        trajectory="run" if law.trajectory else None)


def _prior_draws(law, ds):
    program = build_program(law, ds)
    predictive = Predictive(program.model, num_samples=N_DRAWS)
    draws = predictive(jax.random.PRNGKey(0), **dict(program.model_kwargs, response=None))
    return program, {k: draws[k] for k in program.law.params}


@pytest.fixture(scope="module", params=CASES, ids=[f"{w.name}-{m}" for w, m in CASES])
def law_case(request):
    """(the law as it runs on the case's data, its program, prior draws of its parameters)."""
    law, motion = request.param
    ds = _dataset(law, motion)
    program, params = _prior_draws(law, ds)
    assert program.law.response == ds.attrs["response"]
    return program.law, program, params


def _direction(law) -> str | None:
    return next((q for q in ("velocity", "linear_velocity") if q in law.inputs), None)


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
    elif _direction(law):
        v = program.inputs[_direction(law)]
        bad = np.sign(out) * np.sign(v) < 0
    else:
        bad = out < -1e-9
    assert not bad.any(), f"{law.name}: {bad.mean():.1%} of prior-predictive means have the wrong sign"


def test_odd_in_velocity(law_case):
    law, program, params = law_case
    if not _direction(law) or law.trajectory or law.response not in ("torque", "force"):
        pytest.skip("only steady-state velocity laws are odd in velocity")
    p0 = {k: v[0] for k, v in params.items()}
    flipped = dict(program.inputs, **{_direction(law): -program.inputs[_direction(law)]})
    a = np.asarray(law.mean(program.inputs, p0, program.constants))
    b = np.asarray(law.mean(flipped, p0, program.constants))
    np.testing.assert_allclose(a, -b, rtol=1e-12, atol=1e-12)


def test_translational_form_follows_the_rotary_declaration():
    """Units map N·m → N and rad → m, the response to force, the inputs to their counterparts."""
    for law, motion in CASES:
        if motion != "translational":
            continue
        moved = build_program(law, _dataset(law, motion)).law
        assert moved.response == "force" and moved.recipe["motion"] == "translational"
        assert set(moved.operating_inputs) == {TRANSLATIONAL.get(q, q) for q in law.operating_inputs}
        for name, p in moved.params.items():
            rotary = law.params[name]
            # same dimension as the rotary unit with torque -> force (÷ m) and angle -> length (× m)
            rad = parse_unit(rotary.unit)._units.get("radian", 0)
            torque = parse_unit(rotary.unit)._units.get("newton", 0)
            expected = parse_unit(rotary.unit) * parse_unit("m") ** (rad - torque) / parse_unit("rad") ** rad
            assert parse_unit(p.unit).dimensionality == expected.dimensionality, (law.name, name, p.unit)
            assert all(k not in ("velocity", "angle") for k in p.prior.scaled_by), (law.name, name)


def test_rotary_only_laws_say_why():
    """Laws that cannot run translationally give a reason (declared, or read from their inputs)."""
    for law in LAWS:
        problem = translation_problem(law)
        assert problem is None or problem.strip(), law.name
        if law.family in ("bearing", "thermal", "drum"):
            assert problem, f"{law.name}: a geometry-specific rotary law must stay rotary-only"
