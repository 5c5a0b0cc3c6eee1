"""Calibration of sizing beyond the tested envelope (issues #10, #28): how often does the nominal
90 % band of the model-averaged friction curve cover the true mean curve, within-model and
calibrated for the model-form error that a blocked fold measured?

Each replicate simulates 30 speeds in 0.1–2 rad/s (normal noise, sd 0.3 N·m), fits the candidate
laws ``coulomb_viscous`` and ``coulomb``, refits them on a blocked fold inside the data (train ≤
1.0 rad/s, score the 16 points above: what a study does), weights them by stacking on that fold,
measures each law's miss there and its misfit at the data (:mod:`bayesfric.sizing.misfit`), and
sizes the range 2.5–4 rad/s (0.26–1.05 tested ranges beyond the data) through
:func:`bayesfric.sizing.answer_question`, exactly as ``bayesfric size`` does.

Posteriors are **exact** rather than sampled: both candidates are linear in their coefficients, so
with flat priors on them and ``p(σ²) ∝ 1/σ²`` the posterior is normal-inverse-χ² and is drawn
directly (2 chains × 500 draws), for the full fit and the fold alike. This tests the sizing and
calibration method, not the sampler (NUTS is checked against such posteriors elsewhere), and
makes 200 replicates per scenario affordable.

Scenarios (truth = mean torque at speed v > 0):

* the true law is a candidate: ``5 + 2 v`` (coulomb_viscous);
* no candidate is the true law: viscous plus quadratic churning drag, a sub-linear viscous term
  ``4 + 3 v^0.6`` (the case the within-model band covered 41 % of new observations in before),
  a Stribeck dip on a linear law, and a Stribeck decay plus a gear power-law viscous term ``3 √v``
  (the robot-joint generator's shape).

Asserted (R = 200): when the truth is a candidate, the calibrated band covers it at 3 rad/s in
85–95 % of replicates (consistent at 1 % false alarm) with median width ≤ 1.5× the within-model
width at every reported point; in the first three non-candidate scenarios it covers the true
curve in ≥ 85 % at every reported point (2.5, 3 and 4 rad/s). The Stribeck + gear power-law
scenario falls short (74–80.5 %): its fold's miss is mostly within one standard error of zero, so
the rate is often estimated as 0 (see :mod:`bayesfric.sizing.calibration`); the test asserts
only that calibration lifts its coverage well above the within-model one and prints the figure,
which docs/sizing.md states. ``benchmarks/bench_calibration_frontier.py`` shows why no rule does much
better at this data size: the fold's standardised miss hardly differs from when the candidate is
the truth (AUC 0.62 between the two). With the fold at 1.4 rad/s (ten held-out points) the sub-linear case
fell short too (83 % at 3 rad/s, with the miss offset at 0.2). Figures: docs/sizing.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special, stats

from bayesfric import compare, sizing
from bayesfric.compare.heldout import HeldOut
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.sizing.calibration import Scheme, measure_miss
from bayesfric.sizing.misfit import local_misfit
from tests.sizing_helpers import PASSED, hand_fit

REPLICATES = 200
SIGMA = 0.3
SPEEDS = np.linspace(0.1, 2.0, 30)
CUT = 1.0
ASKED = "2.5..4 rad/s"
REPORT_AT = (2.5, 3.0, 4.0)  # rad/s: grid points of the asked range (25 points, 0.0625 apart)
ASSERT_AT = 3.0
CHAINS, DRAWS = 2, 500
DESIGN = {"coulomb_viscous": lambda v: np.c_[np.sign(v), v], "coulomb": lambda v: np.sign(v)[:, None]}
PARAMS = {"coulomb_viscous": ("T_C", "c_v"), "coulomb": ("T_C",)}
COVERED = {  # no candidate is the truth; asserted >= 85 %
    "viscous + quadratic drag": lambda v: 4.0 + 1.0 * v + 0.8 * v**2,
    "sub-linear viscous": lambda v: 4.0 + 3.0 * v**0.6,
    "Stribeck dip + linear": lambda v: 3.0 + 2.0 * np.exp(-((v / 0.3) ** 2)) + 2.0 * v,
}
SHORT = {  # no candidate is the truth; below 85 % (the fold hardly sees the miss): stated, not hidden
    "Stribeck + gear power law": lambda v: 2.0 + 2.0 * np.exp(-np.sqrt(v / 0.1)) + 3.0 * np.sqrt(v),
}
TRUTHS = {"candidate": lambda v: 5.0 + 2.0 * v, **COVERED, **SHORT}


def posterior(x: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Exact posterior draws (coefficients (S, p), sigma (S,)) of y = x β + N(0, σ²)."""
    n, p = x.shape
    xtx = x.T @ x
    beta_hat = np.linalg.solve(xtx, x.T @ y)
    s2 = float(np.sum((y - x @ beta_hat) ** 2)) / (n - p)
    s = CHAINS * DRAWS
    sigma2 = (n - p) * s2 / rng.chisquare(n - p, s)
    chol = np.linalg.cholesky(np.linalg.inv(xtx))
    beta = beta_hat + np.sqrt(sigma2)[:, None] * (rng.standard_normal((s, p)) @ chol.T)
    return beta, np.sqrt(sigma2)


def law_pieces(name: str, y: np.ndarray, heldout: np.ndarray, label: str, rng: np.random.Generator):
    """The full fit (a DataTree as sampled fits are) and the blocked fold's CVResult of a law."""
    x = DESIGN[name](SPEEDS)
    beta, sigma = posterior(x, y, rng)
    shape = (CHAINS, DRAWS)
    draws = {k: beta[:, i].reshape(shape) for i, k in enumerate(PARAMS[name])} | {"sigma": sigma.reshape(shape)}
    fit = hand_fit(name, draws, {"velocity": SPEEDS})
    beta_f, sigma_f = posterior(x[~heldout], y[~heldout], rng)
    mu = beta_f @ x[heldout].T  # (S, n_heldout)
    lpd = special.logsumexp(stats.norm.logpdf(y[heldout], mu, sigma_f[:, None]), axis=0) - math.log(mu.shape[0])
    elpd_i = np.full(SPEEDS.size, np.nan)
    elpd_i[heldout] = lpd
    index = np.flatnonzero(heldout)
    cv = compare.CVResult(name, label, float(lpd.sum()), float(np.sqrt(lpd.size * lpd.var())), elpd_i, heldout,
                          [PASSED], 0.0, predictive=HeldOut(index, np.zeros(index.size, dtype=int), mu,
                                                            np.full(index.size, float(np.mean(sigma_f**2)))))
    return fit, cv


def sources(y: np.ndarray, rng: np.random.Generator) -> tuple[list[sizing.LawSource], Scheme]:
    """Every candidate's LawSource, weighted and with its measured miss, as a study gives them."""
    ds = make_dataset({"velocity": SPEEDS}, y)
    folds = compare.blocked_masks(ds, "velocity", threshold=CUT, direction="upper")
    label = folds.labels[0]
    scheme = Scheme(label, "velocity", "upper")
    pieces = {name: law_pieces(name, y, folds.heldout[0], label, rng) for name in DESIGN}
    weights = compare.model_weights({k: cv for k, (_, cv) in pieces.items()}, method="stacking")
    out = []
    for name, (fit, cv) in pieces.items():
        miss = measure_miss(cv, ds, scheme)
        out.append(sizing.LawSource(name, fit, {label: weights.weights.get(name, 0.0)},
                                    misses={label: miss} if miss is not None else {}))
    return out, scheme


def calibrate(replicates: int = REPLICATES, seed: int = 2026) -> dict:
    """Per scenario and reported point: coverage of the true mean curve, within-model and
    calibrated, and the calibrated width relative to the within-model width."""
    rng = np.random.default_rng(seed)
    question = sizing.check_question(sizing.make_question({"velocity": ASKED}, 0.9), ["velocity"], ["velocity"],
                                     "torque")
    x = question.grid()["velocity"]
    cols = [int(np.argmin(np.abs(x - v))) for v in REPORT_AT]
    out = {}
    for scenario, truth in TRUTHS.items():
        within, calibrated, ratio, new_obs = [], [], [], []
        mu = np.abs(truth(x))
        for r in range(replicates):
            y = truth(SPEEDS) + rng.normal(0, SIGMA, SPEEDS.size)
            laws, scheme = sources(y, rng)
            misfits = {s.name: local_misfit(s.fit, {"velocity": SPEEDS}, y, r) for s in laws}  # as sizing.answer
            answer = sizing.answer_question(question, laws, {"velocity": SPEEDS}, schemes=[scheme], seed=r, fan=False,
                                            misfits=misfits)
            mix, cal = answer.average, answer.average.calibrated
            within.append((mix.mean_fn.q(0.05) <= mu) & (mu <= mix.mean_fn.q(0.95)))
            calibrated.append((cal.mean_fn.q(0.05) <= mu) & (mu <= cal.mean_fn.q(0.95)))
            ratio.append((cal.mean_fn.q(0.95) - cal.mean_fn.q(0.05)) / (mix.mean_fn.q(0.95) - mix.mean_fn.q(0.05)))
            new = np.abs(truth(x) + rng.normal(0, SIGMA, x.size))
            new_obs.append((cal.noisy.q(0.05) <= new) & (new <= cal.noisy.q(0.95)))
        out[scenario] = {
            "x": x[cols], "distance": sizing.extrapolation_distance(x[cols], SPEEDS[0], SPEEDS[-1]),
            "within": np.mean(within, axis=0)[cols], "calibrated": np.mean(calibrated, axis=0)[cols],
            "width ratio": np.median(ratio, axis=0)[cols], "new observation": np.mean(new_obs, axis=0)[cols],
            "covers": int(np.sum(np.asarray(calibrated)[:, cols[REPORT_AT.index(ASSERT_AT)]])),
        }
    return out


def acceptance(replicates: int, level: float = 0.01) -> tuple[int, int]:
    """Counts of covers consistent with a coverage in [0.85, 0.95] (false alarm ≤ ``level``)."""
    low = int(stats.binom.ppf(level, replicates, 0.85))  # P(X < low | 0.85) ≤ level
    high = int(stats.binom.isf(level, replicates, 0.95))  # P(X > high | 0.95) ≤ level
    return low, high


def table(result: dict) -> str:
    """The figures as printed (and quoted in docs/sizing.md)."""
    lines = []
    for scenario, r in result.items():
        lines.append(f"{scenario}:")
        for i, v in enumerate(r["x"]):
            lines.append(f"  v = {v:.2f} rad/s (distance {r['distance'][i]:.2f}): 90 % band of the mean curve covers "
                         f"the truth {r['within'][i]:.1%} within-model, {r['calibrated'][i]:.1%} calibrated (median "
                         f"width {r['width ratio'][i]:.2f}x); calibrated band with noise covers a new observation "
                         f"{r['new observation'][i]:.1%}")
    return "\n".join(lines)


@pytest.mark.slow
def test_calibrated_sizing_covers_the_truth_beyond_the_envelope():
    result = calibrate()
    print("\n" + table(result))
    i = REPORT_AT.index(ASSERT_AT)
    low, high = acceptance(REPLICATES)
    assert low <= result["candidate"]["covers"] <= high
    assert np.all(result["candidate"]["width ratio"] <= 1.5)
    for scenario in COVERED:
        assert np.all(result[scenario]["calibrated"] >= 0.85), scenario
    for scenario in SHORT:
        assert result[scenario]["calibrated"][i] > result[scenario]["within"][i] + 0.3, scenario
