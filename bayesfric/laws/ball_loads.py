"""Ball normal loads of a four-point contact slewing (pitch) bearing under combined loads.

Model (rigid rings, Hertz point contacts)
-----------------------------------------
The rings are rigid bodies; only the balls deform. The inner ring moves relative to the outer by
an axial approach ``a``, a tilt ``θ`` about a diametral axis and a radial shift ``r`` (radial force
taken along the same azimuth as the moment's load zone, the worst case). A four-point contact ball
at azimuth ψ_j = 2πj/Z has two diagonal contact pairs with nominal contact angle α (no clearance,
no preload; contact angles stay at α):

    δ_A(ψ) = +sin α (a + θR cos ψ) + cos α · r cos ψ      (pair A takes axial load in +z)
    δ_B(ψ) = −sin α (a + θR cos ψ) + cos α · r cos ψ      (pair B takes axial load in −z)
    Q = K · max(δ, 0)^1.5                                  (Hertz)

with R = D_M/2. This is the cosine ball-load distribution of seed 003 Eq. 1–3 (there: one radial
force, δ ∝ cos φ, F_N ∝ cos^1.5 φ) generalised to axial force + tilting moment + radial force and to
both contact pairs. Equilibrium per row (every row deflects the same; the axial offset between the
two rows is neglected):

    Σ (Q_A − Q_B) sin α = F_a / rows,   Σ (Q_A − Q_B) sin α · R cos ψ = M / rows,
    Σ (Q_A + Q_B) cos α cos ψ = F_r / rows.

These equations are the gradient of the convex potential E(a, θR, r) = Σ 0.4 K max(δ,0)^2.5 − F·x,
so the equilibrium is its minimiser; it is found with a fixed number of Levenberg–Marquardt-damped
Newton steps (a step is kept only if it lowers E), so the solver is jit-able,
vmappable over load arrays and differentiable (all powers are written with finite gradients at 0).

Stiffness cancels. With zero clearance and no preload δ is linear in the displacements, so every
equation is homogeneous of degree 1.5: scaling K by c scales the displacements by c^(-2/3) and
leaves every Q unchanged. Hence the ball loads -- not only P1 = Σ|Q| -- do not depend on K, and K
is not an argument here (displacements are never returned). With clearance or preload this would
no longer hold (the shape would then depend on K); neither is modelled.

Pure moment (hand check used by the tests): one pair per ball is loaded, Q(ψ) = Q_max |cos ψ|^1.5,
so M/rows = Q_max sin α R Σ|cos ψ|^2.5 and P1 = Σ|Q| = M Σ|cos ψ|^1.5 / (sin α R Σ|cos ψ|^2.5),
linear in M. For many balls the sums become Z times the mean of |cos|^p,
Γ((p+1)/2)/(√π Γ(p/2+1)) = 0.5564 (p=1.5) and 0.4577 (p=2.5), so P1 ≈ 1.2157 M / (R sin α).

Simplification and expected error
---------------------------------
Seed 000 (§2.1) took its ball loads from an FE model of the whole test rig (ANSYS, simplifications
of Daidie et al. 2008) that includes ring, hub and blade flexibility. This module has no ring
flexibility and no FE. In flexible large slewing rings the rigid-ring model is known to misplace
the load zone and to overestimate the peak ball load, typically by 10–40 % (literature comparisons
of rigid-ring vs. FE slewing-ring models, e.g. Daidie et al. 2008; Schwack et al. 2016 for free
contact angles). P1 is a sum over all balls and so is less sensitive than the peak load, but its
error is not known here; as long as it is close to proportional to the FE value, it is absorbed by
the friction coefficient (f1, μ) multiplying it. Contact-angle changes under load are neglected.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from bayesfric.numerics import positive_power

__all__ = [
    "BearingGeometry",
    "PITCH_BEARING",
    "ball_loads",
    "contact_loads",
    "sum_ball_loads",
    "sum_contact_powers",
]

NEWTON_STEPS = 60
_HESSIAN_FLOOR = 1e-12  # keeps the damped system regular at zero load (unit-stiffness units)


@dataclass(frozen=True)
class BearingGeometry:
    """Geometry of a (multi-row) four-point contact ball bearing, SI units.

    Parameters
    ----------
    pitch_diameter : float
        Pitch (ball-centre circle) diameter D_M in m.
    n_balls : int
        Number of balls per row.
    ball_diameter : float
        Ball diameter in m.
    contact_angle : float
        Nominal contact angle α in rad.
    rows : int
        Number of ball rows (loads are shared equally).
    name : str
        Short name.
    source : str
        Where each number comes from, or "assumed".
    """

    pitch_diameter: float
    n_balls: int
    ball_diameter: float
    contact_angle: float
    rows: int
    name: str
    source: str


PITCH_BEARING = BearingGeometry(
    pitch_diameter=2.1,
    n_balls=120,
    ball_diameter=0.05,
    contact_angle=float(np.deg2rad(45.0)),
    rows=2,
    name="3 MW pitch bearing (seed 000)",
    source=(
        "seed 000 §2.1: grease-lubricated two-row four-point contact bearing of a 3 MW-class "
        "turbine, outer diameter roughly 2.3 m (rows = 2 from the seed); pitch diameter 2.1 m, "
        "ball diameter 0.05 m, 120 balls per row and contact angle 45° are assumed (the seed "
        "does not state them)"
    ),
)


def _directions(geometry: BearingGeometry):
    """Per contact (pair A and B of every ball): derivative of δ w.r.t. (a, θR, r)."""
    psi = 2.0 * np.pi * np.arange(geometry.n_balls) / geometry.n_balls
    s, c, cos = np.sin(geometry.contact_angle), np.cos(geometry.contact_angle), np.cos(psi)
    g_a = np.stack([s * np.ones_like(cos), s * cos, c * cos], axis=-1)  # (Z, 3)
    g_b = np.stack([-s * np.ones_like(cos), -s * cos, c * cos], axis=-1)
    return jnp.asarray(np.stack([g_a, g_b], axis=1))  # (Z, 2, 3)


def _initial_guess(f, geometry: BearingGeometry):
    """Superposed single-load solutions (unit stiffness) as the Newton start."""
    z = geometry.n_balls
    s, c = np.sin(geometry.contact_angle), np.cos(geometry.contact_angle)
    mean_cos25 = 0.4577  # mean of |cos ψ|^2.5 (module docstring)

    def root(q):
        return jnp.sign(q) * positive_power(jnp.abs(q), 2.0 / 3.0)

    a0 = root(f[..., 0] / (z * s)) / s
    t0 = root(f[..., 1] / (z * s * mean_cos25)) / s
    r0 = root(f[..., 2] / (z * c * mean_cos25)) / c
    return jnp.stack([a0, t0, r0], axis=-1)


def _solve_unit(f, geometry: BearingGeometry):
    """Contact loads (Z, 2) for per-row load vector f = (F_a, M/R, F_r) at unit stiffness.

    Levenberg–Marquardt-damped Newton on the convex potential: a step is accepted only if it
    lowers the potential (then the damping shrinks), otherwise the damping grows. The damping
    matters where the Hessian is singular, e.g. when only one contact pair is loaded (then tilt
    and radial shift act on it alike and the other pair must engage to separate M from F_r).
    """
    g = _directions(geometry)

    def energy(x):
        value = jnp.sum(0.4 * positive_power(g @ x, 2.5)) - f @ x
        return jnp.where(jnp.isfinite(value), value, jnp.inf)

    def step(_, state):
        x, damping = state
        delta = g @ x  # (Z, 2)
        grad = jnp.einsum("zk,zkj->j", positive_power(delta, 1.5), g) - f
        hess = jnp.einsum("zk,zki,zkj->ij", 1.5 * positive_power(delta, 0.5), g, g)
        level = jnp.trace(hess) / 3.0 + _HESSIAN_FLOOR
        trial = x - jnp.linalg.solve(hess + damping * level * jnp.eye(3), grad)
        better = energy(trial) < energy(x)
        x = jnp.where(better, trial, x)
        damping = jnp.clip(jnp.where(better, damping / 3.0, damping * 4.0), 1e-12, 1e12)
        return x, damping

    start = (_initial_guess(f, geometry), jnp.asarray(1e-3))
    x, _ = jax.lax.fori_loop(0, NEWTON_STEPS, step, start)
    return positive_power(g @ x, 1.5)


def contact_loads(
    bending_moment, axial_force, radial_force, geometry: BearingGeometry = PITCH_BEARING
):
    """Normal loads of both diagonal contact pairs of every ball.

    Parameters
    ----------
    bending_moment, axial_force, radial_force : array_like
        Tilting moment (N·m), axial force (N), radial force (N); broadcast together.
    geometry : BearingGeometry
        Bearing geometry (default: :data:`PITCH_BEARING`).

    Returns
    -------
    jax.Array
        Shape ``(..., rows, n_balls, 2)``: contact-pair loads Q_A, Q_B >= 0 in N.
    """
    m, fa, fr = jnp.broadcast_arrays(
        *(jnp.asarray(v, dtype=float) for v in (bending_moment, axial_force, radial_force))
    )
    return _contact_loads(m, fa, fr, geometry)


@partial(jax.jit, static_argnums=3)
def _contact_loads(m, fa, fr, geometry):
    radius = 0.5 * geometry.pitch_diameter
    loads = jnp.stack([fa, m / radius, fr], axis=-1)  # (..., 3)
    squared = jnp.sum(loads**2, axis=-1)
    nonzero = squared > 0
    scale = jnp.where(nonzero, jnp.sqrt(jnp.where(nonzero, squared, 1.0)), 0.0)
    unit = loads / jnp.where(nonzero, scale, 1.0)[..., None] / geometry.rows
    flat = unit.reshape(-1, 3)
    per_row = jax.vmap(lambda f: _solve_unit(f, geometry))(flat)  # (N, Z, 2)
    per_row = per_row.reshape(unit.shape[:-1] + per_row.shape[1:]) * scale[..., None, None]
    return jnp.broadcast_to(
        per_row[..., None, :, :], unit.shape[:-1] + (geometry.rows, geometry.n_balls, 2)
    )


def ball_loads(
    bending_moment, axial_force, radial_force, geometry: BearingGeometry = PITCH_BEARING
):
    """Ball normal loads Q >= 0 (both contact pairs of a ball added) in N.

    Parameters
    ----------
    bending_moment, axial_force, radial_force : array_like
        Tilting moment (N·m), axial force (N), radial force (N); broadcast together.
    geometry : BearingGeometry
        Bearing geometry (default: :data:`PITCH_BEARING`).

    Returns
    -------
    jax.Array
        Shape ``(..., rows, n_balls)``.
    """
    return jnp.sum(contact_loads(bending_moment, axial_force, radial_force, geometry), axis=-1)


def sum_ball_loads(
    bending_moment, axial_force, radial_force, geometry: BearingGeometry = PITCH_BEARING
):
    """Equivalent load P1 = Σ|Q| over all contacts of all balls and rows (seed 000 Eq. 2), in N.

    Parameters
    ----------
    bending_moment, axial_force, radial_force : array_like
        Tilting moment (N·m), axial force (N), radial force (N); broadcast together.
    geometry : BearingGeometry
        Bearing geometry (default: :data:`PITCH_BEARING`).

    Returns
    -------
    jax.Array
        Shape of the broadcast loads.
    """
    return sum_contact_powers(bending_moment, axial_force, radial_force, geometry, 1.0)


def sum_contact_powers(
    bending_moment,
    axial_force,
    radial_force,
    geometry: BearingGeometry = PITCH_BEARING,
    power: float = 1.0,
):
    """Σ Q^power over all loaded contacts (both pairs, all balls and rows), Q in N.

    Laws whose friction per contact is a power of the contact load (Hertz contact width
    b ∝ Q^(1/3), EHL rolling force ∝ Q^0.47 ...) read this. When all three load arrays are
    concrete (not traced, e.g. data closed over by a numpyro model) the solve is evaluated once
    at trace time (``jax.ensure_compile_time_eval``), so a sampler does not repeat it at every
    log-density evaluation.

    Parameters
    ----------
    bending_moment, axial_force, radial_force : array_like
        Tilting moment (N·m), axial force (N), radial force (N); broadcast together.
    geometry : BearingGeometry
        Bearing geometry (default: :data:`PITCH_BEARING`).
    power : float
        Exponent p > 0 (a Python number).

    Returns
    -------
    jax.Array
        Σ Q^p in N^p, shape of the broadcast loads.
    """
    loads = (bending_moment, axial_force, radial_force)
    if any(isinstance(v, jax.core.Tracer) for v in loads):
        return _sum_powers(*loads, geometry, float(power))
    with jax.ensure_compile_time_eval():
        m, fa, fr = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in loads))
        total = _jit_sum_powers(m.ravel(), fa.ravel(), fr.ravel(), geometry, float(power))
        return jnp.asarray(np.asarray(total).reshape(m.shape))


def _sum_powers(m, fa, fr, geometry, power):
    return jnp.sum(positive_power(contact_loads(m, fa, fr, geometry), power), axis=(-3, -2, -1))


_jit_sum_powers = jax.jit(_sum_powers, static_argnums=(3, 4))
