"""Hysteresis (state) laws: Dahl solid friction (seed 001) and LuGre (named in seed 002).

Both laws carry an internal state along ordered trajectories (``jax.lax.scan``) and reset it
where the structural input ``trajectory_start`` is True.

Dahl solid friction model (seed 001, Eq. 3-8)
---------------------------------------------
dF/dx = σ |1 − (F/F_c) sgn ẋ|^i · sgn(1 − (F/F_c) sgn ẋ), with the knee x_c = F_c/σ (Eq. 5).
Along a monotone step of length |Δx| in direction s = sgn Δx, the variable u = 1 − s F/F_c obeys
du/d|x| = −u^i / x_c, whose exact solution over the step (the closed form behind Eq. 4, 6-8 and
the reversal forms Eq. 11-14) is

    u⁺ = [u^(1−i) + (i − 1) |Δx|/x_c]^(1/(1−i))     (i ≠ 1),     u⁺ = u e^(−|Δx|/x_c)   (i = 1).

The law applies this closed form step by step, so the integration is *exact* for every i > 0
(no sub-stepping, no stabilising factor S); the only assumption is that the angle moves
monotonically between successive samples. u stays in [0, 2], i.e. |F| ≤ F_c, by construction.

Initial state: by default each trajectory starts on the saturated branch F = −F_c·sgn(ẋ₀),
opposite to its first motion -- the state a bearing is in after a full sweep in the other
direction, which is how seed 001's triangle-driven loops reach every reversal point and exactly
what its data reduction assumes (Eq. 9-14: f = F_c − F = 2F_c at the rate-reversal point x' = 0).
The constant ``F_start`` (fraction of F_c, default 1) can be set to 0 for a virgin start F = 0
(Eq. 4's initial condition). A trajectory whose first step does not move starts at F = 0.
Caveat: the assumed start value carries information on F_c; data recorded inside a small periodic
loop should use trajectories that begin at a reversal after a saturating sweep, or drop the first
cycle from the likelihood (``mask``).

Preload: one law covers the six preloads of the experiment through F_c(P) = F_c0 (P/P_ref)^γ and
x_c(P) = x_c0 (P/P_ref)^κ. The preload input is optional: on data without a preload column (a
tribometer at one normal load) the law runs with P = P_ref, so both factors are 1, F_c0 and x_c0
are the running friction and knee of the test itself, and γ, κ (which then have no effect) are
fixed at 0 instead of sampled (:class:`bayesfric.laws.base.OptionalInput`).
The state is carried as F/F_c, so a preload change inside a trajectory
(absent from seed 001, where each run holds its preload) rescales the torque instantly.

LuGre (Canudas de Wit, Olsson, Åström & Lischinsky 1995, IEEE TAC 40(3):419-425)
-------------------------------------------------------------------------------------
dz/dt = v − σ0 |v| z / g(v), g(v) = F_c + (F_s − F_c) e^(−(v/v_s)²), F = σ0 z + σ1 dz/dt + σ2 v,
written in rotary units (z in rad, σ0 in N·m/rad, F in N·m). With v held at the midpoint value
v̄ = (v_{k−1} + v_k)/2 over a sample interval h, the ODE is linear in z with constant
coefficients, a = σ0|v̄|/g(v̄), so

    z_k = z_{k−1} e^(−a h) + v̄ h (1 − e^(−a h))/(a h),

exact for piecewise-constant velocity and unconditionally stable however stiff σ0 is (z_k is a
convex combination of z_{k−1} and the steady deflection g(v̄) sgn(v̄)/σ0). The recursion is
affine in z, so it runs as an associative scan. Start state: the constant ``F_start``
(:data:`START_STATE`, the convention Dahl's ``F_start`` uses and the multi-element laws of
:mod:`bayesfric.laws.slip` share): z = −F_start · g(v̄₁) sgn(v̄₁)/σ0 at each trajectory start, v̄₁
the first step's held velocity -- 0 (default) at rest, z = 0; 1 saturated against the first
motion (after a sweep the other way); −1 in steady sliding along it.

Parametrisation. The Stribeck curve is sampled as F_c and the ratio r = F_c/F_s ∈ (0, 1)
(``F_ratio``), not as F_c and F_s − F_c: data at one drive speed v₀ (seed 001's triangle drive)
identify only g(v₀) = F_c (1 + (1/r − 1) e^(−(v₀/v_s)²)), and in (log F_c, logit r, log v_s) that
ridge has the same width everywhere, whereas with F_c and F_s − F_c it narrowed to a funnel where
v_s ≪ v₀ (F_c pinned) and widened where v_s ≳ v₀ (measured on ``dahl_duplex``: tail ESS 254,
divergences at target_accept 0.9). That ridge still bends where v_s crosses v₀: below, F_c is
pinned and r, v_s are free; above, F_c = r·g(v₀) slides with r; between, e^(−(v₀/v_s)²) turns
from 0 to 1 within about one unit of log v_s, and NUTS diverged there (1-2 divergent transitions
per fit at target_accept 0.99, every one at v_s = 0.6-1.05 v₀, tail ESS 213-649, 85-126 leapfrog
steps per draw; seeds 0-2). So the sampler moves F_c on log g(v_ref), the Stribeck curve at the
data's largest speed v_ref (:class:`~bayesfric.laws.base.SampledAs`): at one drive speed that is
the pinned quantity, and the ridge is straight (no divergence at the default target, bulk and
tail ESS ≥ 1400, about 20 steps per draw, same seeds). The model is unchanged -- F_c keeps its
prior and the posterior is the same; only the sampler's coordinate moved. σ0 stays a parameter:
it is g(v₀)/z_ss(v₀), the rest stiffness the loop fixes whatever the split of g. Preload: like
Dahl (seed 001 Fig. 12 and §V, knee independent of preload) the bristle force scales as
(P/P_ref)^γ, F = (P/P_ref)^γ (σ0 z + σ1 ż) + σ2 v; scaling σ0 and g together leaves z unchanged,
so the knee g/σ0 is the same at every preload. On data without a preload column P = P_ref and γ is
fixed at 0 (:class:`OptionalInput`).

What seed 001 says against LuGre on its loops: the triangle drive holds one speed, "well below
those where viscous friction effects would become troublesome" (§III), so F_c, r and v_s are
identified only through g(v₀), σ2 only through the jump 2σ2 v₀ at each reversal, and σ1 not at
all (its transient σ1 ż lasts one knee); their posteriors are their priors along that ridge.
At one speed LuGre's loop is Dahl's i = 1 loop (exponential approach, knee g(v₀)/σ0), which the
report found less accurate than i ≈ 1.5 (§V).
"""

from __future__ import annotations

import inspect
import math

import jax.numpy as jnp
from jax import lax

from bayesfric.laws.base import TRAJECTORY_START, Constant, Derived, OptionalInput, Param, SampledAs, law
from bayesfric.numerics import positive_power, power_ratio
from bayesfric.priors import Prior

__all__ = ["DAHL_LAWS", "dahl_torque", "lugre", "dahl_relax", "lugre_bristle", "START_STATE",
           "held_velocity", "phi1", "dahl_steady", "lugre_steady"]

SEED = "seed 001 (Dahl 1977, solid friction parameters of ball bearings)"
LUGRE = "Canudas de Wit et al. 1995 (LuGre), named in seed 002"
_GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"
LBF = 4.4482216152605  # N per pound-force (exact by definition of the avoirdupois pound)

# --- Dahl: parameters declared once ----------------------------------------------------------
F_c0 = Param(
    "N*m",
    Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
    "running (Coulomb) friction torque F_c at the reference preload P_ref",
    f"{SEED} Eq. 3, Fig. 12; {_GENERIC}",
)
gamma = Param(
    "1",
    Prior("Normal", loc=1.0, scale=0.5),
    "preload exponent of the running friction, F_c ∝ P^γ",
    f"{SEED} Fig. 12 (F_c rises with preload, values illegible in the extraction); Palmgren's "
    "load moment M1 = f1·P1·d_m (seed 000) suggests γ ≈ 1",
)
# Knee: seed 001 Table II (x_c per preload) is illegible in the text extraction. Its order of
# magnitude follows from §III and Fig. 11: the torque meter (0.28 ft·lbf/deg = 54 in·ozf/deg) was
# "about an order of magnitude stiffer than the rest-stiffness of the bearing", so σ ≈ 5.4
# in·ozf/deg; Fig. 11's torque scale (0.356 in·ozf per plotter inch, loop about 7 in high) gives
# 2F_c ≈ 2.5 in·ozf, so x_c = F_c/σ ≈ 1.25/5.4 ≈ 0.23° ≈ 4e-3 rad. LogNormal scale 1.0: 90 % of
# the prior mass within a factor 5 of that.
# On translational data (a tribometer's force-displacement loops) no seed fixes the knee: its
# prior is scaled by the largest displacement, median 5 % of it, 90 % within ~[0.4 %, 60 %].
x_c0 = Param(
    "rad",
    Prior("LogNormal", loc=math.log(4e-3), scale=1.0),
    "knee (characteristic angle) x_c = F_c/σ at the reference preload",
    f"{SEED} Eq. 5, §III (meter vs. bearing rest stiffness), Fig. 11 scales: "
    "x_c ≈ 0.23° ≈ 4e-3 rad; translational: generic, scaled by the largest displacement",
    translational=Prior("LogNormal", loc=math.log(0.05), scale=1.5, scaled_by={"displacement": 1}),
)
kappa = Param(
    "1",
    Prior("Normal", loc=0.0, scale=0.5),
    "preload exponent of the knee, x_c ∝ P^κ",
    f"{SEED} §V: x_c 'approximately constant and independent of preload' (κ ≈ 0)",
)
exponent_i = Param(
    "1",
    Prior("LogNormal", loc=math.log(1.5), scale=0.25),  # median 1.5, 90 % in [1.0, 2.3]
    "SFM exponent i of the friction slope function",
    f"{SEED} §V: i 'approximately constant', average about 1.5; tested range 1-2 (Eq. 6-8)",
)
P_REF = Constant(20.0 * LBF, "N", "reference preload P_ref = 20 lbf (middle of seed 001's 6-36 lb)")
F_START = Constant(1.0, "1", "torque at each trajectory start as a fraction of F_c, against the "
                   "first motion (1: saturated branch, seed 001 Eq. 9-14; 0: virgin F = 0, Eq. 4)")
#: Start state of the velocity-driven state laws (LuGre, GMS, elasto-plastic, Maxwell-slip), Dahl's
#: convention with a relaxed default: fraction of the saturated state, against the first motion.
START_STATE = Constant(0.0, "1", "state at each trajectory start as a fraction of the saturated "
                       "(steady-sliding) state, against the first motion (0: relaxed, zero state; "
                       "1: saturated after a sweep the other way; −1: sliding along the first motion)")
sigma_ref = Derived(lambda F_c0, x_c0: F_c0 / x_c0, "N*m/rad",
                    "rest stiffness σ = F_c/x_c at P_ref (Eq. 5)")

_DAHL_NOTES = (
    "Identifiability (Fisher information of the periodic loop, 100 samples per loop, 1 % noise, "
    "i = 1.5; test_small_loops_do_not_separate_knee_and_running_friction): loops that saturate "
    "(±10 x_c) identify F_c from the asymptote and x_c, i from the knee (|corr| ≤ 0.45). On loops "
    "that never saturate F_c, x_c and i are nearly collinear: with i free at ±0.5 x_c, "
    "corr(log F_c, log x_c) ≈ 0.9999, sd(log F_c) ≈ 0.18; mainly σ = F_c/x_c is identified. "
    "The assumed start F = −F_start·F_c adds F_c information only as good as that assumption. "
    "γ needs ≥ 2 preloads; κ needs ≥ 2 preloads with resolved knees (angle step ≪ x_c). Not "
    "sign-definite in velocity: the torque follows the loop."
)


def dahl_relax(u, distance, i):
    """Exact Dahl relaxation over a monotone step (closed form of Eq. 3; Eq. 4, 6-8, 11-14).

    Parameters
    ----------
    u : array
        ``1 − (F/F_c) sgn ẋ`` before the step, in [0, 2].
    distance : array
        Step length in units of the knee, ``|Δx| / x_c`` (≥ 0).
    i : float or array
        SFM exponent (> 0).

    Returns
    -------
    array
        u after the step: ``u (1 + (i−1) d u^(i−1))^(−1/(i−1))``, ``u e^(−d)`` at i = 1; for
        i < 1, 0 once the branch has saturated in finite distance.
    """
    eps = i - 1.0
    positive = u > 0
    u_safe = jnp.where(positive, u, 1.0)
    y = distance * positive_power(u_safe, eps)
    t = eps * y
    valid = 1.0 + t > 0
    t_safe = jnp.where(valid, t, 0.0)
    near_one = jnp.abs(eps) < 1e-6
    eps_safe = jnp.where(near_one, 1.0, eps)
    # log(1 + εy)/ε, with its series y − εy²/2 + ε²y³/3 where ε → 0 (i = 1 exactly)
    rate = jnp.where(near_one, y - eps * y**2 / 2 + eps**2 * y**3 / 3, jnp.log1p(t_safe) / eps_safe)
    return jnp.where(positive & valid, u_safe * jnp.exp(-rate), 0.0)


def dahl_torque(angle, preload, trajectory_start, F_c0, gamma, x_c0, kappa, i, P_ref, F_start):
    """Dahl friction torque along ordered angle trajectories (exact step update, see module doc).

    Parameters
    ----------
    angle : array, shape (n,)
        Drive angle in rad, ordered within each trajectory.
    preload : array, shape (n,)
        Axial preload in N (> 0).
    trajectory_start : array of bool, shape (n,)
        True at the first sample of each trajectory.
    F_c0, gamma, x_c0, kappa, i, P_ref, F_start
        As declared by the ``dahl*`` laws.

    Returns
    -------
    array, shape (n,)
        Friction torque in N·m.
    """
    angle = jnp.asarray(angle, dtype=float)
    start = jnp.asarray(trajectory_start, dtype=bool)
    preload = jnp.asarray(preload, dtype=float)
    F_c = F_c0 * power_ratio(preload, P_ref, gamma)
    x_c = x_c0 * power_ratio(preload, P_ref, kappa)
    step = jnp.where(start, 0.0, jnp.diff(angle, prepend=angle[:1]))
    direction = jnp.sign(step)
    distance = jnp.abs(step) / x_c
    # F_start·F_c against the first motion of each trajectory (F = 0 if it does not move)
    initial = -F_start * jnp.append(direction[1:], 0.0)

    def advance(phi, row):
        is_start, s, d, phi0 = row
        moved = s * (1.0 - dahl_relax(1.0 - s * phi, d, i))
        phi = jnp.where(is_start, phi0, jnp.where(s == 0, phi, moved))
        return phi, phi

    _, phi = lax.scan(advance, initial[0], (start, direction, distance, initial))
    return F_c * phi


def dahl_steady(velocity, preload, F_c0, gamma, x_c0, kappa, i, P_ref, F_start):
    """Dahl at constant speed: along a monotone run u = 1 − (F/F_c) sgn ẋ relaxes to 0
    (:func:`dahl_relax`, every i > 0), so F = F_c sgn ẋ with F_c = F_c0 (P/P_ref)^γ."""
    return jnp.sign(velocity) * F_c0 * power_ratio(jnp.asarray(preload, dtype=float), P_ref, gamma)


def _signature(names) -> inspect.Signature:
    return inspect.Signature([inspect.Parameter(n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in names])


def _dahl_law(name: str, knee_by_preload: bool):
    """Declare one Dahl law: x_c shared or preload-dependent (the exponent i is fixed by aliases)."""
    params = {"F_c0": F_c0, "gamma": gamma, "x_c0": x_c0}
    constants = {}
    if knee_by_preload:
        params["kappa"] = kappa
    else:
        constants["kappa"] = Constant(0.0, "1", "knee independent of preload (seed 001 §V)")
    params["i"] = exponent_i
    constants["P_ref"] = P_REF
    constants["F_start"] = F_START
    inputs = ("angle", "preload", TRAJECTORY_START)
    signature = _signature([*inputs, *params, *constants])
    steady_signature = _signature(["velocity", "preload", *params, *constants])

    def fn(*args, **kwargs):
        return dahl_torque(**signature.bind(*args, **kwargs).arguments)

    def steady(*args, **kwargs):
        return dahl_steady(**steady_signature.bind(*args, **kwargs).arguments)

    steady.__signature__ = steady_signature

    knee_text = "x_c ∝ P^κ per preload" if knee_by_preload else "one x_c for all preloads"
    fn.__signature__ = signature
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = (f"Dahl solid friction, {knee_text}: dF/dx = σ|1 − (F/F_c) sgn ẋ|^i "
                  "sgn(1 − (F/F_c) sgn ẋ), F_c = F_c0 (P/P_ref)^γ.")
    return law(
        name=name,
        family="hysteresis",
        inputs=inputs,
        response="torque",
        source=f"{SEED}, Eq. 3-8",
        params=params,
        constants=constants,
        derived={"sigma_ref": sigma_ref},
        trajectory=True,
        notes=_DAHL_NOTES,
        optional={"preload": OptionalInput("P_ref", ("gamma", "kappa"))},
        steady=steady,
    )(fn)


_dahl_law("dahl", knee_by_preload=False)
_dahl_law("dahl_xc_preload", knee_by_preload=True)
#: Names users already type for Dahl with a fixed exponent: thin aliases (registered by
#: bayesfric.laws with :func:`bayesfric.laws.variants.alias`), the same as ``fixed = { i = ... }``.
DAHL_ALIASES = {
    f"dahl{i_tag}{knee_tag}": {"base": f"dahl{knee_tag}", "fixed": {"i": value}}
    for i_tag, value in (("_i1", 1.0), ("_i1p5", 1.5), ("_i2", 2.0))
    for knee_tag in ("", "_xc_preload")
}
#: Every Dahl law name: i ∈ {free, 1, 1.5, 2} × knee shared / per preload.
DAHL_LAWS = ("dahl", "dahl_xc_preload", *DAHL_ALIASES)

# --- LuGre -----------------------------------------------------------------------------------
_LUGRE_NOTES = (
    "Identifiability: F_c, F_ratio (F_c/F_s), v_s need steady data spanning v_s -- a drive at one "
    "speed identifies only g(v) there and leaves their posteriors on a prior-shaped ridge (the "
    "parametrisation keeps its width constant, module doc); σ2 needs speeds where σ2·v is "
    "comparable to F_c. σ0 is identified from the pre-sliding slope right after reversals and only "
    "if samples fall within the bristle time g/(σ0|v|); σ1 (here ρ1 times the passivity bound) acts "
    "only through dz/dt during those transients and is barely identified without fast, finely "
    "sampled reversals. γ needs ≥ 2 preloads. Not sign-definite in velocity: the torque lags at "
    "reversals."
)


def phi1(x):
    """(1 − e^(−x))/x for x ≥ 0, equal to 1 − x/2 near 0 (finite gradient at x = 0)."""
    tiny = x < 1e-8
    x_safe = jnp.where(tiny, 1.0, x)
    return jnp.where(tiny, 1.0 - x / 2, -jnp.expm1(-x_safe) / x_safe)


def held_velocity(velocity, time, trajectory_start):
    """Midpoint velocity v̄_k = (v_{k−1} + v_k)/2 held over each sample interval, and the interval
    h_k = t_k − t_{k−1} (0 at trajectory starts: time restarts per trajectory)."""
    v = jnp.asarray(velocity, dtype=float)
    start = jnp.asarray(trajectory_start, dtype=bool)
    time = jnp.asarray(time, dtype=float)
    v_hold = 0.5 * (v + jnp.concatenate([v[:1], v[:-1]]))
    return v_hold, jnp.where(start, 0.0, jnp.diff(time, prepend=time[:1]))


def lugre_bristle(velocity, time, trajectory_start, sigma0, F_c, dF_s, v_s, F_start=0.0):
    """Bristle deflection z (rad) of the LuGre model by the exact exponential step update.

    Returns
    -------
    tuple of arrays
        ``(z, g)``: deflection and the Stribeck curve g(v) at each sample.
    """
    v = jnp.asarray(velocity, dtype=float)
    start = jnp.asarray(trajectory_start, dtype=bool)

    def g(w):
        return F_c + dF_s * jnp.exp(-((w / v_s) ** 2))

    v_hold, h = held_velocity(v, time, start)
    rate_h = sigma0 * jnp.abs(v_hold) / g(v_hold) * h
    decay = jnp.where(start, 0.0, jnp.exp(-rate_h))  # the start state replaces z at every start
    v_first = jnp.append(v_hold[1:], 0.0)  # the first step's held velocity, on the start row
    z_start = -F_start * jnp.sign(v_first) * g(v_first) / sigma0
    gain = jnp.where(start, z_start, v_hold * h * phi1(rate_h))

    def compose(first, second):  # affine maps z -> a z + b, applied first then second
        a1, b1 = first
        a2, b2 = second
        return a2 * a1, a2 * b1 + b2

    _, z = lax.associative_scan(compose, (decay, gain))
    return z, g(v)


def _coulomb_share(reference, F_ratio, v_s):
    """F_c / g(v_ref) = 1/(1 + (1/r − 1) e^(−(v_ref/v_s)²)), v_ref the data's largest speed:
    the sampler moves F_c on log g(v_ref) (module doc, :class:`SampledAs`)."""
    return 1.0 / (1.0 + (1.0 / F_ratio - 1.0) * jnp.exp(-((reference / v_s) ** 2)))


def lugre_steady(velocity, preload, sigma0, rho1, sigma2, F_c, F_ratio, v_s, gamma, F_start, P_ref):
    """LuGre at constant speed: ż = 0 at z = g(v) sgn v/σ0, so T = (P/P_ref)^γ g(v) sgn v + σ2 v."""
    v = jnp.asarray(velocity, dtype=float)
    g = F_c + F_c * (1.0 / F_ratio - 1.0) * jnp.exp(-((v / v_s) ** 2))
    return power_ratio(jnp.asarray(preload, dtype=float), P_ref, gamma) * g * jnp.sign(v) + sigma2 * v


@law(
    name="lugre",
    family="hysteresis",
    inputs=("velocity", "time", "preload", TRAJECTORY_START),
    response="torque",
    source=f"{LUGRE}; passivity: Barabanov & Ortega 2000 (IEEE TAC 45(4):830-832); preload "
           f"factor as Dahl's, {SEED} Fig. 12, §V",
    params={
        "sigma0": Param(
            "N*m/rad",
            # median: the largest torque reached within 1 mrad of bristle deflection; e^(±3.3)
            Prior("LogNormal", loc=math.log(1e3), scale=2.0, scaled_by={"response": 1}),
            "bristle (pre-sliding) stiffness σ0 at P_ref",
            f"{LUGRE} (σ0 = F_c/z_ss with z_ss ~ 1e-5 m there); seed 001 knee ~ 4e-3 rad; "
            "prior centred on 1 mrad pre-sliding deflection (translational: on 10 µm, as in LuGre)",
            translational=Prior("LogNormal", loc=math.log(1e5), scale=2.0, scaled_by={"response": 1}),
        ),
        "rho1": Param(
            "1",
            Prior("Uniform", low=0.0, high=1.0),
            "bristle damping σ1 as a fraction of its passivity bound σ2·F_c/(F_s − F_c)",
            "Barabanov & Ortega 2000: v -> F passive iff σ1 ≤ σ2·F_c/(F_s − F_c); "
            "Åström & Canudas-de-Wit 2008 (IEEE CSM 28(6)) Eq. 8",
        ),
        "sigma2": Param(
            "N*m*s/rad",
            Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "velocity": -1}),
            "viscous friction coefficient σ2",
            f"{LUGRE}; {_GENERIC}",
        ),
        "F_c": Param("N*m", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
                     "Coulomb friction torque F_c at P_ref", f"{LUGRE}; {_GENERIC}",
                     sampled_as=SampledAs(_coulomb_share, {"velocity": 1},
                                          "g(v_ref) = F_c/c, the Stribeck curve at the data's largest speed")),
        "F_ratio": Param(
            "1",
            # median 0.69 (F_s ≈ 1.46 F_c), 90 % in [0.34, 0.92]: the median ratio the former
            # independent half-normal priors on F_c and F_s − F_c (scales 1 : 0.5) implied
            Prior("Beta", concentration1=4.0, concentration0=2.0),
            "Coulomb to static friction ratio F_c/F_s (≤ 1)",
            f"{LUGRE} (F_s ≥ F_c); weakly informative: median F_s ≈ 1.5 F_c",
        ),
        "v_s": Param(
            "rad/s",
            # median 0.14 of the largest tested speed, 90 % within ~[0.01, 1.6] of it
            Prior("LogNormal", loc=-2.0, scale=1.5, scaled_by={"velocity": 1}),
            "Stribeck velocity v_s of the Gaussian decay e^(−(v/v_s)²)",
            f"{LUGRE}; {_GENERIC}",
        ),
        "gamma": gamma,
    },
    constants={"F_start": START_STATE, "P_ref": P_REF},
    derived={
        "F_s": Derived(lambda F_c, F_ratio: F_c / F_ratio, "N*m", "static friction torque F_s"),
        "dF_s": Derived(lambda F_c, F_ratio: F_c * (1.0 / F_ratio - 1.0), "N*m",
                        "static friction excess F_s − F_c"),
        "sigma1": Derived(lambda rho1, sigma2, F_ratio: rho1 * sigma2 * F_ratio / (1.0 - F_ratio),
                          "N*m*s/rad", "bristle damping σ1 (≤ passivity bound)"),
    },
    trajectory=True,
    notes=_LUGRE_NOTES,
    optional={"preload": OptionalInput("P_ref", ("gamma",))},
    steady=lugre_steady,
)
def lugre(velocity, time, preload, trajectory_start, sigma0, rho1, sigma2, F_c, F_ratio, v_s, gamma,
          F_start, P_ref):
    """LuGre friction: F = (P/P_ref)^γ (σ0 z + σ1 ż) + σ2 v, ż = v − σ0|v| z/g(v), σ1 = ρ1·σ2 F_c/(F_s − F_c)."""
    dF_s = F_c * (1.0 / F_ratio - 1.0)
    z, g = lugre_bristle(velocity, time, trajectory_start, sigma0, F_c, dF_s, v_s, F_start)
    v = jnp.asarray(velocity, dtype=float)
    z_rate = v - sigma0 * jnp.abs(v) * z / g
    sigma1 = rho1 * sigma2 * F_ratio / (1.0 - F_ratio)  # ρ1 σ2 F_c/(F_s − F_c)
    load = power_ratio(jnp.asarray(preload, dtype=float), P_ref, gamma)
    return load * (sigma0 * z + sigma1 * z_rate) + sigma2 * v
