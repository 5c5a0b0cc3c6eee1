"""EXPERIMENTAL, a test helper, not part of the package: how a law's miss grows with distance,
estimated from nested blocked cuts along one axis (unfinished).

Status (measured on the exact-posterior harness, ``tests/test_sizing_calibration.py`` with
``cuts=NESTED`` = 0.7 / 1.0 / 1.3 rad/s, 40–60 replicates per case, so ±6–8 points): no variant
tried meets the targets (85–97 % at every point of every shape, the candidate at ≤ 1.5× width),
so it lives beside the harness, outside the package; the shipped calibration stays one cut with the
fixed growth (:func:`bayesfric.sizing.calibration.measure_miss`). What was measured:

* one power ``p`` of ``u = w (d + OFFSET)`` (self-similar), zero-mean band: the convex
  ``4 + 2v + 0.15 v³`` rose from 78 / 72 / 72 % to 78 / 82 / 93 % (2.5 / 3 / 4 rad/s); concave
  shapes stayed at 100 %; the far point's interval score worsened for quadratic drag (43 against
  32) and the Stribeck dip (55 against 32);
* the same with a signed empirical-Bayes band (the miss's mean carried, not only its size):
  interval scores fell by 2–4× in most cases (quadratic drag 1.9 / 5.5 / 34 against 6.1 / 13 / 32),
  but the Stribeck dip + linear fell to 30 / 57 % at 2.5 / 3 rad/s (its fold's miss comes from
  the dip at low speed, which a wider training range dilutes: not self-similar) and the candidate's
  width reached 3.9× at 4 rad/s (the power is unidentified when the miss is nil);
* the present code, two powers (distance ``p`` and training width ``q``) with a signed band:
  every case 98–100 %, widths up to 60× (cuts at 0.6–1.2 rad/s of training width do not pin ``q``
  for the full fit's 1.9).

What it computes
    Several blocked folds along the same axis and direction, cut at different points of the
    tested range (each trains inside its cut and scores everything beyond it, as a
    ``[[compare.blocked]]`` fold does), see the law's miss at different training widths ``w_j``
    and distances. Each extra cut costs one masked refit of the law (in the harness, where the
    posteriors are exact, nothing). With the scale ``u = w_j (d + OFFSET)`` (input units) the
    miss is modelled, for every cut at once, as::

        e_ij = β · |m_ij| · (w_j / w_0)^q ((d_ij + OFFSET) / t_0)^p + η_ij,   η_j ~ N(0, Σ_j)

    one relative rate ``β`` and two powers for all cuts (``q = p`` is a self-similar error: a fit
    of a wrong form on ``[0, w]`` misses by ``w^p h(d)`` when the truth's departure is a power
    ``p`` of the input, e.g. ``k x²`` for ``p = 2``). For each ``(p, q)`` on a grid (:data:`POWERS`
    × :data:`WIDTH_POWERS`), the
    generalised-least-squares fit of ``β`` gives a residual quadratic form; the cuts' folds are
    treated as independent (their held-out points overlap and nested training sets share
    parameter error, so that overstates what they say together), and the deviance is divided by
    the mean number of cuts that score a point (a magnitude-adjusted composite likelihood). The
    powers' posterior on the grid (flat prior) ``π ∝ exp(−D / 2k)`` gives their means and
    covariance.

    The rate at ``p̂`` is the cuts' precision-weighted slope; its standard error is the smallest
    single cut's (not the pooled one, which would treat correlated cuts as independent), and
    ``κ = sqrt(max(0, β̂² − LAMBDA_NESTED se²))``. The band at a sizing point
    (:meth:`bayesfric.sizing.calibration.Miss.band`) is signed: the rate's empirical-Bayes posterior
    times the growth factor at the full data's width ``L`` and the point's distance, over the
    powers' Gaussian posterior (log-normal moments).

What it assumes
    Power laws of distance and width for the whole axis (a saturating truth has no single power;
    the estimate then fits the stretch the cuts see); the cuts' folds treated as independent with
    the composite-likelihood adjustment; the powers' uncertainty Gaussian in the band. Each extra
    cut costs one masked refit of each law (in the harness, where posteriors are exact, nothing).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import xarray as xr

from bayesfric.sizing.calibration import OFFSET, Miss, Pieces, Scheme, measure_miss, pieces

__all__ = ["POWERS", "WIDTH_POWERS", "LAMBDA_NESTED", "measure_growth", "measure_misses"]

#: Grid of powers of distance ``p`` the growth is estimated on (flat prior over it).
POWERS = np.linspace(0.25, 4.0, 16)
#: Grid of powers of the training width ``q`` (flat prior; negative: wider training misses less).
WIDTH_POWERS = np.linspace(-2.0, 4.0, 25)
#: Share of the sampling variance subtracted from ``β̂²`` for nested cuts (1: the unbiased
#: moment estimate, DerSimonian & Laird 1986; the rate's posterior then carries ``se``).
LAMBDA_NESTED = 1.0


def _fit(cuts: Sequence[Pieces], p: float, q: float, t0: float, w0: float):
    """Per cut ``(β̂_j, se_j, residual)`` of ``e = β |m| (w/w0)^q ((d+c)/t0)^p``."""
    out = []
    for c in cuts:
        g = c.m * (c.w / w0) ** q * ((c.d + OFFSET) / t0) ** p
        solve_g = np.linalg.solve(c.cov, g)
        info = float(g @ solve_g)
        if not info > 0:
            return None
        beta = float(c.e @ solve_g) / info
        r = c.e - beta * g
        out.append((beta, 1.0 / math.sqrt(info), float(r @ np.linalg.solve(c.cov, r))))
    return out


def _profile(cuts: Sequence[Pieces], t0: float, w0: float) -> np.ndarray:
    """Posterior weights over (POWERS × WIDTH_POWERS) (see the module)."""
    deviance = np.full((POWERS.size, WIDTH_POWERS.size), np.nan)
    for i, p in enumerate(POWERS):
        for j, q in enumerate(WIDTH_POWERS):
            fits = _fit(cuts, p, q, t0, w0)
            if fits is None:
                continue
            prec = np.array([1.0 / se**2 for _, se, _ in fits])
            betas = np.array([b for b, _, _ in fits])
            pooled = float(prec @ betas / prec.sum())
            deviance[i, j] = sum(r for _, _, r in fits) + float(prec @ (betas - pooled) ** 2)
    overlap = sum(c.e.size for c in cuts) / max(c.e.size for c in cuts)
    if not np.isfinite(deviance).any():
        return np.zeros_like(deviance)
    w = np.where(np.isfinite(deviance), np.exp(-0.5 * (deviance - np.nanmin(deviance)) / overlap), 0.0)
    return w / w.sum()


def measure_growth(cuts: Sequence[Pieces], label: str) -> Miss | None:
    """The miss of a law measured on nested cuts along one axis and direction, its growth with
    distance and training width estimated (see the module); None when nothing fits. ``label``:
    the scheme it is filed under."""
    widths = np.array([c.w for c in cuts])
    w0 = float(np.exp(np.mean(np.log(widths))))
    t0 = float(np.exp(np.mean(np.log(np.concatenate([c.d for c in cuts]) + OFFSET))))
    post = _profile(cuts, t0, w0)
    if not post.sum() > 0:
        return None
    pp, qq = np.meshgrid(POWERS, WIDTH_POWERS, indexing="ij")
    p, q = float(np.sum(post * pp)), float(np.sum(post * qq))
    cov = np.array([[np.sum(post * (pp - p) ** 2), np.sum(post * (pp - p) * (qq - q))],
                    [np.sum(post * (pp - p) * (qq - q)), np.sum(post * (qq - q) ** 2)]])
    fits = _fit(cuts, p, q, t0, w0)
    if fits is None:
        return None
    prec = np.array([1.0 / se**2 for _, se, _ in fits])
    beta = float(prec @ np.array([b for b, _, _ in fits]) / prec.sum())
    se = float(min(se for _, se, _ in fits))
    return Miss(label, math.sqrt(max(0.0, beta**2 - LAMBDA_NESTED * se**2)), beta, se,
                int(sum(c.e.size for c in cuts)), float(max(np.max(c.d) for c in cuts)),
                p, float(math.sqrt(cov[0, 0])), t0, len(cuts), q, float(math.sqrt(cov[1, 1])), w0,
                float(cov[0, 1]))


def measure_misses(cvs: Mapping[str, object], ds: xr.Dataset, schemes: Sequence[Scheme]) -> dict[str, Miss | None]:
    """Every scheme's miss of one law: schemes alone along their axis and direction as
    :func:`~bayesfric.sizing.calibration.measure_miss` (fixed growth); nested cuts (several
    schemes along one axis, direction and scale) jointly, their growth estimated
    (:func:`measure_growth`), the same miss filed under each of their labels (sizing takes the
    largest over one family, never their sum).

    ``cvs``: scheme label -> the law's :class:`bayesfric.compare.CVResult` there (with its
    held-out predictive); a label missing from it gets None.
    """
    out: dict[str, Miss | None] = {}
    families: dict[tuple, list[Scheme]] = {}
    for s in schemes:
        families.setdefault((s.axis, s.direction, s.use_abs), []).append(s)
    for family in families.values():
        measured = [(s, p) for s in family if s.label in cvs and (p := pieces(cvs[s.label], ds, s)) is not None]
        if len(measured) < 2:
            for s in family:
                out[s.label] = measure_miss(cvs[s.label], ds, s) if s.label in cvs else None
            continue
        joint = measure_growth([p for _, p in measured], measured[0][0].label)
        for s in family:
            out[s.label] = replace(joint, scheme=s.label) if joint is not None and s.label in cvs else None
    return out
