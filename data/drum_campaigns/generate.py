"""Generate the *reconstructed* multi-campaign drum roll-out tests (seeds 003, 004) -- not measured.

Usage: ``python data/drum_campaigns/generate.py [OUTDIR]`` writes ``drum_campaigns.csv``,
``drum_campaigns.toml`` and ``truth.json`` (default OUTDIR: this folder). Bit-identical on every
run: numpy float64, fixed-step RK4, one fixed seed, fixed text formats.

What is simulated (README.md gives sources and reasons): the return pulley of seed 003 in its
second set-up (bearings plus the two O-rings, Sec. 4) is taken out of service for a roll-out
(coast-down) test campaign every 1000 operating hours, 0 h to 6000 h. In each campaign it is spun
up to about 400, 800 and 1200 rpm, released, and coasts down, ``J dω/dt = -τ(ω, θ; h)``. The
friction truth is drum_rollout's multi-mechanism law (``data/drum_rollout/generate.py``), whose
parameters move with the service hours h:

* the O-ring constant torque and the O-ring speed coefficient grow with wear, with a mild
  acceleration (quadratic in h) -- Sec. 3.2: O-ring friction varies "with hours of operation" and
  "with increasing wearout, e.g. by abrasion";
* the bearing torque grows linearly (abrasion as an increased rolling friction, Sec. 3.1) and its
  once-per-revolution ripple grows with it (damage gives ripple, Sec. 5, Fig. 10);
* each campaign scatters around the trend (temperature on the day, re-assembly of the O-rings on
  the test rig): the two linear parameters that seed 004 finds temperature dependent between
  series (a constant and a speed coefficient) and the bearing torque get a random factor per
  campaign, shared by the campaign's three coast-downs. This scatter is far larger than the
  encoder's measurement noise.

At h = 0 the trend equals drum_rollout's bearings + O-rings truth exactly. ``truth.json`` holds
the trend, every campaign's parameters, the trend's friction torque at 1400 rpm against hours
and the service time at which it first exceeds the assumed capacity (README.md §2).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from bayesfric.laws.drum import DRUM_INERTIA  # the one inertia shared with the coast-down laws

NAME = "drum_campaigns"
SEED = 30031  # seed 003, second data set
PAPER = "Modeling a drum motor for illustrating wearout phenomena"
SHORT = "Modeling a drum motor for illustrating wearout phenomena (seed 003)"
DRIFT_PAPER = "Velocity dependence of joint friction in robotic manipulators with gear transmissions"

RPM = 2.0 * np.pi / 60.0

# -- campaigns and runs ----------------------------------------------------------------------------
HOURS = (0, 1000, 2000, 3000, 4000, 5000, 6000)  # service hours of each test campaign
RELEASE_RPM = (400.0, 800.0, 1200.0)  # nominal release speeds, as in drum_rollout
RELEASE_JITTER_RPM = 10.0  # the operator releases within +-10 rpm of the nominal speed
HOUR_SCALE = 1000.0  # u = h / 1000 h in the trend polynomials

# -- friction truth at h = 0 (N*m; omega in rad/s, theta in rad): drum_rollout's, bearings + O-rings
BEARING_STATIC = 0.21
BEARING_RISE = 0.06
BEARING_RISE_SPEED = 40.0  # rad/s
RIPPLE = 0.012
WINDAGE = 8.0e-7  # N*m*s^2/rad^2
ORING_CONSTANT = 0.72
ORING_SPEED_COEFF = 1.1e-3  # N*m at 1 rad/s
ORING_SPEED_POWER = 0.85
ORING_BREAKAWAY = 0.05
ORING_BREAKAWAY_SPEED = 4.0  # rad/s

# -- wear trend, u = h / 1000 h (assumed; README.md §2) ---------------------------------------------
ORING_CONSTANT_TREND = (ORING_CONSTANT, 0.040, 0.0030)  # N*m: c0 + c1 u + c2 u^2
ORING_SPEED_TREND = (1.0, 0.060, 0.0040)  # factor on ORING_SPEED_COEFF: 1 + c1 u + c2 u^2
BEARING_STATIC_TREND = (BEARING_STATIC, 0.008, 0.0)  # N*m, linear abrasion
RIPPLE_TREND = (1.0, 0.10, 0.0)  # factor on RIPPLE

# -- campaign-to-campaign scatter: log-normal factors, one draw per campaign -----------------------
SCATTER_ORING_CONSTANT = 0.03  # sd of log factor on the O-ring constant
SCATTER_ORING_SPEED = 0.06  # ... on the O-ring speed coefficient
SCATTER_BEARING = 0.04  # ... on the bearing torque (static + rise)

# -- the forecast question ------------------------------------------------------------------------
QUERY_RPM = 1400.0  # operating point of the question
CAPACITY = 1.8  # N*m at 1400 rpm: assumed friction allowance of the drive (README.md §2)
TORQUE_GRID_HOURS = tuple(range(0, 15001, 250))

# -- integration, encoder, subsampling (as drum_rollout) -------------------------------------------
DT = 1.0e-3  # s
COUNTS_PER_REV = 8192
VELOCITY_WINDOW = 10  # samples (10 ms)
ROWS_PER_RUN = 48
TAIL = 1.06


def poly(coeffs: tuple[float, ...], hours) -> np.ndarray:
    """c0 + c1 u + c2 u^2 with u = hours / 1000 h."""
    u = np.asarray(hours, dtype=float) / HOUR_SCALE
    return coeffs[0] + coeffs[1] * u + coeffs[2] * u**2


def trend_parameters(hours) -> dict[str, np.ndarray]:
    """The wear trend's parameters (no campaign scatter) at ``hours``."""
    return {
        "bearing_static": poly(BEARING_STATIC_TREND, hours),
        "bearing_rise": BEARING_RISE * np.ones_like(np.asarray(hours, dtype=float)),
        "ripple": RIPPLE * poly(RIPPLE_TREND, hours),
        "oring_constant": poly(ORING_CONSTANT_TREND, hours),
        "oring_speed_coeff": ORING_SPEED_COEFF * poly(ORING_SPEED_TREND, hours),
    }


def mean_torque(omega, p: dict) -> np.ndarray:
    """Friction torque (N*m) averaged over a revolution (the ripple averages out), ``omega`` >= 0."""
    omega = np.asarray(omega, dtype=float)
    bearing = p["bearing_static"] + p["bearing_rise"] * (1.0 - np.exp(-omega / BEARING_RISE_SPEED))
    oring = (
        p["oring_constant"]
        + p["oring_speed_coeff"] * omega**ORING_SPEED_POWER
        + ORING_BREAKAWAY * np.exp(-omega / ORING_BREAKAWAY_SPEED)
    )
    return bearing + WINDAGE * omega**2 + oring


def friction_torque(omega, theta, p: dict, phase) -> np.ndarray:
    """Instantaneous friction torque: the mean torque plus the once-per-revolution ripple."""
    return mean_torque(omega, p) + p["ripple"] * np.sin(theta + phase)


def coast_down(omega0: np.ndarray, p: dict, phase: np.ndarray, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """RK4 integration of all runs at once (columns); returns angle and speed on the 1 kHz clock."""
    theta = np.zeros((n_steps + 1, omega0.size))
    omega = np.zeros((n_steps + 1, omega0.size))
    omega[0] = omega0

    def rhs(th, om):
        om = np.maximum(om, 0.0)
        return om, -friction_torque(om, th, p, phase) / DRUM_INERTIA

    for k in range(n_steps):
        th, om = theta[k], omega[k]
        moving = om > 0.0
        k1t, k1o = rhs(th, om)
        k2t, k2o = rhs(th + 0.5 * DT * k1t, om + 0.5 * DT * k1o)
        k3t, k3o = rhs(th + 0.5 * DT * k2t, om + 0.5 * DT * k2o)
        k4t, k4o = rhs(th + DT * k3t, om + DT * k3o)
        new_theta = th + DT / 6.0 * (k1t + 2 * k2t + 2 * k3t + k4t)
        new_omega = om + DT / 6.0 * (k1o + 2 * k2o + 2 * k3o + k4o)
        theta[k + 1] = np.where(moving, new_theta, th)
        omega[k + 1] = np.where(moving, np.maximum(new_omega, 0.0), 0.0)
    return theta, omega


def encoder_velocity(theta: np.ndarray, omega0: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Count-difference velocity (rad/s) over ``VELOCITY_WINDOW`` samples, per run (columns)."""
    before = -omega0 * DT * np.arange(VELOCITY_WINDOW, 0, -1)[:, None]
    angle = np.vstack([before, theta])
    counts = np.floor(angle * COUNTS_PER_REV / (2.0 * np.pi) + offset)
    diff = counts[VELOCITY_WINDOW:] - counts[:-VELOCITY_WINDOW]
    return diff * (2.0 * np.pi / COUNTS_PER_REV) / (VELOCITY_WINDOW * DT)


def trend_torque_at_query(hours) -> np.ndarray:
    """The trend's friction torque (N*m) at ``QUERY_RPM`` against service hours."""
    return mean_torque(QUERY_RPM * RPM, trend_parameters(hours))


def crossing_hours(capacity: float = CAPACITY, lo: float = 0.0, hi: float = 50000.0) -> float:
    """First service time (h) at which the trend's torque at 1400 rpm reaches ``capacity``.

    The torque rises monotonically with hours (every trend coefficient is >= 0), so bisection on
    [lo, hi] finds the one crossing; 200 halvings reach float64 resolution.
    """
    if trend_torque_at_query(lo) >= capacity:
        return lo
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if trend_torque_at_query(mid) >= capacity:
            hi = mid
        else:
            lo = mid
    return hi


TITLE = (
    "Roll-out (coast-down) tests of a return pulley with bearings + O-rings in 7 campaigns over "
    f"0-6000 service hours (reconstructed from {SHORT})"
)
SOURCE = (
    f"{PAPER}: Sec. 4 (roll-out tests; bearings + O-rings about 0.95 N*m + 0.1 N*m per 1000 rpm, "
    "bearings 0.2-0.3 N*m), Sec. 3.2 (Eq. 6; O-ring friction varies with hours of operation and "
    "with wearout), Sec. 3.1 (abrasion as increased rolling friction); "
    f"{DRIFT_PAPER} (seed 004), end of Sec. 4 and Sec. 6 (the linear parameters are temperature "
    "dependent and change during operation; series measured after warm-up)"
)
DESCRIPTION = (
    "Encoder speed of a coasting return pulley against time since release, three runs per "
    "campaign, one campaign every 1000 h of service. Pulley inertia "
    f"{DRUM_INERTIA:g} kg*m^2. Synthetic values from drum_rollout's multi-mechanism truth with "
    "wear trends and campaign scatter (assumed); see data/drum_campaigns/README.md and truth.json."
)


def toml_text() -> str:
    """The sidecar read by :func:`bayesfric.datasets.load_dataset`."""
    return f'''[dataset]
name = "{NAME}"
title = "{TITLE}"
provenance = "reconstructed"
source = "{SOURCE}"
description = "{DESCRIPTION}"
trajectory = "run"

[columns.time]
role = "input"
quantity = "time"
unit = "s"

[columns.initial_velocity]
role = "input"
quantity = "initial_velocity"
unit = "rpm"

[columns.run]
role = "group"

[columns.hours]
role = "group"
unit = "h"

[columns.velocity]
role = "response"
quantity = "velocity"
unit = "rpm"
'''


def _rounded(values, digits: int = 6) -> list[float]:
    return [round(float(v), digits) for v in np.atleast_1d(values)]


def truth_dict(campaign_params: list[dict], runs: list[dict]) -> dict:
    """Everything a study or test needs to score a forecast against the truth."""
    grid = np.array(TORQUE_GRID_HOURS, dtype=float)
    crossing = crossing_hours()
    return {
        "name": NAME,
        "provenance": "reconstructed",
        "note": ("RECONSTRUCTED, not measured: the truth of data/drum_campaigns/generate.py. Trend "
                 "parameters are c0 + c1*u + c2*u^2 with u = hours / 1000 h; the torque law and "
                 "units are in README.md section 3."),
        "inertia_kg_m2": DRUM_INERTIA,
        "torque_law": ("tau(omega) = bearing_static + bearing_rise*(1 - exp(-omega/bearing_rise_speed)) "
                       "+ windage*omega^2 + oring_constant + oring_speed_coeff*omega^oring_speed_power "
                       "+ oring_breakaway*exp(-omega/oring_breakaway_speed) "
                       "[+ ripple*sin(theta + phase), zero on average]; tau in N*m, omega in rad/s"),
        "fixed": {
            "bearing_rise_speed": BEARING_RISE_SPEED,
            "windage": WINDAGE,
            "oring_speed_power": ORING_SPEED_POWER,
            "oring_breakaway": ORING_BREAKAWAY,
            "oring_breakaway_speed": ORING_BREAKAWAY_SPEED,
        },
        "trend": {
            "hour_scale_h": HOUR_SCALE,
            "bearing_static": list(BEARING_STATIC_TREND),
            "bearing_rise": [BEARING_RISE, 0.0, 0.0],
            "ripple": [RIPPLE * c for c in RIPPLE_TREND],
            "oring_constant": list(ORING_CONSTANT_TREND),
            "oring_speed_coeff": [ORING_SPEED_COEFF * c for c in ORING_SPEED_TREND],
        },
        "scatter_log_sd": {
            "oring_constant": SCATTER_ORING_CONSTANT,
            "oring_speed_coeff": SCATTER_ORING_SPEED,
            "bearing": SCATTER_BEARING,
        },
        "campaigns": [
            {
                "hours": h,
                "runs": [r["run"] for r in runs if r["hours"] == h],
                **{k: round(float(v), 9) for k, v in p.items()},
                "torque_at_query_Nm": round(float(mean_torque(QUERY_RPM * RPM, p)), 6),
                "trend_torque_at_query_Nm": round(float(trend_torque_at_query(h)), 6),
            }
            for h, p in zip(HOURS, campaign_params, strict=True)
        ],
        "runs": runs,
        "query": {
            "speed_rpm": QUERY_RPM,
            "capacity_Nm": CAPACITY,
            "capacity_meaning": ("assumed friction allowance of the drive at 1400 rpm: the torque "
                                 "left for the drum's own seal and bearing friction (the paper gives "
                                 "no motor rating; README.md section 2)"),
            "trend_torque_hours": list(TORQUE_GRID_HOURS),
            "trend_torque_Nm": _rounded(trend_torque_at_query(grid)),
            "crossing_hours": round(crossing, 3),
            "crossing_definition": ("first service time at which the trend's (campaign-scatter-free) "
                                    "friction torque at 1400 rpm reaches capacity_Nm"),
            "crossing_over_last_campaign": round(crossing / HOURS[-1], 4),
        },
    }


def main(outdir: Path) -> None:
    """Write ``drum_campaigns.csv``, ``drum_campaigns.toml`` and ``truth.json`` into ``outdir``."""
    rng = np.random.default_rng(SEED)
    n_c, n_r = len(HOURS), len(RELEASE_RPM)
    # campaign scatter first (one draw per campaign and parameter), then the per-run draws
    z = rng.standard_normal((n_c, 3))
    campaign_params = []
    for c, h in enumerate(HOURS):
        p = {k: float(v) for k, v in trend_parameters(h).items()}
        p["oring_constant"] *= float(np.exp(SCATTER_ORING_CONSTANT * z[c, 0]))
        p["oring_speed_coeff"] *= float(np.exp(SCATTER_ORING_SPEED * z[c, 1]))
        bearing_factor = float(np.exp(SCATTER_BEARING * z[c, 2]))
        p["bearing_static"] *= bearing_factor
        p["bearing_rise"] *= bearing_factor
        campaign_params.append(p)
    release = np.array([[rpm for rpm in RELEASE_RPM] for _ in HOURS]).ravel()
    release = release + rng.uniform(-RELEASE_JITTER_RPM, RELEASE_JITTER_RPM, release.size)
    phase = rng.uniform(0.0, 2.0 * np.pi, release.size)
    offset = rng.uniform(0.0, 1.0, release.size)
    omega0 = release * RPM
    p_runs = {k: np.repeat([p[k] for p in campaign_params], n_r) for k in campaign_params[0]}
    # the slowest deceleration: every run's torque exceeds 0.8 N*m (bearing + O-ring constants)
    n_steps = int(np.ceil(TAIL * omega0.max() * DRUM_INERTIA / 0.8 / DT))
    theta, omega = coast_down(omega0, p_runs, phase, n_steps)
    velocity = encoder_velocity(theta, omega0, offset)
    lines = [
        f"# RECONSTRUCTED from {PAPER} (seed 003) -- not measured data",
        "time,initial_velocity,run,hours,velocity",
    ]
    runs = []
    for j in range(release.size):
        hours = HOURS[j // n_r]
        stop = int(np.argmax(omega[:, j] <= 0.0))
        if omega[stop, j] > 0.0:
            raise RuntimeError("a run did not stop within the integration window")
        picks = np.unique(np.round(np.linspace(0, TAIL * stop, ROWS_PER_RUN)).astype(int))
        initial_rpm = velocity[0, j] / RPM
        runs.append({"run": j + 1, "hours": hours, "release_rpm": round(float(release[j]), 4),
                     "stop_s": round(stop * DT, 3)})
        for k in picks:
            lines.append(f"{k * DT:.3f},{initial_rpm:.4f},{j + 1:d},{hours:d},{velocity[k, j] / RPM:.4f}")
    outdir.mkdir(parents=True, exist_ok=True)
    (outdir / f"{NAME}.csv").write_text("\n".join(lines) + "\n")
    (outdir / f"{NAME}.toml").write_text(toml_text())
    truth = truth_dict(campaign_params, runs)
    (outdir / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
