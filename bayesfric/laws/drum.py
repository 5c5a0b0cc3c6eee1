"""Law family 'drum': friction of a conveyor drum motor (seed 003) and its coast-down dynamics.

Seed 003 models the bearings and O-ring seals of a drum motor and identifies their friction from
roll-out (coast-down) tests: a return pulley is spun up and left to decelerate under friction
alone. This module declares

* the O-ring law τ = k_o ω + τ_o0 (Eq. 6) as names only: it is Coulomb + viscous, so ``oring``
  and ``coastdown_oring_closed_form`` are thin aliases (τ_o0 = T_C, k_o = c_v), see
  :data:`ORING_ALIASES`;
* the rolling friction of a radially loaded ball bearing from per-ball normal forces (Eq. 1–5),
  which gives both the torque against radial load and its ripple with the ball-set angle;
* a smooth non-parametric torque–speed law, the Bayesian counterpart of the seed's look-up tables;
* coast-down laws J dω/dt = −T_f(ω) whose observations are speed trajectories ω(t): closed forms
  for Coulomb + viscous and for Coulomb alone, and :func:`coastdown`, a factory that turns any
  registered velocity law into a coast-down law integrated with diffrax.

Inertia
-------
Only T_f/J is observable in a coast-down, so J is a fixed constant (:data:`DRUM_INERTIA`).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import replace

import jax
import jax.numpy as jnp

from bayesfric.laws import classical
from bayesfric.laws.base import (
    REGISTRY,
    TRAJECTORY_START,
    Constant,
    Law,
    LawDeclarationError,
    Param,
    law,
)
from bayesfric.numerics import positive_power
from bayesfric.priors import DataScale, Prior

#: Why these laws run on rotary (torque) data only (bayesfric.laws.variants).
_ROTARY = "the drum motor's rolling bearings and O-rings (seed 003): ball geometry, shaft speed"

__all__ = [
    "DRUM_INERTIA",
    "DRUM_BEARING",
    "SPLINE_KNOTS",
    "coastdown",
    "coulomb_viscous_coastdown",
    "integrate_coastdown",
    "seed_ball_normal_forces",
    "spline_knot_speeds",
    "pchip",
]

SEED = "seed 003 (drum motor for wear-out modelling)"
_GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"

#: Moment of inertia of a drum shell in kg·m² (assumed; the seed gives none). A return pulley of
#: 113 mm diameter and 0.5 m face width with a 4 mm steel tube weighs
#: π·0.113·0.5·0.004·7850 ≈ 5.6 kg, so J_tube = m r² ≈ 5.6·0.0565² ≈ 0.018 kg·m²; end caps,
#: bearing outer rings and the seals add about 10 %, hence 0.02 kg·m². The simulated roll-out
#: data sets use the same number.
DRUM_INERTIA = 0.02
INERTIA = Constant(
    DRUM_INERTIA, "kg*m^2", "drum-shell moment of inertia (assumed, see DRUM_INERTIA)"
)

# --- O-ring law (Eq. 6) ---------------------------------------------------------------------------
#: Seed 003's O-ring law τ = k_o ω + τ_o0 sign(ω) (Eq. 6) *is* Coulomb + viscous with τ_o0 = T_C
#: and k_o = c_v, so it is not declared again: its names are thin aliases (registered by
#: :mod:`bayesfric.laws` with :func:`bayesfric.laws.variants.alias`) of the one declaration.
ORING_NOTES = (f"{SEED}, Eq. 6 (O-ring friction τ = k_o ω + τ_o0): the seed's k_o is c_v and its τ_o0 is "
               "T_C. §4 reports ≈ 0.95 N·m (bearings + O-rings) and ≈ 0.1 N·m per 1000 rpm "
               "(9.5e-4 N·m·s/rad).")
ORING_ALIASES = {
    "oring": {"base": "coulomb_viscous"},
    "coastdown_oring_closed_form": {"base": "coastdown_coulomb_viscous_closed_form"},
}


# --- rolling friction of a radially loaded ball bearing (Eq. 1–5) ---------------------------------
#: Deep-groove ball bearing 6205 (ISO 15: d = 25 mm, D = 52 mm), 9 balls of 7.938 mm on a
#: 38.5 mm pitch circle; raceway radii r_in/out = 19.25 ∓ 3.97 mm. Assumed: the seed names no size.
DRUM_BEARING = {"n_balls": 9, "r_in": 0.01528, "r_out": 0.02222}
N_BALLS = Constant(float(DRUM_BEARING["n_balls"]), "1", "number of balls (6205, assumed)")
R_IN = Constant(DRUM_BEARING["r_in"], "m", "inner raceway radius (6205, assumed)")
R_OUT = Constant(DRUM_BEARING["r_out"], "m", "outer raceway radius (6205, assumed)")


def seed_ball_normal_forces(radial_force, angle, n_balls: int):
    """Per-ball normal forces of seed 003 Eq. 1–3 for a radial load.

    Ball i sits at φ_i = angle + 2πi/Z from the load direction. Balls with cos φ_i > 0 carry
    F_N^i = F̃ cos^(3/2) φ_i (Eq. 1), with F̃ = F_B / Σ sqrt(cos φ_i) (Eq. 3) so that the partial
    forces F_B^i = F̃ sqrt(cos φ_i) (Eq. 2) add up to F_B.

    This is the seed's own closure, kept as published. The textbook (Stribeck) equilibrium
    instead balances the radial projections, Σ F_N^i cos φ_i = F_B. Then Σ F_N^i differs by the
    factor Σ cos^(5/2)/Σ cos^(1/2) (≈ 0.60 for many balls), which a fitted k_R absorbs; the
    ripple shapes differ slightly.
    :mod:`bayesfric.laws.ball_loads` (combined loads, fixed ball positions) cannot be reused here
    because it has no ball-set angle and uses the textbook equilibrium.

    Parameters
    ----------
    radial_force : array_like
        Radial (belt) force F_B in N.
    angle : array_like
        Ball-set (cage) angle in rad, measured from the load direction to ball 0.
    n_balls : int
        Number of balls Z.

    Returns
    -------
    jax.Array
        Shape ``broadcast(radial_force, angle).shape + (n_balls,)``, normal forces in N.
    """
    radial_force, angle = jnp.broadcast_arrays(jnp.asarray(radial_force, float),
                                               jnp.asarray(angle, float))
    phi = angle[..., None] + 2.0 * jnp.pi * jnp.arange(n_balls) / n_balls
    cos = jnp.cos(phi)
    weight = positive_power(cos, 0.5)
    f_tilde = radial_force / jnp.sum(weight, axis=-1)
    return f_tilde[..., None] * positive_power(cos, 1.5)


@law(
    name="drum_ball_rolling",
    family="drum",
    rotary_only=_ROTARY,
    inputs=("radial_force", "angle"),
    response="torque",
    source=f"{SEED}, Eq. 1–4 (Hertz ball loads, rolling friction per ball), Eq. 5 (ball angle)",
    params={
        "k_R": Param(
            "1",
            Prior("LogNormal", loc=-6.5, scale=0.75),  # median 1.5e-3, 90 % in [4.4e-4, 5.1e-3]
            "rolling friction factor, equal on both rings (k_R,in = k_R,out)",
            "SKF rolling bearings catalogue, constant friction coefficient μ ≈ 0.0015 of "
            "deep-groove ball bearings (M = μ P d/2); seed 003 Eq. 4",
        ),
        "tau_0": Param(
            "N*m",
            Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
            "load-independent bearing torque (grease, seals; Modelica BearingFriction part)",
            f"{SEED} §3.1 and Fig. 7 (0.2–0.3 N·m without O-rings); {_GENERIC}",
        ),
    },
    constants={"n_balls": N_BALLS, "r_in": R_IN, "r_out": R_OUT},
    notes=(
        "Returns the magnitude of the friction torque (Eq. 4). Only r_in k_in + r_out k_out enters "
        "for undamaged rings, so one factor k_R serves both rings; separate ring factors are not "
        "identifiable. k_R needs a load sweep to separate from tau_0. The angle input is the "
        "ball-set angle; ring-relative ball angles of Eq. 5 (φ_cage = φ_in·r_in/(r_in + r_out) "
        "for a fixed outer ring) matter only for localised damage, which is not modelled."
    ),
)
def drum_ball_rolling(radial_force, angle, k_R, tau_0, n_balls, r_in, r_out):
    """Bearing torque from per-ball rolling friction: τ = τ_0 + Σ_i F_N^i k_R (r_in + r_out)."""
    normal = seed_ball_normal_forces(radial_force, angle, int(n_balls))
    return tau_0 + k_R * (r_in + r_out) * jnp.sum(normal, axis=-1)


# --- non-parametric torque–speed law (look-up-table counterpart) ----------------------------------
SPLINE_KNOTS = 8
SPLINE_MAX_SPEED = Constant(
    float(1000 * 2 * math.pi / 60), "rad/s",
    "speed of the last knot (1000 rpm; set to the data's top speed; constant torque beyond)",
)


def spline_knot_speeds(max_speed, n_knots: int = SPLINE_KNOTS):
    """Knot speeds ω_k = ω_max (k/(K−1))², k = 0..K−1 (uniform in sqrt(ω): dense at low speed)."""
    return max_speed * (jnp.arange(n_knots) / (n_knots - 1)) ** 2


def _safe_div(a, b):
    nonzero = b != 0
    return jnp.where(nonzero, a / jnp.where(nonzero, b, 1.0), 0.0)


def _pchip_end_slope(h0, h1, d0, d1):
    """Three-point end slope with the Fritsch–Carlson limits (as scipy's PchipInterpolator)."""
    m = _safe_div((2 * h0 + h1) * d0 - h0 * d1, h0 + h1)
    m = jnp.where(jnp.sign(m) != jnp.sign(d0), 0.0, m)
    return jnp.where((jnp.sign(d0) != jnp.sign(d1)) & (jnp.abs(m) > 3 * jnp.abs(d0)), 3 * d0, m)


def pchip(x, knots, values):
    """Monotone piecewise-cubic Hermite interpolation (Fritsch & Carlson 1980), JAX.

    Matches ``scipy.interpolate.PchipInterpolator`` inside the knot range; outside it the end
    values are held constant. C¹, differentiable in ``values``.

    Parameters
    ----------
    x : array_like
        Evaluation points.
    knots : array_like
        Strictly increasing knot positions, shape (K,), K ≥ 3.
    values : array_like
        Values at the knots, shape (K,).

    Returns
    -------
    jax.Array
        Interpolated values, shape of ``x``.
    """
    h = jnp.diff(knots)
    d = jnp.diff(values) / h
    w1, w2 = 2 * h[1:] + h[:-1], h[1:] + 2 * h[:-1]
    same_sign = d[:-1] * d[1:] > 0
    harmonic = _safe_div(w1 + w2, _safe_div(w1, d[:-1]) + _safe_div(w2, d[1:]))
    interior = jnp.where(same_sign, harmonic, 0.0)
    first = _pchip_end_slope(h[0], h[1], d[0], d[1])
    last = _pchip_end_slope(h[-1], h[-2], d[-1], d[-2])
    slopes = jnp.concatenate([first[None], interior, last[None]])
    xc = jnp.clip(jnp.asarray(x, float), knots[0], knots[-1])
    i = jnp.clip(jnp.searchsorted(knots, xc, side="right") - 1, 0, knots.shape[0] - 2)
    t = (xc - knots[i]) / h[i]
    h00, h10 = (1 + 2 * t) * (1 - t) ** 2, t * (1 - t) ** 2
    h01, h11 = t**2 * (3 - 2 * t), t**2 * (t - 1)
    left = h00 * values[i] + h10 * h[i] * slopes[i]
    return left + h01 * values[i + 1] + h11 * h[i] * slopes[i + 1]


@law(
    name="drum_torque_spline",
    family="drum",
    rotary_only=_ROTARY,
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, §3.2 and §4 (look-up tables of measured torque over speed)",
    params={
        "level": Param("N*m", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
                       "friction torque at the first knot (zero speed)",
                       f"{SEED} Fig. 7–8; {_GENERIC}"),
        "tau": Param("1", Prior("HalfNormal", scale=0.3),
                     "random-walk step scale of log torque between knots (smoothness)",
                     "smoothing prior: a step of 0.3 in log torque (±35 %) per knot is generous "
                     "for the smooth curves of seed 003 Fig. 7–8"),
        "z": Param("1", Prior("Normal", loc=0.0, scale=1.0),
                   "standardised random-walk increments (non-centred)",
                   "non-centred random walk (Papaspiliopoulos et al. 2007)",
                   shape=(SPLINE_KNOTS - 1,)),
    },
    constants={"max_speed": SPLINE_MAX_SPEED},
    notes=(
        "Knot torques T_k = level·exp(tau·cumsum(z)): a random walk in log torque, positive by "
        "construction; monotone-cubic (PCHIP, C¹) interpolation keeps the torque between "
        "neighbouring knot values and gives coast-down integrators a smooth right-hand side. "
        "Knots beyond the largest tested speed are set by the prior alone, and the law is held "
        "constant above max_speed (no extrapolation of trends). tau and the z "
        "increments trade off (only tau·z is seen by the data)."
    ),
)
def drum_torque_spline(velocity, level, tau, z, max_speed):
    """Monotone-cubic (PCHIP) torque over speed on K knots, log random-walk prior, odd in ω."""
    log_steps = jnp.concatenate([jnp.zeros(1), jnp.cumsum(tau * z)])
    knot_torque = level * jnp.exp(log_steps)
    return jnp.sign(velocity) * pchip(jnp.abs(velocity), spline_knot_speeds(max_speed), knot_torque)


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


_COASTDOWN_NOTES = (
    "Only T_f/J is identified from a coast-down, so J is a fixed constant (DRUM_INERTIA); the "
    "friction parameters are in absolute units only as far as J is right (they scale with J). "
    "Speeds above the largest initial velocity are not probed. "
)
_COASTDOWN_SOURCE = f"{SEED}, §4 (roll-out tests: J dω/dt = −T_f(ω))"


def _closed_form_coastdown(name: str, friction: Law, notes: str):
    """The ``@law`` declaration shared by the closed-form coast-downs of a steady-state law."""
    return law(
        name=name,
        family="drum",
        inputs=COASTDOWN_INPUTS,
        response="velocity",
        source=f"{_COASTDOWN_SOURCE}; friction: {friction.source}",
        params=_coastdown_params(friction, DRUM_INERTIA),
        constants={"J": INERTIA},
        trajectory=True,
        notes=_COASTDOWN_NOTES + notes,
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
    existing = REGISTRY.get(f"coastdown_{base.name}")
    if existing is not None:
        registered_j = existing.constants.get("J")
        if registered_j is None or registered_j.value != float(inertia):
            raise LawDeclarationError(
                f"coastdown_{base.name} is registered already (J = {getattr(registered_j, 'value', None)}); "
                "set another inertia through the constant J (study: constants = { J = ... })")
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
    )(integrate)


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
