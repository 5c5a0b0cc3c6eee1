"""Coast-down laws of the drum family (seed 003): J dω/dt = −T_f(ω), observed as speed
trajectories ω(t) of roll-out tests (a return pulley spun up and left to decelerate under friction
alone).

Closed forms for Coulomb + viscous and for Coulomb alone, and :func:`coastdown`, a factory that
turns any registered steady-state velocity law into a coast-down law integrated with diffrax
(:func:`integrate_coastdown`). The drum's other laws (O-rings, ball rolling, the spline law) are in
:mod:`bayesfric.laws.drum`, which imports this module and re-exports its public names.

Inertia
-------
Only T_f/J is observable in a coast-down, so J is a fixed constant (:data:`DRUM_INERTIA`).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import replace

import jax
import jax.numpy as jnp

from bayesfric.laws import classical
from bayesfric.laws.base import REGISTRY, TRAJECTORY_START, Constant, Law, LawDeclarationError, Param, Steady, law
from bayesfric.priors import DataScale, Prior

__all__ = ["SEED", "DRUM_INERTIA", "INERTIA", "COASTDOWN_INPUTS", "coastdown", "coulomb_viscous_coastdown",
           "integrate_coastdown"]

SEED = "seed 003 (drum motor for wear-out modelling)"

#: Moment of inertia of a drum shell in kg·m² (assumed; the seed gives none). A return pulley of
#: 113 mm diameter and 0.5 m face width with a 4 mm steel tube weighs
#: π·0.113·0.5·0.004·7850 ≈ 5.6 kg, so J_tube = m r² ≈ 5.6·0.0565² ≈ 0.018 kg·m²; end caps,
#: bearing outer rings and the seals add about 10 %, hence 0.02 kg·m². The simulated roll-out
#: data sets use the same number.
DRUM_INERTIA = 0.02
INERTIA = Constant(
    DRUM_INERTIA, "kg*m^2", "drum-shell moment of inertia (assumed, see DRUM_INERTIA)"
)


# --- coast-down dynamics --------------------------------------------------------------------------
COASTDOWN_INPUTS = ("time", "initial_velocity", TRAJECTORY_START)


def coulomb_viscous_coastdown(time, initial_velocity, coulomb, viscous, inertia):
    """Closed-form coast-down of J dω/dt = −(T_C sign ω + c ω).

    ω(t) = (ω0 + T_C/c) e^(−c t/J) − T_C/c until the stop at t_s = (J/c) ln(1 + c ω0/T_C), 0 after;
    written as ω0 e^(−x) + (T_C t/J)·expm1(−x)/x with x = c t/J so that c → 0 gives the pure
    Coulomb ramp ω0 − T_C t/J. Odd in ω0.

    Parameters
    ----------
    time : array_like
        Time since release in s (≥ 0).
    initial_velocity : array_like
        ω0 in rad/s.
    coulomb, viscous : float
        T_C in N·m and c in N·m·s/rad (both ≥ 0).
    inertia : float
        J in kg·m².

    Returns
    -------
    jax.Array
        ω(t) in rad/s.
    """
    x = viscous * time / inertia
    small = x < 1e-8
    x_safe = jnp.where(small, 1.0, x)
    phi = jnp.where(small, -1.0 + 0.5 * x, jnp.expm1(-x_safe) / x_safe)  # expm1(−x)/x
    speed = jnp.abs(initial_velocity) * jnp.exp(-x) + coulomb * time / inertia * phi
    return jnp.sign(initial_velocity) * jnp.maximum(speed, 0.0)


def _coastdown_prior(prior: Prior, inertia: float) -> Prior:
    """Re-express a torque law's data-scaled prior in the scales of a coast-down data set.

    A torque-law prior scaled by R^a X[velocity]^b (R: torque) becomes one scaled by
    (J X[initial_velocity]/X[time])^a X[initial_velocity]^b: a coast-down from ω0 that lasts
    about t_max needs a torque of order J ω0/t_max. J enters with its default value.
    """
    powers = dict(prior.scaled_by)
    a = powers.pop("response", 0.0)
    b = powers.pop("velocity", 0.0)
    if powers:
        raise LawDeclarationError(f"prior {prior} is scaled by inputs other than velocity")
    if not (a or b):
        return prior
    base = Prior(prior.dist, scaled_by={"response": a}, **prior.args) if a else prior
    absolute = base.resolve(DataScale(response=inertia)) if a else Prior(prior.dist, **prior.args)
    scaled = {k: v for k, v in {"initial_velocity": a + b, "time": -a}.items() if v}
    return Prior(absolute.dist, scaled_by=scaled, **absolute.args)


def _coastdown_params(base: Law, inertia: float) -> dict[str, Param]:
    """The base law's parameter declarations with priors re-expressed for coast-down data."""
    return {k: replace(p, prior=_coastdown_prior(p.prior, inertia)) for k, p in base.params.items()}


def _steady(base: Law, params: dict[str, Param], constants: dict[str, Constant]) -> Steady:
    """A coast-down's steady state: its friction law T_f(ω), the torque that would hold the speed
    constant (−J dω/dt along the coast-down at that speed); J plays no part in it."""
    kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
    signature = inspect.Signature([inspect.Parameter(k, kind) for k in ("velocity", *params, *constants)])

    def torque(*args, **kwargs):
        a = signature.bind(*args, **kwargs).arguments
        return base.fn(a["velocity"], *(a[k] for k in params), **{k: a[k] for k in base.constants})

    torque.__signature__ = signature
    return Steady(torque, response="torque", sign_definite=base.sign_definite)


_COASTDOWN_NOTES = (
    "Only T_f/J is identified from a coast-down, so J is a fixed constant (DRUM_INERTIA); the "
    "friction parameters are in absolute units only as far as J is right (they scale with J). "
    "Speeds above the largest initial velocity are not probed. "
)
_COASTDOWN_SOURCE = f"{SEED}, §4 (roll-out tests: J dω/dt = −T_f(ω))"


def _closed_form_coastdown(name: str, friction: Law, notes: str):
    """The ``@law`` declaration shared by the closed-form coast-downs of a steady-state law."""
    params = _coastdown_params(friction, DRUM_INERTIA)
    return law(
        name=name,
        family="drum",
        inputs=COASTDOWN_INPUTS,
        response="velocity",
        source=f"{_COASTDOWN_SOURCE}; friction: {friction.source}",
        params=params,
        constants={"J": INERTIA},
        trajectory=True,
        notes=_COASTDOWN_NOTES + notes,
        steady=_steady(friction, params, {"J": INERTIA}),
    )


@_closed_form_coastdown(
    "coastdown_coulomb_viscous_closed_form", classical.coulomb_viscous,
    "T_C and c_v are separated by the curvature of ω(t) (exponential vs. linear decay); runs from "
    "several ω0 help. Each row carries its own (t, ω0), so trajectory_start is not needed by the "
    "closed form.",
)
def coastdown_coulomb_viscous_closed_form(time, initial_velocity, trajectory_start, T_C, c_v, J):
    """Coast-down under Coulomb + viscous friction, closed form (0 after the stop)."""
    return coulomb_viscous_coastdown(time, initial_velocity, T_C, c_v, J)


def integrate_coastdown(torque: Callable, time, initial_velocity, inertia, *,
                        rtol: float = 1e-10, atol: float = 1e-10):
    """ω(t) of J dω/dt = −T_f(ω), one diffrax solve (Tsit5, adaptive) per row, vmapped.

    The speed magnitude u = |ω| is integrated with du/dt = −T_f(u)/J while u > 0 and 0 after,
    so the drum stops and stays stopped (a Coulomb term does not chatter about zero); the result
    is sign(ω0)·max(u, 0). A solve that fails (step limit) returns NaN, which a sampler rejects.

    Parameters
    ----------
    torque : callable
        Friction torque T_f(ω) in N·m for ω ≥ 0 (an odd friction law).
    time, initial_velocity : array_like
        Time since release (s) and ω0 (rad/s) per row; broadcast together.
    inertia : float
        J in kg·m².
    rtol, atol : float
        Tolerances of the PID step-size controller.

    Returns
    -------
    jax.Array
        ω(t) in rad/s, shape of the broadcast inputs.
    """
    import diffrax  # here, not at module level: ~0.8 s of import that only coast-down laws use

    time, initial_velocity = jnp.broadcast_arrays(jnp.asarray(time, float),
                                                  jnp.asarray(initial_velocity, float))

    def rhs(t, u, args):
        moving = u > 0
        return jnp.where(moving, -torque(jnp.where(moving, u, 1.0)) / inertia, 0.0)

    term = diffrax.ODETerm(rhs)
    solver = diffrax.Tsit5()
    controller = diffrax.PIDController(rtol=rtol, atol=atol)

    def one(t1, w0):
        end = jnp.maximum(t1, 1e-12)  # diffrax needs t1 > t0; the offset is below any tolerance
        sol = diffrax.diffeqsolve(term, solver, 0.0, end, None, jnp.abs(w0),
                                  saveat=diffrax.SaveAt(t1=True), stepsize_controller=controller,
                                  max_steps=4096, throw=False)
        u = jnp.where(sol.result == diffrax.RESULTS.successful, sol.ys[-1], jnp.nan)
        return jnp.sign(w0) * jnp.maximum(u, 0.0)

    out = jax.vmap(one)(time.ravel(), initial_velocity.ravel())
    return out.reshape(time.shape)


def coastdown(velocity_law: Law | str, *, inertia: float = DRUM_INERTIA) -> Law:
    """Coast-down law ``coastdown_<law>`` of any steady-state velocity law, integrated with diffrax.

    The new law reads ``("time", "initial_velocity", "trajectory_start")``, predicts the speed
    ω(t) in rad/s and reuses the base law's parameter declarations (unit, meaning, source), with
    data-scaled priors re-expressed for coast-down data (torque scale J·X[ω0]/X[t]). The base
    law's constants are kept and the inertia ``J`` is added.

    Parameters
    ----------
    velocity_law : Law or str
        A registered law with the single input ``velocity`` and response ``torque``.
    inertia : float
        Default of the constant J (kg·m²); also used to re-express the priors.

    Returns
    -------
    Law
        The registered ``coastdown_<law>``; asked again for the same law and inertia, the law
        registered the first time (a law is declared once).

    Raises
    ------
    LawDeclarationError
        The base law is not a steady-state torque law, or ``coastdown_<law>`` is registered
        already with another default inertia (set ``J`` through the law's constants instead).
    """
    base = velocity_law if isinstance(velocity_law, Law) else REGISTRY[velocity_law]
    if (existing := _registered(base, inertia)) is not None:
        return existing
    if base.inputs != ("velocity",) or base.response != "torque":
        raise LawDeclarationError(
            f"coastdown needs a steady-state law T_f(velocity) -> torque; {base.name!r} reads "
            f"{base.inputs} and predicts {base.response}"
        )
    if "J" in base.constants:
        raise LawDeclarationError(f"law {base.name!r} already has a constant named 'J'")
    params = _coastdown_params(base, inertia)
    constants = {**base.constants, "J": replace(INERTIA, value=float(inertia))}
    return law(
        name=f"coastdown_{base.name}",
        family="drum",
        inputs=COASTDOWN_INPUTS,
        response="velocity",
        source=f"{_COASTDOWN_SOURCE}; friction: {base.source}",
        params=params,
        constants=constants,
        derived=base.derived,
        trajectory=True,
        notes=_COASTDOWN_NOTES + "Rows are integrated independently from their own (t, ω0), so "
        "trajectory_start is accepted but not needed. "
        + (f"Base law: {base.notes}" if base.notes else ""),
        sign_definite=base.sign_definite,
        steady=_steady(base, params, constants),
    )(_integrator(base, params, constants))


def _registered(base: Law, inertia: float) -> Law | None:
    """``coastdown_<base>`` if it is registered already with this default inertia (None if not
    registered); another inertia is a :class:`LawDeclarationError`."""
    existing = REGISTRY.get(f"coastdown_{base.name}")
    if existing is None:
        return None
    registered_j = existing.constants.get("J")
    if registered_j is None or registered_j.value != float(inertia):
        raise LawDeclarationError(
            f"coastdown_{base.name} is registered already (J = {getattr(registered_j, 'value', None)}); "
            "set another inertia through the constant J (study: constants = { J = ... })")
    return existing


def _integrator(base: Law, params: dict[str, Param], constants: dict[str, Constant]) -> Callable:
    """The coast-down law's function: arguments by the declared signature, one compiled solve."""
    kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
    signature = inspect.Signature(
        [inspect.Parameter(k, kind) for k in (*COASTDOWN_INPUTS, *params)]
        + [inspect.Parameter(k, kind, default=c.value) for k, c in constants.items()]
    )

    @jax.jit
    def solve(time, initial_velocity, inertia, values, fixed):
        # compiled once per law, so eager calls and calls inside a sampler's jit agree exactly
        def torque(speed):
            return base.fn(speed, *values, **fixed)

        return integrate_coastdown(torque, time, initial_velocity, inertia)

    def integrate(*args, **kwargs):
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        a = bound.arguments
        return solve(a["time"], a["initial_velocity"], a["J"], tuple(a[k] for k in params),
                     {k: a[k] for k in base.constants})

    integrate.__signature__ = signature
    integrate.__doc__ = (
        f"Coast-down J dω/dt = −T_f(ω) with T_f = law {base.name!r} ({base.summary}), diffrax."
    )
    integrate.__name__ = integrate.__qualname__ = f"coastdown_{base.name}"
    return integrate


# The registered generic coast-down law (checked against the closed form and by recovery). Others
# are built on demand, e.g. coastdown("stribeck") or coastdown("drum_torque_spline"); the knot
# law's adaptive solve agrees between batched and unbatched evaluation only to ~1e-8 (step
# decisions flip on last-bit differences of exp), short of the registry contract's 1e-9.
coastdown_coulomb_viscous = coastdown(classical.coulomb_viscous)
# A Stribeck rise at low speed (the O-rings' breakaway behaviour, seed 003 §4) that the linear
# O-ring law cannot follow. Integrated with diffrax: correct, but the friction's jump at the stop
# makes the adaptive solve slow under NUTS, so the roll-out study uses closed forms instead.
coastdown_stribeck = coastdown(classical.stribeck)


@_closed_form_coastdown("coastdown_coulomb_closed_form", classical.coulomb,
                        "Constant torque: a linear ramp ω0 − T_C t/J to the stop.")
def coastdown_coulomb_closed_form(time, initial_velocity, trajectory_start, T_C, J):
    """Coast-down under constant (Coulomb) friction, closed form: ω0 − T_C t/J, 0 after the stop."""
    return coulomb_viscous_coastdown(time, initial_velocity, T_C, 0.0, J)
