"""Law family 'thermal': temperature-dependent viscous friction of a geared drive (seed 002).

Seed 002 measures the steady-state friction torque of a web-machine unwinding group against motor
speed (100–1400 rpm) and gearbox lubricant temperature (19–38 °C). Its laws are empirical: a
viscous coefficient quadratic in temperature (Eq. 5, Fig. 11), a polynomial surface of 2nd order in
speed and 4th order in temperature (Fig. 12) and a viscous bearing term (Eq. 6). A physically based
alternative ties the temperature dependence to the lubricant's Vogel viscosity.

Units and conventions
---------------------
* Speed is the angular velocity in rad/s (the paper quotes rpm and Nm/rpm; datasets convert).
* Temperature inputs are kelvin (SI). Where the paper's polynomials are in °C the laws convert
  internally with ``θ = T − 273.15`` and centre on the constant ``T_ref`` (in °C). A centred
  difference θ − T_ref is the same number in °C and K, so the coefficients are per kelvin too.
* Polynomial bases are scaled, ``s = (θ − T_ref)/T_scale`` and ``u = |ω|/ω_scale``, so every
  coefficient has the unit of the leading one and one data-scaled prior fits all of them.
* All laws are odd in ω: written for |ω| and multiplied by sign(ω).
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from bayesfric.laws.base import Constant, Param, law
from bayesfric.numerics import power_ratio
from bayesfric.priors import Prior

#: Why these laws run on rotary (torque) data only (bayesfric.laws.variants).
_ROTARY = "a geared drive's oil-bath friction (seed 002): speed in rad/s through the gearbox"

SEED = "seed 002 (web-machine unwinding group)"
KELVIN_OFFSET = 273.15  # θ[°C] = T[K] − 273.15
RPM = 2.0 * math.pi / 60.0  # rad/s per rpm

# --- constants (one place each) -----------------------------------------------------------------
T_REF = Constant(28.5, "degC", "reference lubricant temperature: centre of the seed's 19–38 °C")
T_SCALE = Constant(10.0, "K", "temperature scale of the polynomial basis s = (θ − T_ref)/T_scale")
OMEGA_SCALE = Constant(
    float(1400 * RPM), "rad/s", "speed scale of the polynomial basis: seed's top speed 1400 rpm"
)
OMEGA_REF = Constant(float(1000 * RPM), "rad/s", "reference speed of the power law (1000 rpm)")

# --- shared parameter declarations ---------------------------------------------------------------
_GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"
_VISCOUS = Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "velocity": -1})
# per T_scale = 10 K the seed's f1 changes by ~ −12 % (21 % drop over 18 K): scale 0.5 is wide
_VISCOUS_SLOPE = Prior("Normal", loc=0.0, scale=0.5, scaled_by={"response": 1, "velocity": -1})
_TORQUE_LEVEL = Prior("HalfNormal", scale=1.0, scaled_by={"response": 1})

f1_ref = Param(
    "N*m*s/rad", _VISCOUS, "viscous coefficient f1 at T_ref",
    f"{SEED} Eq. 5, Fig. 11; {_GENERIC}",
)
f1_lin = Param(
    "N*m*s/rad", _VISCOUS_SLOPE, "change of f1 per T_scale (linear term of the quadratic)",
    f"{SEED} Fig. 11 (2nd-order fit of f1 over temperature); {_GENERIC}",
)
f1_quad = Param(
    "N*m*s/rad", _VISCOUS_SLOPE, "quadratic term of f1 per T_scale²",
    f"{SEED} Fig. 11 (2nd-order fit of f1 over temperature); {_GENERIC}",
)
SURFACE_SHAPE = (3, 5)  # speed powers 0..2 × temperature powers 0..4
surface_coefficients = Param(
    "N*m",
    Prior("Normal", loc=0.0, scale=1.0, scaled_by={"response": 1}),
    "coefficients c[i, j] of u^i s^j (u = |ω|/ω_scale, s = (θ − T_ref)/T_scale)",
    f"{SEED} Fig. 12 (2nd order in speed × 4th order in temperature); {_GENERIC}",
    shape=SURFACE_SHAPE,
)
f2 = Param(
    "N*m*s/rad", _VISCOUS, "viscous coefficient f2 of the roller bearings (mass 2)",
    f"{SEED} Eq. 6, Fig. 13; {_GENERIC}",
)


def _centred(temperature, T_ref, T_scale):
    """``s = (θ − T_ref)/T_scale`` with θ = T − 273.15 in °C (T_ref in °C)."""
    return ((temperature - KELVIN_OFFSET) - T_ref) / T_scale


@law(
    name="thermal_viscous_quadratic",
    family="thermal",
    rotary_only=_ROTARY,
    inputs=("velocity", "temperature"),
    response="torque",
    source=f"{SEED}, Eq. 5 with f1(t_GB) a 2nd-order polynomial (Fig. 11)",
    params={"f1_ref": f1_ref, "f1_lin": f1_lin, "f1_quad": f1_quad},
    constants={"T_ref": T_REF, "T_scale": T_SCALE},
    sign_definite=False,
    notes=(
        "f1(T) is a polynomial: prior draws (and extrapolation far outside the tested "
        "temperatures) can make it negative, which is unphysical. On the seed's design "
        "(19–38 °C, s ∈ [−0.95, 0.95]) all three coefficients are identified; the centred "
        "basis keeps them nearly uncorrelated (f1_ref and f1_quad still correlate through the "
        "even power of s)."
    ),
)
def thermal_viscous_quadratic(velocity, temperature, f1_ref, f1_lin, f1_quad, T_ref, T_scale):
    """Temperature-dependent viscous friction: T = f1(θ)·ω, f1 = f1_ref + f1_lin s + f1_quad s²."""
    s = _centred(temperature, T_ref, T_scale)
    return (f1_ref + f1_lin * s + f1_quad * s**2) * velocity


@law(
    name="thermal_poly_surface",
    family="thermal",
    rotary_only=_ROTARY,
    inputs=("velocity", "temperature"),
    response="torque",
    source=f"{SEED}, Fig. 12 (polynomial surface, 2nd order in speed × 4th order in temperature)",
    params={"c": surface_coefficients},
    constants={"omega_scale": OMEGA_SCALE, "T_ref": T_REF, "T_scale": T_SCALE},
    sign_definite=False,
    notes=(
        "Purely empirical: 15 coefficients of monomials u^i s^j, collinear on any bounded design "
        "(s^0, s^2, s^4 and s^1, s^3 are strongly correlated on [−1, 1]); individual c[i, j] are "
        "weakly identified and only the surface inside the tested box is. The u^0 column acts as "
        "sign(ω)·offset (odd extension). Extrapolation in temperature follows a quartic and is "
        "not trustworthy; the polynomial may be negative for prior draws."
    ),
)
def thermal_poly_surface(velocity, temperature, c, omega_scale, T_ref, T_scale):
    """Polynomial friction map: T = sign(ω) Σ_ij c[i, j] (|ω|/ω_scale)^i s^j, i ≤ 2, j ≤ 4."""
    u = jnp.abs(velocity) / omega_scale
    s = _centred(temperature, T_ref, T_scale)
    speed_powers = jnp.stack([jnp.ones_like(u), u, u**2], axis=-1)  # (..., 3)
    temp_powers = jnp.stack([s**j for j in range(SURFACE_SHAPE[1])], axis=-1)  # (..., 5)
    value = jnp.einsum("...i,ij,...j->...", speed_powers, c, temp_powers)
    return jnp.sign(velocity) * value


# --- physically based: power law in speed and Vogel viscosity ------------------------------------
def vogel_viscosity(temperature, A, B, C):
    """Vogel equation η = A·exp(B/(T − C)) with T and C in kelvin (valid for T > C).

    Parameters
    ----------
    temperature : array_like
        Lubricant temperature in K.
    A : float
        Viscosity scale (unit of the returned viscosity, e.g. Pa·s or mm²/s).
    B, C : float
        Vogel constants in K.

    Returns
    -------
    jax.Array
        Viscosity in the unit of ``A``.
    """
    return A * jnp.exp(B / (temperature - C))


VOGEL_B = Param(
    "K",
    Prior("LogNormal", loc=7.09, scale=0.3),  # median e^7.09 = 1200 K, 90 % in [735, 1960] K
    "Vogel constant B of the gear oil (η = A exp(B/(T − C)))",
    "Vogel fits of mineral gear/machine oils (Stachowiak & Batchelor, Engineering Tribology, "
    "Table 2.3) and of ISO VG 100–680, VI 90–160 oils (ISO 3448; ASTM D341): B = 885–1660 K; "
    "derivation in bayesfric.laws.thermal.thermal_vogel_power",
)
VOGEL_C = Param(
    "K",
    Prior("TruncatedNormal", loc=170.0, scale=25.0, low=100.0, high=230.0),
    "Vogel temperature C of the gear oil (viscosity diverges as T → C)",
    "same Vogel fits as B: C = 135–200 K; truncated at 230 K (−43 °C) so every prior draw is "
    "valid (T > C) over any gearbox operating temperature",
)


@law(
    name="thermal_vogel_power",
    family="thermal",
    rotary_only=_ROTARY,
    inputs=("velocity", "temperature"),
    response="torque",
    source=(
        f"{SEED} (temperature-dependent viscous friction, §I, Fig. 10); Vogel (1921) "
        "viscosity; hydrodynamic power law T ∝ ω^a η^b (Petroff a = b = 1; Palmgren (ν n)^(2/3); "
        "gear churning ∝ ω^1.4 ν^0.6, Changenet & Velex 2007)"
    ),
    params={
        "c0": Param("N*m", _TORQUE_LEVEL, "speed-independent (Coulomb-like) torque",
                    f"{SEED} §I (Coulomb share of gearbox friction); {_GENERIC}"),
        "c": Param("N*m", _TORQUE_LEVEL, "viscous torque at ω_ref and T_ref",
                   f"{SEED} Fig. 10; {_GENERIC}"),
        "a": Param("1", Prior("LogNormal", loc=0.0, scale=0.35),  # 90 % in [0.56, 1.78]
                   "speed exponent of the viscous torque",
                   "Petroff a = 1; Palmgren/SKF rolling-bearing viscous moment a = 2/3; gear "
                   "churning (Changenet & Velex 2007) a ≈ 1.4"),
        # median 0.5, 90 % in [0.19, 1.34]
        "b": Param("1", Prior("LogNormal", loc=-0.69, scale=0.6),
                   "viscosity exponent of the viscous torque",
                   "Petroff b = 1; Palmgren b = 2/3; churning b ≈ 0.6; seed 002's 21 % drop over "
                   "20–38 °C with η ratio ≈ 3.5 suggests b ≈ 0.2 for the whole gearbox"),
        "B": VOGEL_B,
        "C": VOGEL_C,
    },
    constants={"omega_ref": OMEGA_REF, "T_ref": T_REF},
    notes=(
        "Only η(T)/η(T_ref) enters, so the Vogel scale A cancels (it is not a parameter). From "
        "torque data b and B enter only as b·B·(1/(T−C) − 1/(T_ref−C)): their product (and, "
        "weakly, C through curvature over a 19 K span) is identified, b and B separately only "
        "through the oil-based priors on B and C. c0 and c trade off when a is small."
    ),
)
def thermal_vogel_power(velocity, temperature, c0, c, a, b, B, C, omega_ref, T_ref):
    r"""Viscous power law with Vogel viscosity: T = sign(ω)[c0 + c (|ω|/ω_ref)^a (η(T)/η(T_ref))^b].

    η(T) = A exp(B/(T − C)) (Vogel); the ratio to η at T_ref is ``exp(B/(T − C) − B/(T_ref − C))``
    so A cancels. Temperatures are used in kelvin here (T_ref is converted from °C).

    Derivation of the priors on B and C (rerun: the snippet in ``tests/laws/test_thermal.py``,
    ``test_vogel_prior_derivation``):

    1. Three-point Vogel fits ``ln η = ln A + B/(T − C)`` through dynamic viscosities at 30, 60 and
       100 °C of the mineral oils of Stachowiak & Batchelor, *Engineering Tribology*, Table 2.3
       (heavy machine oils η30 = 122–310 mPa·s, cylinder oil 810 mPa·s; ISO VG ≈ 68–460 at
       40 °C): C = 157–200 K, B = 885–1546 K.
    2. ISO 3448 grades VG 100–680 (ν40 = 100–680 mm²/s) with viscosity index 90–160: typical
       data-sheet pairs (approximate) ν100 = 11.2, 19.0, 39.2 mm²/s for VI ≈ 95/95/90 mineral VG
       100/220/680 and 14.5, 25.5, 65 mm²/s for VI ≈ 150–160 synthetic VG 100/220/680. Each pair
       fixes the ASTM D341 (Walther) line log log(ν + 0.7) = A_w − m log T; the line is evaluated
       at 0, 40, 100 °C and a Vogel curve put through the three points: C = 135–171 K,
       B = 1053–1661 K (higher VI: lower C, higher B).
    3. Union: B ∈ [885, 1661] K, C ∈ [135, 200] K. Priors: B ~ LogNormal(ln 1200, 0.3) (90 % in
       [735, 1960] K), C ~ Normal(170, 25) truncated to [100, 230] K. The upper truncation keeps
       T > C for all temperatures above −43 °C, so η falls with T for every prior draw.

    Kinematic and dynamic viscosity differ by the density, which changes ~0.07 %/K; the ratio
    η(T)/η(T_ref) is taken from kinematic data without that correction (≈ 1 % over 19 K).
    """
    t_ref_kelvin = T_ref + KELVIN_OFFSET
    log_ratio = B / (temperature - C) - B / (t_ref_kelvin - C)
    speed = jnp.abs(velocity)
    speed_term = power_ratio(speed, omega_ref, a)
    return jnp.sign(velocity) * (c0 + c * speed_term * jnp.exp(b * log_ratio))


@law(
    name="thermal_mass2_viscous",
    family="thermal",
    rotary_only=_ROTARY,
    inputs=("velocity",),
    response="torque",
    source=f"{SEED}, Eq. 6 (roller-bearing friction of mass 2, Fig. 13)",
    params={"f2": f2},
    notes="Temperature is ignored: the seed attributes all temperature dependence to the gearbox.",
)
def thermal_mass2_viscous(velocity, f2):
    """Viscous bearing friction of mass 2: T = f2·ω."""
    return f2 * velocity
