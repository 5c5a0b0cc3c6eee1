"""Multi-element and elasto-plastic pre-sliding laws: Maxwell-slip, GMS, elasto-plastic.

All three carry an internal state along ordered trajectories (``jax.lax.scan``), like Dahl and
LuGre (:mod:`bayesfric.laws.hysteresis`), and are declared on rotary quantities (torque, rad,
rad/s). Each trajectory starts in the state set by the constant ``F_start`` (shared with LuGre,
:data:`bayesfric.laws.hysteresis.START_STATE`): 0 relaxed (zero deflection, the virgin state),
1 saturated *against* the first motion (after a sweep the other way, Dahl's convention), −1
saturated *along* it (steady sliding in the first step's direction).

Maxwell-slip (Lampaert, Al-Bender & Swevers 2003; Al-Bender, Lampaert & Swevers 2005)
------------------------------------------------------------------------------------------
N elasto-slide elements in parallel, element i a spring of stiffness k_i ending in a slider of
break-away torque W_i = α_i F_c (Σ α_i = 1). Its spring deflection z_i follows the drive angle
while |z_i| < Δ_i = W_i/k_i and is held at ±Δ_i while the element slides. Over a monotone step
Δx the update z_i ← clip(z_i + Δx, −Δ_i, Δ_i) is exact, so the law is rate independent and
exact for any sampling. T = Σ k_i z_i. Virgin curve from rest: T(x) = Σ k_i min(x, Δ_i),
piecewise linear with kinks at the Δ_i; beyond Δ_N the torque saturates at F_c.

Generalized Maxwell-slip, GMS (Al-Bender, Lampaert & Swevers 2005, IEEE TAC 50(11):1883-1887)
---------------------------------------------------------------------------------------------
The same elements with a rate-dependent break-away: element i sticks (dF_i/dt = k_i v) until
F_i reaches α_i s(v), then slips, dF_i/dt = sgn(v) C (1 − F_i/(α_i s(v))), until the velocity
reverses; s(v) = F_c + (F_s − F_c) e^(−(v/v_s)²) is the Stribeck curve and σ2 v a viscous term.
T = Σ F_i + σ2 v. Held at the midpoint velocity v̄ over a sample interval h, sticking is exact
(F_i + k_i v̄ h) and slipping is a linear relaxation towards α_i s(v̄) sgn v̄, solved exactly:
F_i ← α_i s sgn v̄ + (F_i − α_i s sgn v̄) e^(−C h/(α_i s)). An element that reaches its threshold
within a step sits at that equilibrium at the step's end. So the update is exact for
piecewise-constant velocity. In steady sliding every element sits at α_i s(v) sgn v and
T = s(v) sgn v + σ2 v: the declared Stribeck curve. The stiffness is k_i = α_i F_s/Δ_i with Δ_i
the break-away deflection of element i at rest.

Ordering: in both laws Δ_i = Σ_{j≤i} δ_j with δ_j > 0 (a cumulative-positive parametrisation),
so the elements are ordered by break-away deflection and cannot swap labels; the weights
α = w/Σw with w_j ~ Gamma(2, 1) i.i.d., i.e. α ~ Dirichlet(2, …, 2) (Σw itself is not
identified and keeps its Gamma(2N, 1) prior). The increments' prior puts the median of Δ_N at 10 %
of the largest |angle| for both laws; GMS reads no angle, so on data without one the scale is the
largest excursion ∫v dt from a trajectory's start (:func:`bayesfric.datasets.views.travel`). GMS's
scale was once max|v|·max t: 12.6× the stroke on two 1 Hz sine cycles, which started
every element beyond the loops and left a chain on Dahl loops in an all-elastic mode (R-hat 2.2).

Elasto-plastic (Dupont, Hayward, Armstrong & Altpeter 2002, IEEE TAC 47(5):787-792)
-----------------------------------------------------------------------------------
ż = v (1 − α(z, v) z/z_ss(v)), z_ss(v) = f_ss(v) sgn(v)/σ0, f_ss(v) = F_c + (F_s − F_c)
e^(−(v/v_s)²), T = σ0 z + σ2 v, with α = 0 for |z| ≤ z_ba or sgn z ≠ sgn v (purely elastic:
no drift under small oscillations), α = 1 for |z| ≥ |z_ss|, and the sine blend
α = ½ sin(π (z − (z_max + z_ba)/2)/(z_max − z_ba)) + ½ in between (z_max = |z_ss|). The
break-away deflection z_ba = β F_c/σ0 with 0 < β < 1 stays below z_max at every speed.
Integration over each sample (v held at v̄, displacement v̄ h): the elastic part is exact, the
remaining distance is crossed in ``SUBSTEPS`` exponential-Euler steps of du/dx = 1 − (α/z_max) u
with α frozen per sub-step, capped at z_max (exact where α = 0 or 1; *approximate* in the blend,
error checked against a 4000-step reference in tests/laws/test_slip.py); a sample whose remaining
distance starts at or above z_max (α = 1 throughout) is crossed in one exact step instead. Dupont's micro-damping
σ1 ż is omitted (its effect is confined to fast transients, cf. LuGre's notes). As LuGre's,
the Stribeck curve is sampled as F_c and ``F_ratio`` = F_c/F_s: where the data pin
only part of s(v) the ridge of F_c, F_ratio and v_s keeps one width (on the Dahl-simulated
tribo_loops, 2 × (300 + 300) draws: tail ESS 87 → 187, divergences 2 → 0, 27 → 18 leapfrog
steps per draw against F_c and F_s − F_c).
"""

from __future__ import annotations

import inspect
import math
import re

import jax.numpy as jnp
from jax import lax

from bayesfric.laws.base import TRAJECTORY_START, Derived, Law, Param, law, register_resolver
from bayesfric.laws.hysteresis import START_STATE, held_velocity, phi1
from bayesfric.priors import Prior

__all__ = ["maxwell_slip_law", "gms_law", "elastoplastic", "maxwell_slip_torque", "gms_torque",
           "elastoplastic_deflection", "N_DEFAULT", "N_MAX", "SUBSTEPS", "maxwell_slip_steady", "gms_steady",
           "elastoplastic_steady"]

MS = "Lampaert, Al-Bender & Swevers 2003 (Tribology Letters 16(1-2):95-105), Maxwell-slip"
GMS = "Al-Bender, Lampaert & Swevers 2005 (IEEE TAC 50(11):1883-1887), generalized Maxwell-slip"
EP = "Dupont, Hayward, Armstrong & Altpeter 2002 (IEEE TAC 47(5):787-792), elasto-plastic"
_GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"
N_DEFAULT = 4  #: elements of the laws registered as ``maxwell_slip`` and ``gms``
N_MAX = 16  #: largest N a study may ask for (``maxwell_slip_n<N>``, ``gms_n<N>``)
SUBSTEPS = 8  #: exponential-Euler sub-steps of the elasto-plastic blend zone per sample

F_C = Param("N*m", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
            "sliding (Coulomb) friction torque F_c = Σ break-away torques", f"{MS}; {_GENERIC}")


def _stribeck_params(source: str) -> dict[str, Param]:
    """F_s − F_c, v_s and σ2 of a Stribeck curve s(v) + σ2 v, with the citing law's source."""
    return {
        "dF_s": Param("N*m", Prior("HalfNormal", scale=0.5, scaled_by={"response": 1}),
                      "static friction excess F_s − F_c ≥ 0 of the Stribeck curve", f"{source}; {_GENERIC}"),
        "v_s": Param("rad/s", Prior("LogNormal", loc=-2.0, scale=1.5, scaled_by={"velocity": 1}),
                     "Stribeck velocity v_s of the decay e^(−(v/v_s)²)", f"{source}; {_GENERIC}"),
        "sigma2": Param("N*m*s/rad", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "velocity": -1}),
                        "viscous friction coefficient σ2", f"{source}; {_GENERIC}"),
    }


def _weights(n: int) -> Param:
    return Param("1", Prior("Gamma", concentration=2.0, rate=1.0),
                 "element weights w; α = w/Σw (α ~ Dirichlet(2, …, 2)) shares F_c between elements",
                 f"{MS} (W_i = α_i F_c); symmetric Dirichlet prior, no element preferred", shape=(n,))


def _increments(n: int, where: str) -> Param:
    # median of the largest break-away deflection Δ_N: 10 % of the largest |angle| (module doc)
    return Param("rad", Prior("LogNormal", loc=math.log(0.1 / n), scale=1.5, scaled_by={"angle": 1}),
                 "increments δ of the ordered break-away deflections Δ_i = Σ_{j≤i} δ_j",
                 f"{MS}; ordered (cumulative-positive) so elements cannot swap; prior median of "
                 f"Δ_N at 10 % of {where}", shape=(n,))


def _shares(w, dx):
    alpha = w / jnp.sum(w, axis=-1, keepdims=True)
    return alpha, jnp.cumsum(dx, axis=-1)


def _first_motion(direction, start):
    """Sign of each trajectory's first step, placed on its start row (0 if it does not move)."""
    return jnp.where(start, jnp.append(direction[1:], 0.0), 0.0)


# --- Maxwell-slip ------------------------------------------------------------------------------
def maxwell_slip_torque(angle, trajectory_start, F_c, w, dx, F_start):
    """Maxwell-slip torque along ordered angle trajectories (exact clip update, module doc)."""
    angle = jnp.asarray(angle, dtype=float)
    start = jnp.asarray(trajectory_start, dtype=bool)
    alpha, delta = _shares(w, dx)
    step = jnp.where(start, 0.0, jnp.diff(angle, prepend=angle[:1]))
    initial = -F_start * _first_motion(jnp.sign(step), start)  # φ_i = z_i/Δ_i at a start

    def advance(phi, row):
        is_start, dxk, phi0 = row
        phi = jnp.where(is_start, phi0, jnp.clip(phi + dxk / delta, -1.0, 1.0))
        return phi, phi

    phi0 = jnp.full(delta.shape, initial[0])
    _, phi = lax.scan(advance, phi0, (start, step, initial))
    return F_c * phi @ alpha


def maxwell_slip_steady(velocity, F_c, w, dx, F_start):
    """Maxwell-slip at constant speed: every element slides at its break-away torque, T = Σ α_i F_c sgn v."""
    alpha, _ = _shares(w, dx)
    return jnp.sign(velocity) * F_c * jnp.sum(alpha, axis=-1)


# --- GMS ---------------------------------------------------------------------------------------
def gms_torque(velocity, time, trajectory_start, F_c, dF_s, v_s, sigma2, C, w, dx, F_start):
    """GMS torque along ordered velocity trajectories (exact for piecewise-constant velocity)."""
    v = jnp.asarray(velocity, dtype=float)
    start = jnp.asarray(trajectory_start, dtype=bool)
    alpha, delta = _shares(w, dx)
    v_hold, h = held_velocity(v, time, start)
    s_hold = F_c + dF_s * jnp.exp(-((v_hold / v_s) ** 2))
    first = _first_motion(jnp.sign(v_hold), start)
    s_first = jnp.where(start, jnp.append(s_hold[1:], F_c + dF_s), 0.0)
    phi_init = -F_start * first * s_first  # element torque per unit weight, F_i/α_i
    dir_init = jnp.where(F_start < 0, first, 0.0)  # sliding along the first motion
    stiffness = (F_c + dF_s) / delta  # k_i/α_i

    def advance(carry, row):
        phi, slip = carry
        is_start, vk, hk, sk, phi0, dir0 = row
        sgn = jnp.sign(vk)
        target = sk * sgn
        decay = jnp.exp(-C * hk / (alpha * sk))
        continuing = (slip == sgn) & (sgn != 0)
        stuck = phi + stiffness * vk * hk
        breaks = (sgn != 0) & (sgn * stuck >= sk)
        entry = jnp.where(sgn * phi >= sk, phi, target)  # above threshold already, or reached it
        slipping = continuing | breaks
        relaxed = target + (jnp.where(continuing, phi, entry) - target) * decay
        new = (jnp.where(slipping, relaxed, stuck), jnp.where(slipping, sgn, 0.0))
        new = (jnp.where(is_start, phi0, new[0]), jnp.where(is_start, dir0, new[1]))
        return new, new[0]

    init = (jnp.full(delta.shape, phi_init[0]), jnp.full(delta.shape, dir_init[0]))
    _, phi = lax.scan(advance, init, (start, v_hold, h, s_hold, phi_init, dir_init))
    return phi @ alpha + sigma2 * v


def gms_steady(velocity, F_c, dF_s, v_s, sigma2, C, w, dx, F_start):
    """GMS at constant speed: every element sits at α_i s(v) sgn v, so T = Σ α_i s(v) sgn v + σ2 v."""
    v = jnp.asarray(velocity, dtype=float)
    alpha, _ = _shares(w, dx)
    return jnp.sign(v) * (F_c + dF_s * jnp.exp(-((v / v_s) ** 2))) * jnp.sum(alpha, axis=-1) + sigma2 * v


# --- elasto-plastic ----------------------------------------------------------------------------
def elastoplastic_deflection(velocity, time, trajectory_start, sigma0, beta, F_c, dF_s, v_s, F_start,
                             substeps: int = SUBSTEPS):
    """Deflection z (rad) of the elasto-plastic model (module doc; ``substeps`` in the blend)."""
    v = jnp.asarray(velocity, dtype=float)
    start = jnp.asarray(trajectory_start, dtype=bool)
    v_hold, h = held_velocity(v, time, start)
    z_max = (F_c + dF_s * jnp.exp(-((v_hold / v_s) ** 2))) / sigma0
    z_ba = beta * F_c / sigma0
    first = _first_motion(jnp.sign(v_hold), start)
    z_init = -F_start * first * jnp.where(start, jnp.append(z_max[1:], (F_c + dF_s) / sigma0), 0.0)

    def blend(u, zm):
        a = 0.5 * jnp.sin(jnp.pi * (u - 0.5 * (zm + z_ba)) / (zm - z_ba)) + 0.5
        return jnp.where(u <= z_ba, 0.0, jnp.where(u >= zm, 1.0, a)) / zm

    def advance(z, row):
        is_start, vk, hk, zm, z0 = row
        sgn = jnp.sign(vk)
        u, d = sgn * z, jnp.abs(vk) * hk  # deflection along the motion, distance travelled
        elastic = jnp.clip(z_ba - u, 0.0, d)
        u, rest = u + elastic, d - elastic

        def blended(u):  # somewhere in the blend zone: sub-steps
            step = rest / substeps

            def substep(_, u):
                # 1/a + (u − 1/a) e^(−ad) written without its cancellation: just above z_ba, a is tiny
                # and that form lost the gradient (errors up to 1.3 % in d/dβ, tests/laws/test_slip.py)
                ad = blend(u, zm) * step
                moved = u * jnp.exp(-ad) + step * phi1(ad)
                return jnp.where(u < zm, jnp.minimum(moved, zm), moved)

            # unrolled at the default count: a loop nested in the scan took 1.9x the gradient's time
            return lax.fori_loop(0, substeps, substep, u, unroll=substeps <= SUBSTEPS)

        def sliding(u):  # at or above z_max (α = 1 throughout), or no distance left: one exact step
            ad = rest / zm
            return u * jnp.exp(-ad) + rest * phi1(ad)

        # sub-steps only where the blend can act: a row that ends elastic, or slides at or above
        # z_max, is exact in one step (the sub-steps' composition there is the same map). On Dahl
        # loops at the tribo_loops scale 128 of 360 rows skip them: the log density's gradient
        # 386 -> 301 µs (a row in the blend stays there while z_max rises towards a reversal)
        u = lax.cond((rest > 0) & (u < zm), blended, sliding, u)
        z = jnp.where(is_start, z0, jnp.where(sgn == 0, z, sgn * u))
        return z, z

    _, z = lax.scan(advance, z_init[0], (start, v_hold, h, z_max, z_init))
    return z


def elastoplastic_steady(velocity, sigma0, beta, F_c, F_ratio, v_s, sigma2, F_start):
    """Elasto-plastic at constant speed: z reaches z_ss(v) = f_ss(v) sgn v/σ0 (α = 1 there), so
    T = σ0 z_ss + σ2 v = f_ss(v) sgn v + σ2 v."""
    v = jnp.asarray(velocity, dtype=float)
    return jnp.sign(v) * (F_c + F_c * (1.0 / F_ratio - 1.0) * jnp.exp(-((v / v_s) ** 2))) + sigma2 * v


@law(
    name="elastoplastic",
    family="hysteresis",
    inputs=("velocity", "time", TRAJECTORY_START),
    response="torque",
    source=EP,
    params={
        "sigma0": Param("N*m/rad",
                        Prior("LogNormal", loc=math.log(1e3), scale=2.0, scaled_by={"response": 1}),
                        "bristle (pre-sliding) stiffness σ0",
                        f"{EP}; prior as LuGre's: centred on 1 mrad pre-sliding deflection "
                        "(translational: on 10 µm)",
                        translational=Prior("LogNormal", loc=math.log(1e5), scale=2.0,
                                            scaled_by={"response": 1})),
        "beta": Param("1", Prior("Uniform", low=0.0, high=1.0),
                      "break-away deflection z_ba as a fraction of F_c/σ0 (elastic below it)",
                      f"{EP} (0 < z_ba < z_max for every speed)"),
        "F_c": Param("N*m", F_C.prior, "Coulomb friction torque F_c", f"{EP}; {_GENERIC}"),
        "F_ratio": Param("1", Prior("Beta", concentration1=4.0, concentration0=2.0),
                         "Coulomb to static friction ratio F_c/F_s (≤ 1)",
                         f"{EP} (F_s ≥ F_c); prior as LuGre's: median F_s ≈ 1.5 F_c"),
    } | {k: p for k, p in _stribeck_params(EP).items() if k != "dF_s"},
    constants={"F_start": START_STATE},
    derived={"z_ba": Derived(lambda sigma0, beta, F_c: beta * F_c / sigma0, "rad",
                             "break-away deflection z_ba"),
             "F_s": Derived(lambda F_c, F_ratio: F_c / F_ratio, "N*m", "static friction torque F_s"),
             "dF_s": Derived(lambda F_c, F_ratio: F_c * (1.0 / F_ratio - 1.0), "N*m",
                             "static friction excess F_s − F_c")},
    trajectory=True,
    notes=("Identifiability: as LuGre for F_c, F_ratio, v_s, σ2 and σ0; β (z_ba) only from reversals "
           "sampled finely inside the pre-sliding range, otherwise its prior returns. On Dahl loops "
           "(rate independent, no elastic range) the best fit leaves residuals ~14× the noise with β "
           "near 0 and σ2 standing in for the knee; σ0, β and σ2 then mix well (ESS ≥ 720 of 2000), "
           "but a flat sliding level is reached two ways, v_s below the data's speeds (s = F_c) or "
           "above them (s = F_s less a drop that σ2 v partly cancels); the chains cross through F_c/F_s "
           "near 1, and NUTS diverges at the edge of the second arm: defaults on the tribo_loops "
           "design, R-hat 1.012, ESS 660/437, 1 divergence after the retry at 0.99; "
           "check R-hat and divergences. Not sign-definite in velocity: the torque lags at reversals."),
    steady=elastoplastic_steady,
)
def elastoplastic(velocity, time, trajectory_start, sigma0, beta, F_c, F_ratio, v_s, sigma2, F_start):
    """Elasto-plastic friction: T = σ0 z + σ2 v, ż = v(1 − α(z, v) z/z_ss(v)), elastic below z_ba."""
    dF_s = F_c * (1.0 / F_ratio - 1.0)
    z = elastoplastic_deflection(velocity, time, trajectory_start, sigma0, beta, F_c, dF_s, v_s, F_start)
    return sigma0 * z + sigma2 * jnp.asarray(velocity, dtype=float)


# --- declarations for N elements -----------------------------------------------------------------
def _signature(names):
    return inspect.Signature([inspect.Parameter(n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in names])


def maxwell_slip_law(n: int = N_DEFAULT) -> Law:
    """Declare (once) and return the Maxwell-slip law with ``n`` elements.

    Named ``maxwell_slip`` for n = ``N_DEFAULT`` and ``maxwell_slip_n<n>`` otherwise; a study
    asks for N by that name.
    """
    name = "maxwell_slip" if n == N_DEFAULT else f"maxwell_slip_n{n}"
    params = {"F_c": F_C, "w": _weights(n), "dx": _increments(n, "the largest |angle|")}
    inputs = ("angle", TRAJECTORY_START)
    sig = _signature(list(inputs) + list(params) + ["F_start"])

    def fn(*args, **kwargs):
        return maxwell_slip_torque(**sig.bind(*args, **kwargs).arguments)

    fn.__signature__, fn.__name__, fn.__qualname__ = sig, name, name
    fn.__doc__ = (f"Maxwell-slip, {n} elasto-slide elements: z_i ← clip(z_i + Δx, ±Δ_i), "
                  "T = Σ k_i z_i, Δ_i ordered.")
    return law(name=name, family="hysteresis", inputs=inputs, response="torque",
               source=f"{MS}; {GMS} (rate-independent case)", params=params,
               constants={"F_start": START_STATE}, trajectory=True, steady=maxwell_slip_steady,
               derived={"break_away": Derived(lambda dx: jnp.sum(dx, axis=-1), "rad",
                                              "largest break-away deflection Δ_N (end of pre-sliding)")},
               notes=(f"{n} elements. The ordered deflections Δ_i are identified only where the data "
                      "resolve the kinks of the virgin/reversal curves (angle steps ≪ Δ_i); weights "
                      "of elements whose kinks fall between samples trade off against each other. "
                      "Rate independent. Not sign-definite in velocity: the torque follows the loop."))(fn)


def gms_law(n: int = N_DEFAULT) -> Law:
    """Declare (once) and return the GMS law with ``n`` elements (``gms`` or ``gms_n<n>``)."""
    name = "gms" if n == N_DEFAULT else f"gms_n{n}"
    params = {"F_c": F_C, **_stribeck_params(GMS),
              "C": Param("N*m/s", Prior("LogNormal", loc=math.log(100.0), scale=2.0,
                                         scaled_by={"response": 1, "time": -1}),
                         "attraction rate C of slipping elements towards α_i s(v)",
                         f"{GMS}; {_GENERIC} (median: relaxation in 1 % of the record)"),
              "w": _weights(n),
              "dx": _increments(n, "the largest |angle| (where none is recorded: the largest excursion "
                                   "∫v dt from a trajectory's start, datasets.views.travel)")}
    inputs = ("velocity", "time", TRAJECTORY_START)
    sig = _signature(list(inputs) + list(params) + ["F_start"])

    def fn(*args, **kwargs):
        return gms_torque(**sig.bind(*args, **kwargs).arguments)

    fn.__signature__, fn.__name__, fn.__qualname__ = sig, name, name
    fn.__doc__ = (f"Generalized Maxwell-slip, {n} elements: stick dF_i/dt = k_i v, slip dF_i/dt = "
                  "sgn(v) C (1 − F_i/(α_i s(v))), T = Σ F_i + σ2 v.")
    return law(name=name, family="hysteresis", inputs=inputs, response="torque",
               source=GMS, params=params, constants={"F_start": START_STATE}, steady=gms_steady,
               derived={"F_s": Derived(lambda F_c, dF_s: F_c + dF_s, "N*m", "static friction torque F_s")},
               trajectory=True,
               notes=(f"{n} elements. Steady sliding gives the Stribeck curve s(v) sgn v + σ2 v "
                      "(identifies F_c, F_s, v_s, σ2 as for LuGre); the element deflections and "
                      "weights need finely sampled reversals; C only acts after break-away and is "
                      "weakly identified when slip transients are short against the sampling. Sampling "
                      "is hard: on simulated two-element loops (1 % noise) NUTS chains with the "
                      "default priors stuck in different local modes (R-hat 2.7; on the compiled "
                      "engine 3 of 4 chains found the truth and one stayed in a mode with large "
                      "deflections and viscous term, R-hat 1.6); check R-hat. On rate-independent (Dahl) "
                      "loops the Stribeck curve and C are left open (v_s below or above the tested speeds, "
                      "C over 3.5 decades): N = 4 with defaults, 360 rows, 830 leapfrog steps per draw, "
                      "R-hat 1.012 with the log-likelihood converged. Not "
                      "sign-definite in velocity."))(fn)


_N_NAME = re.compile(r"(maxwell_slip|gms)_n(\d+)")


def _resolve(name: str) -> Law | None:
    """``maxwell_slip_n<N>`` / ``gms_n<N>`` (1 ≤ N ≤ N_MAX), declared on first use."""
    match = _N_NAME.fullmatch(name)
    if not match or not 1 <= int(match[2]) <= N_MAX or int(match[2]) == N_DEFAULT:
        return None
    return (maxwell_slip_law if match[1] == "maxwell_slip" else gms_law)(int(match[2]))


MAXWELL_SLIP = maxwell_slip_law()
GMS_LAW = gms_law()
register_resolver(_resolve)
