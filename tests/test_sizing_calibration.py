"""Calibration of sizing beyond the tested envelope (issues #10, #28): how often does the nominal
90 % band of the model-averaged friction curve cover the true mean curve, within-model and
calibrated for the model-form error that a blocked fold measured?

Each replicate simulates 30 speeds in 0.1–2 rad/s (normal noise, sd 0.3 N·m), fits the candidate
laws ``coulomb_viscous`` and ``coulomb``, refits them on a blocked fold inside the data (train ≤
1.0 rad/s, score the 16 points above: what a study does), weights them by Bayesian-bootstrap
stacking on that fold (:func:`bayesfric.compare.weights.bootstrap_stacking`), measures each law's
miss there and its misfit at the data (:mod:`bayesfric.sizing.misfit`), and sizes the range 2.5–4
rad/s (0.26–1.05 tested ranges beyond the data) through :func:`bayesfric.sizing.answer_question`,
exactly as ``bayesfric size`` does. Each case also reports the mean interval score (Gneiting &
Raftery 2007) of the within-model and the calibrated band, and how often the answer said the
fold cannot tell a weighted law from the truth (``Answer.undetected``).

Posteriors are **exact** rather than sampled: both candidates are linear in their coefficients, so
with flat priors on them and ``p(σ²) ∝ 1/σ²`` the posterior is normal-inverse-χ² and is drawn
directly (2 chains × 500 draws), for the full fit and the fold alike. This tests the sizing and
calibration method, not the sampler (NUTS is checked against such posteriors elsewhere), and
makes 200 replicates per scenario affordable.

Scenarios (truth = mean torque at speed v > 0):

* the true law is a candidate: ``5 + 2 v`` (coulomb_viscous);
* no candidate is the true law (eight shapes): viscous plus quadratic churning drag, a sub-linear
  viscous term ``4 + 3 v^0.6``, a Stribeck dip on a linear law, three concave ones (saturating
  ``3 + 4 (1 − e^(−v/0.8))``, logarithmic, tanh + viscous), a convex accelerating one
  ``4 + 2 v + 0.15 v³``, and a Stribeck decay plus a gear power-law viscous term ``3 √v`` (the
  robot-joint generator's shape);
* two more accelerating ones (:data:`ACCELERATING`): exponential growth ``4 + 2 v + 0.3 e^v``
  and power-law drag ``4 + v + 0.5 v^2.5``.

Each case also reports the **silent miss** per point: the share of replicates where the calibrated
90 % band misses the truth and the answer did not say so first (that the data bend upward against
every weighted law, :mod:`bayesfric.sizing.shape`; for a band above the truth, the downward remark
counts), and the part of it where the truth lies above the band (an under-sized drive).

Asserted (R = 200): when the truth is a candidate, the calibrated band covers it at 3 rad/s in
85–95 % of replicates (consistent at 1 % false alarm) with median width ≤ 1.5× the within-model
width at every reported point; in the six :data:`COVERED` scenarios it covers the true curve in ≥
85 % at every reported point (2.5, 3 and 4 rad/s); the answer says the fold cannot tell a law from
the truth in at least half the Stribeck + gear replicates and in at most a tenth of the quadratic
drag ones. NOT met (issue 47 item 6, stated, not asserted): the concave shapes are covered 99–100
% (above 97 %: oversizing), the convex accelerating one and the Stribeck + gear power law below
85 % (:data:`SHORT`: only a lift well above the within-model band is asserted). The fixed growth
of the miss with distance is the cause (:mod:`bayesfric.sizing.calibration`); the nested-cut
estimate of that growth tried for it (``cuts=NESTED``, :mod:`tests.sizing_growth`) did not
meet the targets either. ``benchmarks/bench_calibration_frontier.py`` shows why the Stribeck +
gear case is hard at this data size: the fold's standardised miss hardly differs from when the
candidate is the truth (AUC 0.62 between the two). The statement is asserted: made in at most 10 %
of the candidate's replicates (consistent at 1 % false alarm), in ≥ 95 % where the data bend
strongly (quadratic drag, power-law drag), ≥ 75 % in :data:`UNDER_SAID`; under-sized without a
word in ≤ 10 % of replicates at every point of every other shape. NOT met (stated): the
:data:`UNDER_SAID` shapes are under-sized without a word in 15–18 %. Figures: docs/sizing.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special, stats

from bayesfric import compare, sizing
from bayesfric.compare.heldout import HeldOut
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.sizing.calibration import Scheme
from bayesfric.sizing.misfit import local_misfit
from tests.sizing_growth import measure_misses
from tests.sizing_helpers import PASSED, hand_fit

REPLICATES = 200
SIGMA = 0.3
SPEEDS = np.linspace(0.1, 2.0, 30)
CUT = 1.0  # the study's blocked fold: its stacking weights answer the question
NESTED = (0.7, 1.0, 1.3)  # nested cuts (experimental, tests/sizing_growth.py): not the shipped method
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
    "concave saturating": lambda v: 3.0 + 4.0 * (1.0 - np.exp(-v / 0.8)),
    "logarithmic": lambda v: 2.0 + 1.5 * np.log1p(v / 0.1),
    "tanh + viscous": lambda v: 1.0 + 3.0 * np.tanh(v / 0.6) + 0.8 * v,
}
SHORT = {  # no candidate is the truth; below 85 %: stated, not hidden
    "convex accelerating": lambda v: 4.0 + 2.0 * v + 0.15 * v**3,
    "Stribeck + gear power law": lambda v: 2.0 + 2.0 * np.exp(-np.sqrt(v / 0.1)) + 3.0 * np.sqrt(v),
}
ACCELERATING = {  # no candidate is the truth; convex, growing faster beyond the data than inside it
    "exponential growth": lambda v: 4.0 + 2.0 * v + 0.3 * np.exp(v),
    "power-law drag v^2.5": lambda v: 4.0 + 1.0 * v + 0.5 * v**2.5,
}
TRUTHS = {"candidate": lambda v: 5.0 + 2.0 * v, **COVERED, **SHORT, **ACCELERATING}
#: Accelerating shapes whose band misses the truth from below without the statement in more than a
#: tenth of replicates (measured 15 % and 18 %, docs/sizing.md): the curvature they show on the data
#: (t about 2.5) is found by the one-sided test in 82-85 %, and the misses fall where it shows least.
UNDER_SAID = ("convex accelerating", "exponential growth")


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


def law_pieces(name: str, y: np.ndarray, heldouts: dict[str, np.ndarray], rng: np.random.Generator):
    """The full fit (a DataTree as sampled fits are) and each blocked cut's CVResult of a law."""
    x = DESIGN[name](SPEEDS)
    beta, sigma = posterior(x, y, rng)
    shape = (CHAINS, DRAWS)
    draws = {k: beta[:, i].reshape(shape) for i, k in enumerate(PARAMS[name])} | {"sigma": sigma.reshape(shape)}
    fit = hand_fit(name, draws, {"velocity": SPEEDS})
    cvs = {}
    for label, heldout in heldouts.items():
        beta_f, sigma_f = posterior(x[~heldout], y[~heldout], rng)
        mu = beta_f @ x[heldout].T  # (S, n_heldout)
        lpd = special.logsumexp(stats.norm.logpdf(y[heldout], mu, sigma_f[:, None]), axis=0) - math.log(mu.shape[0])
        elpd_i = np.full(SPEEDS.size, np.nan)
        elpd_i[heldout] = lpd
        index = np.flatnonzero(heldout)
        noise = np.full(index.size, float(np.mean(sigma_f**2)))
        predictive = HeldOut(index, np.zeros(index.size, dtype=int), mu, noise)
        cvs[label] = compare.CVResult(name, label, float(lpd.sum()), float(np.sqrt(lpd.size * lpd.var())), elpd_i,
                                      heldout, [PASSED], 0.0, predictive=predictive)
    return fit, cvs


def sources(y: np.ndarray, rng: np.random.Generator, cuts=(CUT,), bootstrap: bool = True):
    """Every candidate's LawSource, weighted by Bayesian-bootstrap stacking on the study's fold (at
    CUT) and with the miss it measured, as a study gives them. ``bootstrap=False``: point stacking
    (the method before issue 47); ``cuts=NESTED``: the experimental nested-cut growth estimate
    (:func:`tests.sizing_growth.measure_misses`)."""
    ds = make_dataset({"velocity": SPEEDS}, y)
    heldouts, schemes = {}, []
    for c in cuts:
        folds = compare.blocked_masks(ds, "velocity", threshold=c, direction="upper")
        heldouts[folds.labels[0]] = folds.heldout[0]
        schemes.append(Scheme(folds.labels[0], "velocity", "upper"))
    main = schemes[list(cuts).index(CUT)]
    pieces = {name: law_pieces(name, y, heldouts, rng) for name in DESIGN}
    weights = compare.model_weights({k: cvs[main.label] for k, (_, cvs) in pieces.items()}, method="stacking")
    w = weights.weights if bootstrap else (weights.point or weights.weights)
    out = []
    for name, (fit, cvs) in pieces.items():
        miss = measure_misses(cvs, ds, schemes)[main.label]
        out.append(sizing.LawSource(name, fit, {main.label: w.get(name, 0.0)},
                                    misses={main.label: miss} if miss is not None else {}))
    return out, main


def interval_score(lo: np.ndarray, hi: np.ndarray, x: np.ndarray, alpha: float = 0.1) -> np.ndarray:
    """Interval score of a central (1 − alpha) band (Gneiting & Raftery 2007, eq. 43): its width
    plus 2/alpha times how far the truth lies outside; lower is better."""
    return (hi - lo) + 2 / alpha * (np.maximum(lo - x, 0) + np.maximum(x - hi, 0))


def calibrate(replicates: int = REPLICATES, seed: int = 2026, truths=None, cuts=(CUT,), bootstrap: bool = True) -> dict:
    """Per scenario and reported point: coverage of the true mean curve, within-model and
    calibrated, the calibrated width relative to the within-model width, both bands' mean
    interval score, and how often the answer said the folds cannot tell a law from the truth."""
    rng = np.random.default_rng(seed)
    question = sizing.check_question(sizing.make_question({"velocity": ASKED}, 0.9), ["velocity"], ["velocity"],
                                     "torque")
    x = question.grid()["velocity"]
    cols = [int(np.argmin(np.abs(x - v))) for v in REPORT_AT]
    out = {}
    for scenario, truth in (truths or TRUTHS).items():
        within, calibrated, ratio, new_obs, score_w, score_c, flagged = [], [], [], [], [], [], []
        said, silent, under = [], [], []
        mu = np.abs(truth(x))
        for r in range(replicates):
            y = truth(SPEEDS) + rng.normal(0, SIGMA, SPEEDS.size)
            laws, scheme = sources(y, rng, cuts, bootstrap)
            misfits = {s.name: local_misfit(s.fit, {"velocity": SPEEDS}, y, r) for s in laws}  # as sizing.answer
            answer = sizing.answer_question(question, laws, {"velocity": SPEEDS}, schemes=[scheme], seed=r, fan=False,
                                            misfits=misfits)
            mix, cal = answer.average, answer.average.calibrated
            band_w, band_c = (mix.mean_fn.q(0.05), mix.mean_fn.q(0.95)), (cal.mean_fn.q(0.05), cal.mean_fn.q(0.95))
            within.append((band_w[0] <= mu) & (mu <= band_w[1]))
            calibrated.append((band_c[0] <= mu) & (mu <= band_c[1]))
            ratio.append((band_c[1] - band_c[0]) / (band_w[1] - band_w[0]))
            score_w.append(interval_score(*band_w, mu))
            score_c.append(interval_score(*band_c, mu))
            flagged.append(bool(answer.undetected))
            # the lead statement: the data bend upward against every weighted law (sizing.shape); a
            # downward bend is said among the warnings (the band errs safe)
            up, down = bool(answer.bend), any("bend DOWNWARD" in w for w in answer.warnings)
            said.append(up)
            low, high = mu < band_c[0], mu > band_c[1]  # the truth below the band (oversized) or above it
            silent.append((high & (not up)) | (low & (not (up or down))))
            under.append(high & (not up))
            new = np.abs(truth(x) + rng.normal(0, SIGMA, x.size))
            new_obs.append((cal.noisy.q(0.05) <= new) & (new <= cal.noisy.q(0.95)))
        out[scenario] = {
            "x": x[cols], "distance": sizing.extrapolation_distance(x[cols], SPEEDS[0], SPEEDS[-1]),
            "within": np.mean(within, axis=0)[cols], "calibrated": np.mean(calibrated, axis=0)[cols],
            "width ratio": np.median(ratio, axis=0)[cols], "new observation": np.mean(new_obs, axis=0)[cols],
            "score within": np.mean(score_w, axis=0)[cols], "score calibrated": np.mean(score_c, axis=0)[cols],
            "flagged": float(np.mean(flagged)), "said": float(np.mean(said)),
            "silent": np.mean(silent, axis=0)[cols], "silent under": np.mean(under, axis=0)[cols],
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
        lines.append(f"{scenario} (folds cannot tell a weighted law from the truth in {r['flagged']:.0%}; the data "
                     f"bend upward against every weighted law, said first, in {r['said']:.1%}):")
        for i, v in enumerate(r["x"]):
            lines.append(f"  v = {v:.2f} rad/s (distance {r['distance'][i]:.2f}): 90 % band of the mean curve covers "
                         f"the truth {r['within'][i]:.1%} within-model, {r['calibrated'][i]:.1%} calibrated (median "
                         f"width {r['width ratio'][i]:.2f}x); interval score {r['score within'][i]:.2f} within-model, "
                         f"{r['score calibrated'][i]:.2f} calibrated; with noise covers a new observation "
                         f"{r['new observation'][i]:.1%}; silent miss {r['silent'][i]:.1%} (truth above the band, "
                         f"unsaid: {r['silent under'][i]:.1%})")
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
    assert result["Stribeck + gear power law"]["flagged"] >= 0.5
    assert result["viscous + quadratic drag"]["flagged"] <= 0.1
    # the statement that the data bend upward against every weighted law (sizing.shape): a false
    # alarm consistent with at most 10 % where the truth is a candidate, said where the data show it
    assert result["candidate"]["said"] * REPLICATES <= stats.binom.isf(0.01, REPLICATES, 0.10)
    for scenario in ("viscous + quadratic drag", "power-law drag v^2.5"):
        assert result[scenario]["said"] >= 0.95, scenario
    for scenario in UNDER_SAID:  # NOT met (stated): a tenth or more under-sized without a word
        assert result[scenario]["said"] >= 0.75, scenario
    for scenario in set(TRUTHS) - set(UNDER_SAID):  # under-sized (truth above the band) and unsaid
        assert np.all(result[scenario]["silent under"] <= 0.10), scenario


def test_bootstrap_stacking_softens_a_weight_of_one_from_a_few_points_and_agrees_on_many():
    # five held-out points, law 0 better on four: point stacking gives it weight 1.0
    lpd = np.array([[0.0, -1.0], [0.0, -1.0], [0.0, -1.0], [0.0, -1.0], [-1.0, 0.0]])
    point = compare.model_weights({k: _cv(k, lpd[:, i]) for i, k in enumerate("ab")}, method="stacking")
    assert point.point["a"] == pytest.approx(1.0, abs=1e-3)
    assert 0.6 < point.weights["a"] < 0.97  # some bootstrap draws favour b
    assert point.method == "Bayesian-bootstrap stacking"
    # many points: the bootstrap's spread vanishes and its mean is the point stacking weight
    rng = np.random.default_rng(0)
    many = np.c_[rng.normal(0, 1, 2000), rng.normal(-0.05, 1, 2000)]
    w = compare.model_weights({k: _cv(k, many[:, i]) for i, k in enumerate("ab")}, method="stacking")
    assert w.weights["a"] == pytest.approx(w.point["a"], abs=0.03)


def _cv(name: str, lpd: np.ndarray) -> compare.CVResult:
    heldout = np.ones(lpd.size, dtype=bool)
    return compare.CVResult(name, "upper", float(lpd.sum()), float(np.sqrt(lpd.size * lpd.var())), lpd, heldout,
                            [PASSED], 0.0)


def test_the_answer_says_when_the_fold_cannot_tell_a_law_from_the_truth():
    rng = np.random.default_rng(7)
    question = sizing.check_question(sizing.make_question({"velocity": ASKED}, 0.9), ["velocity"], ["velocity"],
                                     "torque")
    said = {}
    for scenario in ("candidate", "viscous + quadratic drag"):
        y = TRUTHS[scenario](SPEEDS) + rng.normal(0, SIGMA, SPEEDS.size)
        laws, scheme = sources(y, rng, cuts=(CUT,))
        said[scenario] = sizing.answer_question(question, laws, {"velocity": SPEEDS}, schemes=[scheme], fan=False)
    flag = said["candidate"].undetected
    assert "CANNOT TELL" in flag and "coulomb_viscous" in flag and flag in said["candidate"].warnings
    assert said["viscous + quadratic drag"].undetected == ""  # its miss shows: nothing to say
