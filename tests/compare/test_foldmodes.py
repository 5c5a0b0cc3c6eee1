"""Cross-validation folds under the full fit's rules for chains that do not mix
(bayesfric.compare.foldmodes): a fold whose chains wander along a direction no row depends on is
used; one whose chains each sampled a separate mode well is combined by stacking, its held-out
rows scored by the combined draws (checked against the exact mixture of the modes' predictive
densities); a fold whose chains disagree otherwise, or that diverged, still fails.

Fold draws are built by hand (independent normal draws per chain, so each chain is healthy on its
own), on a real program, so the log-likelihood is the law's own.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr
from scipy.special import logsumexp

from bayesfric.compare.foldmodes import fold_posterior, resolve_folds
from bayesfric.datasets.synthetic import make_dataset
from bayesfric.inference.batching import FoldFits
from bayesfric.inference.diagnostics import GATE, Verdict, check_folds, resolve_fold
from bayesfric.inference.pointwise import log_likelihood
from bayesfric.laws import get_law
from bayesfric.model import build_program

CHAINS, DRAWS = 4, 1000
SPEEDS = np.linspace(0.1, 2.0, 30)


def _fits(law: str, samples: dict[str, np.ndarray], y: np.ndarray, diverging: np.ndarray | None = None):
    """An engine stand-in (program and gate) and the FoldFits of ``samples`` (fold, chain, draw)."""
    program = build_program(get_law(law), make_dataset({"velocity": SPEEDS}, y))
    shape = next(iter(samples.values())).shape
    div = np.zeros(shape, bool) if diverging is None else diverging
    post = xr.Dataset({k: (("fold", "chain", "draw"), x) for k, x in samples.items()})
    stats = {"diverging": div}
    verdicts = check_folds(post, xr.Dataset({"diverging": (("fold", "chain", "draw"), div)}))
    fits = FoldFits(samples, np.zeros((shape[0], SPEEDS.size)), verdicts, 0.0, stats, np.full(shape[0], 0.8),
                    np.zeros(shape[0], bool))
    return SimpleNamespace(program=program, gate=GATE), fits


def _stribeck(wander: str, shift: float, seed: int = 9):
    """Two folds of a Stribeck law with no Stribeck bump (dT_s = 0), so v_s and delta change no
    row: fold 0's chain 3 wanders in ``v_s``; fold 1's in ``wander`` by ``shift``."""
    rng = np.random.default_rng(seed)
    shape = (2, CHAINS, DRAWS)
    samples = {"T_C": 3.0 + 0.02 * rng.normal(size=shape), "dT_s": np.zeros(shape),
               "v_s": np.exp(rng.normal(size=shape) * 0.1), "delta": 1.0 + 0.1 * rng.random(shape),
               "sigma": 0.1 * np.exp(0.05 * rng.normal(size=shape))}
    samples["v_s"][0, 3, DRAWS // 2:] += 5.0
    samples[wander][1, 3, DRAWS // 2:] += shift
    samples["T_s"] = samples["T_C"] + samples["dT_s"]
    return _fits("stribeck", samples, 3.0 + 0.1 * rng.normal(size=SPEEDS.size))


def test_a_fold_unmixed_along_an_unidentified_direction_is_used():
    """v_s wanders with no row depending on it: used, v_s named; T_C wandering within a chain
    moves the rows: still failed (that chain is not healthy on its own, so no modes either)."""
    engine, fits = _stribeck("T_C", 0.2)
    assert not fits.verdicts[0].passed and not fits.verdicts[1].passed
    train = np.ones((2, SPEEDS.size), bool)
    used, failed = resolve_folds(engine, fits, train, seed=0).verdicts
    assert used.passed and used.unidentified == ("v_s",) and used.predictions_converged
    assert used.loglik_rhat_max <= 1.01
    assert not failed.passed and not failed.unidentified and not failed.multimodal
    assert failed.predictions_converged is False and "not converged within" in failed.mode_note


def test_a_fold_with_a_divergence_is_not_rescued():
    engine, fits = _stribeck("v_s", 5.0)
    v = fits.verdicts[0]
    diverged = Verdict(False, v.rhat_max, v.ess_bulk_min, v.ess_tail_min, 1, None, None,
                       [*v.problems, "1 divergent transitions"])
    called = []
    post = fold_posterior(engine, fits.samples, 0)
    assert resolve_fold(diverged, post, lambda: called.append(1)) is diverged and not called
    div = np.zeros((2, CHAINS, DRAWS), bool)
    div[:, 0, 7] = True
    engine, fits = _fits("stribeck", fits.samples, np.asarray(engine.program.response), diverging=div)
    assert not any(v.passed for v in resolve_folds(engine, fits, np.ones((2, SPEEDS.size), bool), 0).verdicts)


def test_a_fold_with_two_healthy_modes_is_combined_and_scored_by_the_mixture():
    """Chains 0, 1 near the truth (T_C = 3), chains 2, 3 in a worse mode (T_C = 3.15): the fold
    is multimodal, its modes weighed on its training rows, and every row's predictive density is
    the stacked mixture's, log Σ_k w_k mean_{s in k} p(y_i | θ_s), to resampling error."""
    rng = np.random.default_rng(3)
    y = 3.0 + 0.5 * SPEEDS + 0.1 * rng.normal(size=SPEEDS.size)
    shape = (1, CHAINS, DRAWS)
    t_c = 3.0 + 0.02 * rng.normal(size=shape)
    t_c[0, 2:] += 0.15
    samples = {"T_C": t_c, "c_v": 0.5 + 0.01 * rng.normal(size=shape),
               "sigma": 0.1 * np.exp(0.05 * rng.normal(size=shape))}
    engine, fits = _fits("coulomb_viscous", samples, y)
    train = (SPEEDS <= 1.0)[None]
    out = resolve_folds(engine, fits, train, seed=0)
    verdict = out.verdicts[0]
    assert verdict.passed and verdict.multimodal and verdict.modes == ((0, 1), (2, 3))
    w = np.asarray(verdict.weights)
    assert w[0] > 0.8 and w.sum() == pytest.approx(1.0)
    assert fits.samples["T_C"] is samples["T_C"] and np.all(fits.lpd == 0)  # the input is not changed
    ll = log_likelihood(xr.DataTree.from_dict({"posterior": fold_posterior(engine, samples, 0)}),
                        program=engine.program).values  # (chain, draw, obs)
    per_mode = [logsumexp(ll[list(m)].reshape(-1, SPEEDS.size), axis=0) - np.log(len(m) * DRAWS)
                for m in verdict.modes]
    exact = logsumexp(np.log(w)[:, None] + np.array(per_mode), axis=0)
    np.testing.assert_allclose(out.lpd[0], exact, atol=0.03)
    share = np.isin(out.samples["T_C"][0], t_c[0, 2:]).mean()
    assert share == pytest.approx(w[1], abs=1e-3)


def test_the_cv_result_and_the_law_flags_say_a_fold_was_combined():
    from bayesfric.compare.refit import CVResult

    rng = np.random.default_rng(3)
    y = 3.0 + 0.5 * SPEEDS + 0.1 * rng.normal(size=SPEEDS.size)
    t_c = 3.0 + 0.02 * rng.normal(size=(1, CHAINS, DRAWS))
    t_c[0, 2:] += 0.15
    samples = {"T_C": t_c, "c_v": 0.5 + 0.01 * rng.normal(size=t_c.shape),
               "sigma": 0.1 * np.exp(0.05 * rng.normal(size=t_c.shape))}
    engine, fits = _fits("coulomb_viscous", samples, y)
    out = resolve_folds(engine, fits, (SPEEDS <= 1.0)[None], seed=0)
    cv = CVResult("coulomb_viscous", "blocked", 0.0, 0.0, out.lpd[0], SPEEDS > 1.0, out.verdicts, 0.0)
    assert cv.reliable and cv.modes_note.startswith("fold 1 of 1: multimodal: 2 modes, stacking weights")
    assert "(chains 0,1 | 2,3)" in str(cv)
