"""Lack of fit along a law's own inputs: do its residuals bend with the axis a question
extrapolates along?

Why
    The residual-structure check (:mod:`bayesfric.compare.structure`) conditions on the law's
    inputs on purpose: what differs at the *same* operating point. The other question is whether
    the law's curve has the data's shape along an input: a straight line through friction that
    grows faster and faster (churning drag, an accelerating wear) leaves residuals that bend
    (low in the middle, high at both ends), and beyond the top of the data the law under-predicts
    by more than anything the data themselves could show as noise. The blocked folds' allowance
    assumes a growth of that miss (:mod:`bayesfric.sizing.calibration`); where the data bend
    harder than it assumes, the calibrated band can miss, and the answer must say so first
    (:mod:`bayesfric.sizing.shape`).

The test (:func:`lack_of_fit`), per law and input ``x`` (``|x|`` for an input with both signs)
    The residuals of the magnitude ``e_i = (y_i − m_i) · sign(m_i)`` (positive: the measured
    magnitude above the law's mean ``m_i``) with noise sd ``σ_i`` are regressed by weighted least
    squares (weights ``1/σ²``) on a null model -- an intercept and a slope in ``u = x / width``, a level
    per direction of motion where the velocity has both signs, and a smooth basis of the law's
    other inputs (:func:`bayesfric.compare.structure_stats.operating_basis`) -- and on the null
    plus the curvature terms ``u²`` and ``u³`` (standardised). The F-test of the two terms
    (AR(1)-prewhitened along trajectories, as the structure check) is exact for a law linear in
    its coefficients whose gradient lies in the null's span (Coulomb + viscous on one speed
    axis), and approximate otherwise: the law's own parameters absorb part of a curvature, so
    the test is conservative for flexible laws. An input is flagged at ``p < ALPHA / m`` (``m``
    inputs tested, Bonferroni): at most :data:`ALPHA` false alarm per law when it is the truth.

Which way the data bend (:meth:`LackOfFit.convex`)
    The same regression with ``u²`` alone added to the null: its coefficient, as the relative
    bend ``curvature`` (the fitted ``c u²`` term's sag below its chord at the middle of the
    tested range, over the mean ``|m|``), and its t statistic. Positive: the data curve upward
    against the law (convex: low in the middle, high at both ends) -- friction grows faster than
    the law, which beyond the data then under-predicts on either side; negative: concave, the law
    over-predicts beyond the data.
    A sizing answer states it where the one-sided test of that sign holds at
    :data:`STATEMENT_ALPHA` for every law carrying weight (:mod:`bayesfric.sizing.shape`): a
    one-degree-of-freedom test of the one shape that turns into under-sizing beyond the data.

Cost: a few least-squares fits on the residuals the misfit (:mod:`bayesfric.sizing.misfit`) or
the checks unit already computed; milliseconds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats
from threadpoolctl import threadpool_limits

from bayesfric.compare.structure_stats import CATEGORICAL, _ftest, _standard, operating_basis

__all__ = ["ALPHA", "STATEMENT_ALPHA", "LackOfFit", "lack_of_fit"]

#: Per-law false-alarm rate of the lack-of-fit test (Bonferroni over the inputs tested).
ALPHA = 0.05
#: One-sided level of the bend test behind a sizing answer's statement: where the one weighted law
#: is the true form the statement is made in 8 % of answers (the test is exact for a law linear in
#: its coefficients), inside the one-in-ten false alarm it is held to with room for sampling.
STATEMENT_ALPHA = 0.08


@dataclass(frozen=True)
class LackOfFit:
    """One input's lack-of-fit test for one law (see the module).

    ``p_value``/``threshold``/``flagged``: the F-test of ``u²`` and ``u³`` (Bonferroni);
    ``curvature``: the relative bend over the tested range (positive: convex, the data above the
    law at both ends), ``t``: its t statistic on ``dof`` degrees of freedom; ``df``: the F-test's
    numerator degrees of freedom (0: not testable); ``rho``: the AR(1) coefficient it was
    prewhitened with.
    """

    axis: str
    p_value: float
    threshold: float
    flagged: bool
    curvature: float
    t: float
    dof: int
    df: int
    rho: float = 0.0

    def convex(self, alpha: float) -> bool:
        """The data curve upward against the law beyond chance: the one-sided t-test at ``alpha``."""
        return bool(self.dof > 0 and np.isfinite(self.t) and stats.t.sf(self.t, self.dof) < alpha)

    def concave(self, alpha: float) -> bool:
        """The data curve downward against the law beyond chance (one-sided at ``alpha``)."""
        return bool(self.dof > 0 and np.isfinite(self.t) and stats.t.cdf(self.t, self.dof) < alpha)


def _curvature(u: np.ndarray) -> np.ndarray:
    return np.column_stack([_standard(u**2), _standard(u**3)])


def _bend(x0: np.ndarray, u: np.ndarray, z: np.ndarray, s: np.ndarray) -> tuple[float, float, int]:
    """(relative bend over the tested range, its t statistic, degrees of freedom) of ``u²`` added to
    the null ``x0`` (all weighted by ``1/s``)."""
    x = np.column_stack([x0, u**2 / s])
    coef, _, rank, _ = np.linalg.lstsq(x, z, rcond=None)
    dof = int(z.size - rank)
    if dof < 1:
        return float("nan"), float("nan"), 0
    resid = z - x @ coef
    var = float(resid @ resid) / dof * float(np.linalg.pinv(x.T @ x)[-1, -1])
    span = float(u.max() - u.min())
    bend = float(coef[-1]) * span**2 / 4.0  # c u² about its chord over the range, at the range's middle
    return bend, float(coef[-1] / np.sqrt(var)) if var > 0 else float("nan"), dof


def lack_of_fit(e: np.ndarray, sd: np.ndarray, inputs: Mapping[str, np.ndarray], *,
                starts: np.ndarray | None = None, alpha: float = ALPHA,
                scale: float | None = None) -> tuple[LackOfFit, ...]:
    """The lack-of-fit test of every input of ``inputs`` with more than
    :data:`~bayesfric.compare.structure_stats.CATEGORICAL` values (see the module).

    Parameters
    ----------
    e, sd : ndarray, shape (n,)
        Residuals of the magnitude (positive: the measured magnitude above the law's mean) and
        the noise sd per row, in response units.
    inputs : mapping of str to ndarray
        The law's inputs per row, SI (a velocity with both signs is tested on its magnitude).
    starts : ndarray of bool, optional
        True where an ordered trajectory starts: the F-test is AR(1)-prewhitened within each (the
        bend's t-test is not: rows independent).
    alpha : float
        Per-law false-alarm rate of the F-test, split over the inputs tested.
    scale : float, optional
        The typical magnitude the bend is reported relative to (default: the largest ``sd``
        times 10, a placeholder; give the mean ``|m|``).

    Returns
    -------
    tuple of LackOfFit
        One per input tested.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> v = np.linspace(0.1, 2.0, 60)
    >>> bent = 0.05 * (v - 1.05) ** 2 / 0.9 ** 2 + 0.01 * rng.normal(size=60)  # data above at both ends
    >>> (test,) = lack_of_fit(bent, np.full(60, 0.01), {"velocity": v}, scale=5.0)
    >>> test.flagged, test.convex(0.05), round(test.curvature, 3)
    (True, True, 0.01)
    """
    e, sd = np.asarray(e, dtype=float), np.asarray(sd, dtype=float)
    size = float(scale) if scale else float(10 * np.max(sd))
    arrays = {k: np.asarray(v, dtype=float).ravel() for k, v in inputs.items()}
    axes = [k for k, v in arrays.items() if np.unique(v).size > CATEGORICAL]
    with threadpool_limits(limits=1, user_api="blas"):
        out = [_one(axis, e, sd, arrays, starts, size) for axis in axes]
    threshold = alpha / max(1, len(out))
    return tuple(replace(t, threshold=threshold, flagged=bool(np.isfinite(t.p_value) and t.p_value < threshold))
                 for t in out)


def _one(axis: str, e: np.ndarray, sd: np.ndarray, arrays: Mapping[str, np.ndarray],
         starts: np.ndarray | None, size: float) -> LackOfFit:
    x = arrays[axis]
    signed = bool(x.min() < 0 < x.max())
    natural = np.abs(x) if signed else x
    width = float(natural.max() - natural.min()) or 1.0
    u = natural / width
    null = [np.ones_like(u), _standard(u)]
    if signed:
        null.append(np.sign(x))
    others = {k: v for k, v in arrays.items() if k != axis}
    if others:
        null.append(operating_basis(others)[:, 1:])
    x0 = np.column_stack(null)
    p, df, rho, _ = _ftest(e / sd, x0 / sd[:, None], _curvature(u) / sd[:, None], starts)
    bend, t, dof = _bend(x0 / sd[:, None], u, e / sd, sd)
    return LackOfFit(axis, p, float("nan"), False, bend / size, t, dof, df, rho)
