"""Law family 'bearing': friction torque of large grease-lubricated pitch bearings (seed 000).

Seed 000 (Stammler et al., pitch-bearing test rig, IWES) compares four models with torque
measured against blade-root bending moment (0–6 MN·m) at pitch speeds of about 3–6 °/s:
Palmgren (§2.3, Eq. 1–2), the SKF 2014 four-term model (§2.4, Eq. 3–7), Wang's rheological model
(§2.5, Eq. 8–14) and the Rothe Erde catalogue formula (§2.6, Eq. 15). They are declared here,
plus Rothe Erde with a load-independent term, which the seed's conclusion (§3.3) argues every
bearing has.

Common choices
--------------
* Inputs are ``velocity`` (rad/s) and ``bending_moment`` (N·m), what seed 000 reports. Axial and
  radial forces are constants ``F_a``, ``F_r`` (default 0 N; a study may set e.g. blade weight).
* Laws that read speed are odd in it: ``T = sign(ω)·M(|ω|)``; the seed reports magnitudes at
  positive pitch speeds. Rothe Erde has no speed term (§2.6) and reads only the load.
* Ball loads come from the rigid-ring Hertz model of :mod:`bayesfric.laws.ball_loads` instead of
  the seed's FE model (§2.1); see that module for the expected error. Geometry constants default
  to :data:`~bayesfric.laws.ball_loads.PITCH_BEARING` (partly assumed) and must be concrete numbers.
* Catalogue formulas are empirical in catalogue units (N·mm, mm, r/min, mm²/s); they are
  evaluated in those units and the torque converted to N·m, as each law states.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from bayesfric.laws.ball_loads import PITCH_BEARING, BearingGeometry, sum_contact_powers
from bayesfric.laws.base import Constant, Param, law
from bayesfric.numerics import positive_power, power_ratio
from bayesfric.priors import Prior

#: Why these laws run on rotary (torque) data only (bayesfric.laws.variants).
_ROTARY = "slewing-bearing geometry: friction torque from the tilting moment on the ball set"

SEED = "seed 000 (pitch bearing friction, Stammler et al.)"
_GENERIC = "generic coefficient, data-scaled weakly-informative prior (bayesfric.priors)"
RPM_PER_RAD_S = 30.0 / math.pi

# --- shared constants ---------------------------------------------------------------------------
GEOMETRY = {
    "D_M": Constant(PITCH_BEARING.pitch_diameter, "m", "pitch diameter (PITCH_BEARING: assumed)"),
    "n_balls": Constant(PITCH_BEARING.n_balls, "1", "balls per row (assumed)"),
    "D_RE": Constant(PITCH_BEARING.ball_diameter, "m", "ball diameter (assumed)"),
    "alpha": Constant(PITCH_BEARING.contact_angle, "rad", "nominal contact angle (assumed 45°)"),
    "rows": Constant(PITCH_BEARING.rows, "1", "ball rows (seed 000 §2.1: two-row)"),
}
LOADS = {
    "F_a": Constant(0.0, "N", "axial force; seed 000 reports the bending moment only"),
    "F_r": Constant(0.0, "N", "radial force; seed 000 reports the bending moment only"),
}
NU = Constant(
    150.0,
    "mm**2/s",
    "kinematic viscosity of the grease base oil at operating temperature (assumed; seed 000 "
    "does not state the grease)",
)


def _geometry(D_M, n_balls, D_RE, alpha, rows) -> BearingGeometry:
    return BearingGeometry(float(D_M), int(n_balls), float(D_RE), float(alpha), int(rows),
                           "law constants", "see bayesfric.laws.bearing constants")


def _contact_sum(bending_moment, F_a, F_r, geometry, power):
    """Σ Q^power over all contacts for the moment array and the constant forces (in N^power)."""
    return sum_contact_powers(bending_moment, F_a, F_r, geometry, power)


# --- Palmgren (seed 000 §2.3) -------------------------------------------------------------------
f0 = Param(
    "1",
    Prior("LogNormal", loc=math.log(2.0), scale=1.5),  # median 2, 90 % in [0.17, 24]
    "Palmgren load-independent factor f0",
    "Palmgren (1957) / Harris & Kotzalas (2007): catalogue f0 ≈ 1–4 for angular-contact/four-point "
    "ball bearings (oil/grease); seed 000 §2.3/§3.2: no value exists for pitch bearings, f0 was "
    "fitted to zero-load torque -> median 2, wide",
)
f1 = Param(
    "1",
    Prior("LogNormal", loc=math.log(7e-4), scale=1.0),  # median 7e-4, 90 % in [1.4e-4, 3.6e-3]
    "Palmgren load factor f1 (multiplies P1 = Σ|Q| and D_M)",
    "Palmgren (1957) / Harris & Kotzalas (2007): f1 ≈ 0.0005–0.001 for four-point/angular "
    "contact, defined there for an equivalent bearing load; seed 000 Eq. 2 uses the sum of ball "
    "loads and fitted f1 (§3.2) -> centred on the catalogue range, wide",
)


@law(
    name="palmgren",
    family="bearing",
    rotary_only=_ROTARY,
    inputs=("velocity", "bending_moment"),
    response="torque",
    source=f"{SEED}, Eq. 1–2 (Palmgren 1957)",
    params={"f0": f0, "f1": f1},
    constants={**GEOMETRY, **LOADS, "nu": NU},
    notes=(
        "Low-speed branch (ν·n < 2000 mm²/s·r/min, i.e. |ω| < 1.40 rad/s at ν = 150 mm²/s) is "
        "speed-independent, so on seed-000 designs f0 is identified only by the zero-load torque "
        "and ν not at all. Above the threshold T0 ∝ f0·ν^(2/3): f0 and ν are not separately "
        "identifiable (ν is a constant). f1 multiplies P1·D_M with P1 from the assumed geometry: "
        "f1 is identifiable only jointly with that geometry (P1 ∝ 1/(R sin α) for moment loads)."
    ),
)
def palmgren(velocity, bending_moment, f0, f1, D_M, n_balls, D_RE, alpha, rows, F_a, F_r, nu):
    """Palmgren: T = sign(ω)[T0 + f1 P1 D_M], T0 = 16 f0 D_M³ (νn < 2000), 0.1 f0 (νn)^(2/3) D_M³.

    Seed Eq. 1 in catalogue units: T0 = f0·10⁻⁷·160·d_m³ N·mm with d_m in mm (for ν·n < 2000, ν in
    mm²/s, n in r/min; the seed's unit text is garbled) and T0 = 10⁻⁷ f0 (νn)^(2/3) d_m³ N·mm
    above. With d_m = 1000·D_M and 1 N·mm = 10⁻³ N·m: 160·10⁻⁷·10⁹·10⁻³ = 16 and
    10⁻⁷·10⁹·10⁻³ = 0.1, D_M in m. Eq. 2: T1 = f1·P1·D_M (dimensionless f1, so units carry over).
    P1 = Σ|Q| from the rigid-ring ball loads (seed: FE ball loads).
    """
    geometry = _geometry(D_M, n_balls, D_RE, alpha, rows)
    speed = jnp.abs(velocity)
    nu_n = nu * speed * RPM_PER_RAD_S
    t0 = jnp.where(nu_n < 2000.0, 16.0 * f0 * D_M**3, 0.1 * f0 * positive_power(nu_n, 2.0 / 3.0) * D_M**3)
    p1 = _contact_sum(bending_moment, F_a, F_r, geometry, 1.0)
    return jnp.sign(velocity) * (t0 + f1 * p1 * D_M)


# --- Rothe Erde (seed 000 §2.6) -----------------------------------------------------------------
ROTHE_ERDE_MU = 0.004
mu_rothe_erde = Param(
    "1",
    Prior("LogNormal", loc=math.log(ROTHE_ERDE_MU), scale=math.log(1.25)),
    "Rothe Erde friction coefficient μ of Eq. 15",
    "Rothe Erde (2016) catalogue via seed 000 §2.6 (the seed gives no number): μ = 0.004 for "
    "four-point contact ball bearings (catalogue value as recalled here, not quoted by the seed); "
    "the manufacturer states ± 25 % scatter of the computed torque, read as one log-sd (ln 1.25)",
)
T0_offset = Param(
    "N*m",
    Prior("HalfNormal", scale=0.5, scaled_by={"response": 1}),
    "load-independent torque (seals, grease churning, preload)",
    f"{SEED} §3.3 (all bearings have friction at zero load); {_GENERIC}",
)


def _rothe_erde(bending_moment, mu, D_M, F_a, F_r):
    forces = jnp.abs(F_a) * D_M + 3.81 * jnp.abs(F_r) * D_M
    return 0.5 * mu * (4.4 * jnp.abs(bending_moment) + forces)


@law(
    name="rothe_erde",
    family="bearing",
    rotary_only=_ROTARY,
    inputs=("bending_moment",),
    response="torque",
    source=f"{SEED}, Eq. 15 (Rothe Erde 2016 catalogue)",
    params={"mu": mu_rothe_erde},
    constants={"D_M": GEOMETRY["D_M"], **LOADS},
    notes=(
        "Zero torque at zero load by construction; the catalogue says it must not be used for "
        "unloaded bearings (seed 000 §2.6). μ is identified by the slope alone; any zero-load "
        "torque in the data is misfit (use rothe_erde_offset)."
    ),
)
def rothe_erde(bending_moment, mu, D_M, F_a, F_r):
    """Rothe Erde: T = μ/2 (4.4 M + F_a D_M + 3.81 F_r D_M), SI units throughout (N·m, N, m)."""
    return _rothe_erde(bending_moment, mu, D_M, F_a, F_r)


@law(
    name="rothe_erde_offset",
    family="bearing",
    rotary_only=_ROTARY,
    inputs=("bending_moment",),
    response="torque",
    source=f"{SEED}, Eq. 15 plus a load-independent term (§3.3)",
    params={"mu": mu_rothe_erde, "T0": T0_offset},
    constants={"D_M": GEOMETRY["D_M"], **LOADS},
    notes=(
        "μ (slope) and T0 (intercept) trade off when the design has few low-load points or a "
        "narrow load range; with 0–6 MN·m including zero load both are identified."
    ),
)
def rothe_erde_offset(bending_moment, mu, T0, D_M, F_a, F_r):
    """Rothe Erde plus offset: T = T0 + μ/2 (4.4 M + F_a D_M + 3.81 F_r D_M)."""
    return T0 + _rothe_erde(bending_moment, mu, D_M, F_a, F_r)


# --- SKF 2014 four-term model (seed 000 §2.4) ---------------------------------------------------
_SKF = "SKF (2014) Hauptkatalog friction model, via seed 000 §2.4"
_SKF_RECALLED = (
    "geometry constant for four-point contact ball bearings (series QJ 2) as recalled from the SKF "
    "catalogue table; seed 000 does not list it and it was not verified here"
)
R1 = Param(
    "1",
    Prior("LogNormal", loc=math.log(4.78e-7), scale=0.5),
    "SKF rolling geometry constant R1 (catalogue units: N·mm, mm, N, r/min, mm²/s)",
    f"{_SKF}; {_SKF_RECALLED}; log-sd 0.5 for that uncertainty",
)
S1 = Param(
    "1",
    Prior("LogNormal", loc=math.log(1.20e-2), scale=0.5),
    "SKF sliding geometry constant S1 (catalogue units)",
    f"{_SKF}; {_SKF_RECALLED}; log-sd 0.5 for that uncertainty",
)
mu_bl = Param(
    "1",
    Prior("LogNormal", loc=math.log(0.15), scale=0.3),
    "SKF boundary-lubrication sliding coefficient μ_bl",
    f"{_SKF}: μ_bl = 0.15 (catalogue default); log-sd 0.3",
)
SEAL_DIAMETER_MM = 2000.0
SEAL_EXPONENT = 2.25
K_S1 = Param(
    "1",
    Prior("HalfNormal", scale=1e3 / SEAL_DIAMETER_MM**SEAL_EXPONENT, scaled_by={"response": 1}),
    "SKF seal constant K_S1 (M_seal = K_S1 d_s^β + K_S2 in N·mm, d_s in mm)",
    f"{SEED} §2.4/§3.2: catalogue values exist only up to 340 mm and K_S1 had to be raised "
    "drastically -> broad prior: the seal torque at the default d_s, β is HalfNormal(1)·R "
    "(data scale, bayesfric.priors)",
)
SKF_CONSTANTS = {
    "d_bore": Constant(1.9, "m", "bore diameter d (assumed so that (d + D)/2 = D_M)"),
    "D_outer": Constant(2.3, "m", "outer diameter D (seed 000 §2.1: roughly 2.3 m)"),
    "R2": Constant(2.42, "1", f"SKF R2; {_SKF_RECALLED}"),
    "R3": Constant(1.40e-12, "1", f"SKF R3; {_SKF_RECALLED}"),
    "S2": Constant(0.9, "1", f"SKF S2; {_SKF_RECALLED}"),
    "S3": Constant(1.40e-12, "1", f"SKF S3; {_SKF_RECALLED}"),
    "K_rs": Constant(6e-8, "1", "SKF replenishment constant, 6e-8 for grease (catalogue)"),
    "K_Z": Constant(3.1, "1", "SKF bearing-type constant for four-point contact (catalogue)"),
    "mu_EHL": Constant(0.05, "1", "SKF full-film sliding coefficient, mineral oil (catalogue)"),
    "d_s": Constant(SEAL_DIAMETER_MM, "mm", "seal counterface diameter (assumed)"),
    "beta": Constant(SEAL_EXPONENT, "1", "SKF seal exponent β (contact seal; assumed)"),
    "K_S2": Constant(0.0, "N*mm", "SKF K_S2; a constant collinear with K_S1 d_s^β, fixed at 0"),
    "V_M": Constant(0.0, "1", "SKF drag variable V_M; 0 without an oil bath (grease, H = 0)"),
    "R_S": Constant(0.0, "mm**2", "SKF drag variable R_S; 0 without an oil bath (H = 0)"),
    "f_t": Constant(0.0, "1", "SKF drag variable f_t; 0 without an oil bath (H = 0)"),
}


@law(
    name="skf_2014",
    family="bearing",
    rotary_only=_ROTARY,
    inputs=("velocity", "bending_moment"),
    response="torque",
    source=f"{SEED}, Eq. 3–7 (SKF 2014)",
    params={"R1": R1, "S1": S1, "mu_bl": mu_bl, "K_S1": K_S1},
    constants={**GEOMETRY, **LOADS, "nu": NU, **SKF_CONSTANTS},
    notes=(
        "At pitch speeds φ_bl ≈ 0.94–1, so μ_sl ≈ μ_bl and M_sl ∝ μ_bl·S1: only their product is "
        "identified (priors split it). M_seal = K_S1 d_s^β + K_S2 is one constant: K_S1, d_s, β, "
        "K_S2 are not separable (K_S2 fixed 0). M_rr ∝ R1 (νn)^0.6 is ~1–3 % of the torque at "
        "pitch speeds, so R1 stays at its prior on load-only designs. The bending moment enters "
        "through an equivalent axial load F_a,eq = sin α Σ|Q| (not in the seed)."
    ),
)
def skf_2014(velocity, bending_moment, R1, S1, mu_bl, K_S1, D_M, n_balls, D_RE, alpha, rows,
             F_a, F_r, nu, d_bore, D_outer, R2, R3, S2, S3, K_rs, K_Z, mu_EHL, d_s, beta, K_S2,
             V_M, R_S, f_t):
    """SKF 2014: T = sign(ω)·10⁻³[φ_ish φ_rs G_rr (νn)^0.6 + μ_sl G_sl + M_seal + M_drag] (N·mm in).

    Catalogue forms for four-point contact ball bearings, d_m = 1000·D_M in mm, n in r/min, ν in
    mm²/s, forces in N: G_rr = R1 d_m^1.97 (F_r + F_g + R2 F_a)^0.54, F_g = R3 d_m⁴ n²;
    G_sl = S1 d_m^0.26 ((F_r + F_g')^(4/3) + S2 F_a^(4/3)), F_g' = S3 d_m⁴ n²;
    φ_ish = 1/(1 + 1.84·10⁻⁹ (n d_m)^1.28 ν^0.64); φ_rs = exp(−K_rs ν n (d + D) √(K_Z/(2(D − d))));
    μ_sl = φ_bl μ_bl + (1 − φ_bl) μ_EHL, φ_bl = exp(−2.6·10⁻⁸ (nν)^1.4 d_m);
    M_seal = K_S1 d_s^β + K_S2;
    M_drag (Eq. 7) with K_ball = rows·K_Z (d + D)/(D − d)·10⁻¹²; V_M = R_S = f_t = 0 for a
    grease-lubricated bearing without an oil bath, which makes M_drag = 0 (the equation's value,
    not a dropped term). Simplification (not in the seed): the bending moment enters as the
    equivalent axial load F_a,eq = sin α·Σ|Q| of the rigid-ring ball loads; F_r is the constant.
    """
    geometry = _geometry(D_M, n_balls, D_RE, alpha, rows)
    n = jnp.abs(velocity) * RPM_PER_RAD_S
    dm, d, D = 1e3 * D_M, 1e3 * d_bore, 1e3 * D_outer
    axial = jnp.sin(alpha) * _contact_sum(bending_moment, F_a, F_r, geometry, 1.0)
    radial = jnp.abs(F_r)
    phi_ish = 1.0 / (1.0 + 1.84e-9 * positive_power(n * dm, 1.28) * nu**0.64)
    phi_rs = jnp.exp(-K_rs * nu * n * (d + D) * math.sqrt(K_Z / (2.0 * (D - d))))
    g_rr = R1 * dm**1.97 * positive_power(radial + R3 * dm**4 * n**2 + R2 * axial, 0.54)
    m_rr = phi_ish * phi_rs * g_rr * positive_power(nu * n, 0.6)
    g_sl = S1 * dm**0.26 * (
        positive_power(radial + S3 * dm**4 * n**2, 4.0 / 3.0) + S2 * positive_power(axial, 4.0 / 3.0)
    )
    phi_bl = jnp.exp(-2.6e-8 * positive_power(n * nu, 1.4) * dm)
    m_sl = (phi_bl * mu_bl + (1.0 - phi_bl) * mu_EHL) * g_sl
    m_seal = K_S1 * positive_power(d_s, beta) + K_S2
    k_ball = rows * K_Z * (d + D) / (D - d) * 1e-12
    churn = n * dm**2 * f_t / nu
    has_bath = (churn > 0) & (R_S > 0)
    m_drag = 0.4 * V_M * k_ball * dm**5 * n**2 + jnp.where(
        has_bath, 1.093e-7 * n**2 * dm**3 * positive_power(jnp.where(has_bath, churn, 1.0), -1.379) * R_S, 0.0
    )
    return jnp.sign(velocity) * 1e-3 * (m_rr + m_sl + m_seal + m_drag)


# --- Wang rheological model, reduced order (seed 000 §2.5) --------------------------------------
kappa = Param(
    "1",
    Prior("LogNormal", loc=math.log(0.01), scale=1.0),
    "hysteresis (damping) loss factor κ of the bearing steel, Eq. 10",
    f"{SEED} Eq. 10 after Johnson; hysteresis loss of hardened steel in rolling is of the order "
    "of 1 % (Johnson, Contact Mechanics 1985, §9.2; order of magnitude) -> median 0.01, log-sd 1",
)
T_roll = Param(
    "N*m",
    Prior("HalfNormal", scale=1.0, scaled_by={"response": 1, "velocity": -0.66}),
    "hydrodynamic rolling torque at ω_ref with every contact at Q_ref (Eq. 11–12, C_th included)",
    f"{SEED} Eq. 11–12; {_GENERIC}",
)
tau_lim = Param(
    "Pa",
    Prior("LogNormal", loc=math.log(8e7), scale=0.7),
    "limiting shear stress τ_lim of the lubricant in the EHL contact, Eq. 13",
    f"{SEED} §2.5 (τ limited to τ_lim, Wang 2015); τ_lim ≈ 0.05–0.1 of the mean Hertz pressure "
    "(1–2 GPa) for mineral base oils (Bair & Winer 1979) -> median 80 MPa, log-sd 0.7",
)
omega_lim = Param(
    "rad/s",
    Prior("LogNormal", loc=0.0, scale=1.5, scaled_by={"velocity": 1}),
    "pitch speed at which the Newtonian sliding shear stress reaches τ_lim",
    f"{SEED} §2.5 (Newtonian τ ∝ sliding speed, saturating at τ_lim); {_GENERIC}",
)
WANG_CONSTANTS = {
    "E_star": Constant(1.14e11, "Pa", "contact modulus of steel on steel, E = 208 GPa, ν = 0.3"),
    "Q_ref": Constant(1e4, "N", "reference contact load of T_roll"),
    "omega_ref": Constant(1.0, "rad/s", "reference speed of T_roll"),
}
ROLL_SPEED_EXPONENT = 0.66  # Goksem & Hargreaves / Houpert EHL rolling force ∝ U^0.66
ROLL_LOAD_EXPONENT = 0.47  # ... and ∝ W^0.47


@law(
    name="wang_reduced",
    family="bearing",
    rotary_only=_ROTARY,
    inputs=("velocity", "bending_moment"),
    response="torque",
    source=f"{SEED}, Eq. 8–14 (Wang 2015), reduced order",
    params={"kappa": kappa, "T_roll": T_roll, "tau_lim": tau_lim, "omega_lim": omega_lim},
    constants={**GEOMETRY, **LOADS, **WANG_CONSTANTS},
    notes=(
        "Reduced order: Hertz contacts as circles of radius b (rolling-direction curvature only), "
        "rolling force ∝ speed^0.66·Q^0.47 with C_th and viscosity folded into T_roll, one smooth "
        "saturation τ = τ_lim tanh(ω/ω_lim) for spin + Heathcote sliding (Eq. 9, 13, 14). On a "
        "design with speeds all well below ω_lim only τ_lim/ω_lim is identified; all well above, "
        "only τ_lim. κ (∝ ΣQ^(4/3)) and τ_lim (∝ ΣQ) are nearly collinear on load-only designs: "
        "they separate only through the speed dependence of the sliding term. No seal or other "
        "load-independent term: zero torque at zero load (as Wang's model, seed §3.2)."
    ),
)
def wang_reduced(velocity, bending_moment, kappa, T_roll, tau_lim, omega_lim, D_M, n_balls, D_RE,
                 alpha, rows, F_a, F_r, E_star, Q_ref, omega_ref):
    """Wang (reduced): T = sign(ω)[M_def + M_roll + M_slide] from the rigid-ring contact loads Q_i.

    Every loaded contact pair has an inner and an outer contact (factor 2); a ball-level moment
    is transferred to the ring by the speed ratio ω_RE/ω_ring ≈ D_M/(2 D_RE) (energy balance of
    Eq. 11 and 14, γ = D_RE cos α/D_M neglected). R_x = D_RE/2, circular Hertz contact
    b_i = (3 Q_i R_x/(4 E*))^(1/3).
    M_def (Eq. 10) = 2·(3/16) κ (D_M/(2 D_RE)) Σ b_i Q_i
                   = (3/16) κ (D_M/D_RE) (3R_x/(4E*))^(1/3) ΣQ^(4/3).
    M_roll (Eq. 11–12) = T_roll (|ω|/ω_ref)^0.66 · mean of (Q_i/Q_ref)^0.47 over all 2·rows·Z
    contacts.
    M_slide (Eq. 9, 13, 14): spin moment of a uniform shear τ on the contact circle,
    ∫ r τ dA = (2π/3) τ b³ = τ π Q R_x/(2E*), ring speed ratio (D_M/(2 D_RE)) sin α, two contacts:
    M_slide = τ_lim tanh(|ω|/ω_lim) (π R_x/(2E*)) (D_M/D_RE) sin α ΣQ.
    """
    geometry = _geometry(D_M, n_balls, D_RE, alpha, rows)
    speed = jnp.abs(velocity)
    r_x = 0.5 * D_RE
    n_contacts = 2 * int(rows) * int(n_balls)
    sum_q = _contact_sum(bending_moment, F_a, F_r, geometry, 1.0)
    sum_q43 = _contact_sum(bending_moment, F_a, F_r, geometry, 4.0 / 3.0)
    sum_q047 = _contact_sum(bending_moment, F_a, F_r, geometry, ROLL_LOAD_EXPONENT)
    width_per_load = (3.0 * r_x / (4.0 * E_star)) ** (1.0 / 3.0)  # b = width_per_load · Q^(1/3)
    m_def = 3.0 / 16.0 * kappa * (D_M / D_RE) * width_per_load * sum_q43
    m_roll = (T_roll * power_ratio(speed, omega_ref, ROLL_SPEED_EXPONENT)
              * sum_q047 / (n_contacts * Q_ref**ROLL_LOAD_EXPONENT))
    m_slide = (tau_lim * jnp.tanh(speed / omega_lim) * math.pi * r_x / (2.0 * E_star)
               * (D_M / D_RE) * jnp.sin(alpha) * sum_q)
    return jnp.sign(velocity) * (m_def + m_roll + m_slide)
