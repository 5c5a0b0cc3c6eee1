"""The law contract: the checks every registered law passes, for the registry's tests and for yours.

:func:`check_law` runs a law on a generic operating envelope of the quantities it reads (rotary
torque data and, unless the law is rotary-only, translational force data at tribometer scale:
µm, µm/s, mN, as its translational variant, :mod:`bayesfric.laws.variants`) and checks that

- its declaration is complete: units parse, every parameter has a prior, a meaning and a source;
- its mean function is jit-able, finite over draws from the prior and equal to its eager value;
- its gradient with respect to every parameter is finite over those draws;
- it broadcasts over input shapes (steady laws);
- its prior-predictive mean has the physically right sign: friction opposes motion, load-only
  laws are non-negative, coast-down speeds are non-negative (a law declared not sign-definite
  must say why in its notes);
- a steady velocity law is odd in velocity;
- with its scalar parameters varying between levels of the rows (group terms), each row gets its
  level's mean;
- its translational form maps the units and the priors' data scaling as declared.

``tests/laws/test_contract.py`` runs the same functions over every registered law.

Example
-------
>>> from bayesfric.laws import get_law
>>> from bayesfric.testing import check_law
>>> "rotary: prior-predictive sign" in check_law(get_law("coulomb"), draws=8)
True
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from numpyro.infer import Predictive

from bayesfric.datasets.synthetic import make_dataset
from bayesfric.laws.base import TRAJECTORY_START, Law
from bayesfric.laws.variants import TRANSLATIONAL, translation_problem
from bayesfric.model import Program, build_program
from bayesfric.quantities import parse_unit

__all__ = ["check_law", "LawContractError", "design", "contract_dataset", "prior_draws", "CHECKS",
           "check_declaration", "check_mean", "check_gradient", "check_broadcasting", "check_prior_sign",
           "check_odd", "check_translational_form", "check_group_terms"]

#: Tribometer scale of the translational design: rotary design values (rad, rad/s) times this.
TRIBO = 5e-5


class LawContractError(AssertionError):
    """A law that breaks the contract: the message names the law and the check."""


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise LawContractError(message)


def design(law: Law, n_traj: int = 3, per_traj: int = 40) -> dict[str, np.ndarray]:
    """A generic operating envelope in SI units for the quantities ``law`` reads."""
    n = n_traj * per_traj
    rng = np.random.default_rng(0)
    k = np.arange(per_traj)
    loop = 1 - 4 * np.abs(((k / per_traj) + 0.25) % 1 - 0.5)  # triangular drive, one loop per trajectory
    fixed = {
        "angle": lambda: np.tile(0.2 * loop, n_traj), "displacement": lambda: np.tile(1e-3 * loop, n_traj),
        "time": lambda: np.tile(np.linspace(0.0, 20.0, per_traj), n_traj),
        "initial_velocity": lambda: np.repeat(np.linspace(50.0, 150.0, n_traj), per_traj),
        "temperature": lambda: rng.uniform(292.0, 311.0, n),
        "bending_moment": lambda: np.tile(np.linspace(0.0, 6e6, per_traj), n_traj),
        "axial_force": lambda: rng.uniform(0.0, 2e5, n), "radial_force": lambda: rng.uniform(0.0, 2e5, n),
        "preload": lambda: np.repeat(np.linspace(27.0, 160.0, n_traj), per_traj),
        "linear_velocity": lambda: np.linspace(-0.5, 0.5, n),
        "normal_force": lambda: np.repeat(np.linspace(5.0, 50.0, n_traj), per_traj),
    }
    out: dict[str, np.ndarray] = {}
    for q in law.inputs:
        if q == TRAJECTORY_START:
            continue
        if q == "velocity":
            speeds = np.geomspace(0.005, 4.0, n)
            out[q] = np.where(np.arange(n) % 2 == 0, speeds, -speeds)
        elif q in fixed:
            out[q] = fixed[q]()
        else:  # pragma: no cover - a new vocabulary entry needs a design here
            raise LawContractError(f"the contract has no design for input {q!r}")
    return out


def contract_dataset(law: Law, motion: str = "rotary"):
    """The data set of :func:`design` with a response of the right sign and size for ``law``."""
    values = design(law)
    n = len(next(iter(values.values())))
    groups = {"run": np.repeat(np.arange(3), n // 3)} if law.trajectory else None
    scale = 100.0 if law.response == "velocity" else 10.0
    response = law.response
    if motion == "translational":  # µm-scale loops, mN forces
        values = {TRANSLATIONAL.get(k, k): v * TRIBO if k in TRANSLATIONAL else v for k, v in values.items()}
        scale, response = 1e-3, TRANSLATIONAL[law.response]
    return make_dataset(values, np.full(n, scale), response_quantity=response, groups=groups,
                        trajectory="run" if law.trajectory else None)


def prior_draws(law: Law, ds, draws: int = 64) -> tuple[Program, dict[str, jax.Array]]:
    """The program of ``law`` on ``ds`` and ``draws`` prior draws of its parameters."""
    program = build_program(law, ds)
    predictive = Predictive(program.model, num_samples=draws)
    sample = predictive(jax.random.PRNGKey(0), **dict(program.model_kwargs, response=None))
    return program, {k: sample[k] for k in program.law.params}


def check_declaration(law: Law) -> None:
    """Summary, source and family; every unit parses; every parameter has a prior, meaning and source."""
    _require(bool(law.summary and law.source and law.family), f"{law.name}: needs a summary, source and family")
    for name, p in law.params.items():
        parse_unit(p.unit)
        _require(bool(p.meaning and p.source), f"{law.name}: parameter {name!r} needs a meaning and a source")
        _require(bool(str(p.prior)), f"{law.name}: parameter {name!r} has no printable prior")
    for c in law.constants.values():
        parse_unit(c.unit)


def _means(program: Program, params) -> np.ndarray:
    return np.asarray(jax.jit(jax.vmap(lambda p: program.law.mean(program.inputs, p, program.constants)))(params))


def check_mean(program: Program, params) -> None:
    """The mean function, jit-compiled over prior draws: finite, and equal to its eager value."""
    law = program.law
    out = _means(program, params)
    n_draws = len(next(iter(params.values())))
    _require(out.shape == (n_draws, program.n_obs), f"{law.name}: mean of shape {out.shape}, "
                                                     f"expected {(n_draws, program.n_obs)}")
    _require(bool(np.all(np.isfinite(out))), f"{law.name}: non-finite mean for prior draws")
    eager = np.asarray(law.mean(program.inputs, {k: v[0] for k, v in params.items()}, program.constants))
    _require(np.allclose(eager, out[0], rtol=1e-9, atol=1e-12), f"{law.name}: jit-compiled mean differs from eager")


def check_gradient(program: Program, params) -> None:
    """The gradient of the summed squared mean with respect to every parameter is finite."""
    law = program.law

    def loss(p):
        return jnp.sum(law.mean(program.inputs, p, program.constants) ** 2)

    grad = jax.jit(jax.vmap(jax.grad(loss)))(params)
    for name, g in grad.items():
        _require(bool(np.all(np.isfinite(np.asarray(g)))), f"{law.name}: non-finite gradient wrt {name}")


def check_broadcasting(program: Program, params) -> str | None:
    """A steady law evaluated on (n/2, 2) inputs gives the flat result reshaped; None if it passed,
    else why it does not apply."""
    law = program.law
    if law.trajectory:
        return "trajectory laws scan along one ordered axis; batching is by vmap (check_mean)"
    p0 = {k: v[0] for k, v in params.items()}
    flat = np.asarray(law.mean(program.inputs, p0, program.constants))
    n = program.n_obs
    grid = np.asarray(law.mean({k: np.asarray(v).reshape(n // 2, 2) for k, v in program.inputs.items()}, p0,
                               program.constants))
    _require(grid.shape == (n // 2, 2), f"{law.name}: does not broadcast over input shapes ({grid.shape})")
    _require(np.allclose(grid.ravel(), flat, rtol=1e-12), f"{law.name}: reshaped inputs change the mean")
    return None


def _direction(law: Law) -> str | None:
    return next((q for q in ("velocity", "linear_velocity") if q in law.inputs), None)


def check_prior_sign(program: Program, params) -> str | None:
    """Prior-predictive means have the physically right sign; None if it passed, else why it does
    not apply."""
    law = program.law
    if not law.sign_definite:
        _require(bool(law.notes), f"{law.name} is not sign-definite and must say why in its notes")
        return "not sign-definite (its notes say why)"
    out = _means(program, params)
    if law.response == "velocity":
        bad = out < -1e-9
    elif law.trajectory:
        return "hysteresis torque follows the loop, not the instantaneous velocity sign"
    elif _direction(law):
        bad = np.sign(out) * np.sign(program.inputs[_direction(law)]) < 0
    else:
        bad = out < -1e-9
    _require(not bad.any(), f"{law.name}: {bad.mean():.1%} of prior-predictive means have the wrong sign")
    return None


def check_odd(program: Program, params) -> str | None:
    """A steady velocity law is odd in velocity; None if it passed, else why it does not apply."""
    law = program.law
    if not _direction(law) or law.trajectory or law.response not in ("torque", "force"):
        return "only steady-state velocity laws are odd in velocity"
    p0 = {k: v[0] for k, v in params.items()}
    flipped = dict(program.inputs, **{_direction(law): -program.inputs[_direction(law)]})
    a = np.asarray(law.mean(program.inputs, p0, program.constants))
    b = np.asarray(law.mean(flipped, p0, program.constants))
    _require(np.allclose(a, -b, rtol=1e-12, atol=1e-12), f"{law.name}: not odd in velocity")
    return None


def check_translational_form(law: Law) -> str | None:
    """Units map N·m → N and rad → m, the response to force, the inputs to their counterparts, and
    no prior is scaled by a rotary input; None if it passed, else why it does not apply."""
    if (problem := translation_problem(law)) is not None:
        _require(bool(problem.strip()), f"{law.name}: a rotary-only law must say why")
        return f"rotary only: {problem}"
    moved = build_program(law, contract_dataset(law, "translational")).law
    _require(moved.response == "force" and moved.recipe.get("motion") == "translational",
             f"{law.name}: its translational form predicts {moved.response}")
    _require(set(moved.operating_inputs) == {TRANSLATIONAL.get(q, q) for q in law.operating_inputs},
             f"{law.name}: translational inputs {moved.operating_inputs}")
    for name, p in moved.params.items():
        rotary = parse_unit(law.params[name].unit)
        rad, torque = rotary._units.get("radian", 0), rotary._units.get("newton", 0)
        expected = rotary * parse_unit("m") ** (rad - torque) / parse_unit("rad") ** rad
        _require(parse_unit(p.unit).dimensionality == expected.dimensionality,
                 f"{law.name}: translational unit of {name!r} is {p.unit}")
        _require(all(k not in ("velocity", "angle") for k in p.prior.scaled_by),
                 f"{law.name}: translational prior of {name!r} is scaled by a rotary input")
    return None


def check_group_terms(program: Program, params) -> str | None:
    """Group terms (:meth:`Law.vary_by <bayesfric.laws.base.Law.vary_by>`): every scalar parameter
    varying between two levels of the rows gives, at each row, the law's mean with that row's
    level's values -- checked against the law evaluated once per level (a steady law reads the
    values per row, a trajectory law is evaluated per level: :func:`bayesfric.hierarchy.law_mean`)."""
    from bayesfric.hierarchy import law_mean

    law = program.law
    scalar = [k for k, p in law.params.items() if not p.shape]
    if not scalar:
        return "no scalar parameter to vary"
    level = (np.arange(program.n_obs) // max(1, program.n_obs // 4)) % 2  # blocks of rows alternate
    first, drawn = ({k: v[i] for k, v in params.items()} for i in (0, 1))
    second = first | {k: drawn[k] for k in scalar}  # the levels differ in the scalar parameters only
    values = dict(first) | {k: jnp.stack([first[k], second[k]]) for k in scalar}
    varying = dataclasses.replace(law, recipe={**law.recipe, "vary_by": {"level": scalar}})
    mixed = np.asarray(law_mean(varying, program.inputs, values, program.constants, {"level": jnp.asarray(level)}))
    each = [np.asarray(law.mean(program.inputs, p, program.constants)) for p in (first, second)]
    expected = np.where(level == 0, np.broadcast_to(each[0], level.shape), np.broadcast_to(each[1], level.shape))
    _require(np.allclose(mixed, expected, rtol=1e-9, atol=1e-12),
             f"{law.name}: with parameters varying by level, a row's mean differs from its level's law")
    return None


#: The checks of one program (law on one data set), by name, in the order :func:`check_law` runs them.
CHECKS = {"mean finite and jit-able": check_mean, "gradient finite": check_gradient,
          "broadcasting": check_broadcasting, "prior-predictive sign": check_prior_sign,
          "odd in velocity": check_odd, "group terms": check_group_terms}


def check_law(law: Law, draws: int = 64) -> list[str]:
    """Run the registry's contract on ``law`` (module docstring).

    Parameters
    ----------
    law : Law
        A declared law (registered or not; a variant).
    draws : int
        Prior draws the numerical checks run over.

    Returns
    -------
    list of str
        The checks that ran and passed (``"rotary: gradient finite"`` ...); checks that do not
        apply to the law are left out.

    Raises
    ------
    LawContractError
        The first check that fails, naming the law and what is wrong.
    """
    check_declaration(law)
    passed = ["declaration"]
    motions = ["rotary"] + (["translational"] if translation_problem(law) is None else [])
    for motion in motions:
        program, params = prior_draws(law, contract_dataset(law, motion), draws)
        passed += [f"{motion}: {name}" for name, check in CHECKS.items() if check(program, params) is None]
    if check_translational_form(law) is None:
        passed.append("translational form")
    return passed
