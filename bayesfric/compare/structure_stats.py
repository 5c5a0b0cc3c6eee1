"""The residual-structure statistic on residuals alone: the operating-point basis, the F-test of
a column's terms (AR(1)-prewhitened along trajectories), Bonferroni, effect sizes.

What it computes and why is in :mod:`bayesfric.compare.structure` (steps 2–5), which gives it a
fit's residuals; kept apart so the statistic can be tested by simulation without a fit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats
from scipy.interpolate import BSpline
from threadpoolctl import threadpool_limits

from bayesfric.laws.base import TRAJECTORY_START

__all__ = ["ALPHA", "CATEGORICAL", "DIRECTION", "KNOTS", "Column", "StructureCheck", "operating_basis",
           "structure_tests"]

#: Per-fit false-alarm rate (Bonferroni over the columns tested).
ALPHA = 0.05
#: An input with at most this many distinct values enters the basis as a factor.
CATEGORICAL = 8
#: Interior knots of each input's cubic B-spline (fewer when the basis would exceed n/4 columns).
KNOTS = 3
#: Fewest residual degrees of freedom an F-test is run with.
MIN_DF = 5
#: Largest |ρ| the prewhitening uses.
RHO_MAX = 0.995
#: The name of the direction of motion a stateful law's basis adds when it reads no velocity.
DIRECTION = "direction of motion"


@dataclass(frozen=True)
class Column:
    """A column of the data set to test: coordinate ``name``, ``kind`` ``"group"`` or ``"trend"``,
    its ``values`` per row, its ``quantity`` (``""`` for a group) and CSV ``label``."""

    name: str
    kind: str
    values: np.ndarray
    quantity: str = ""
    label: str = ""


@dataclass(frozen=True)
class StructureCheck:
    """One column's residual-structure test for one fit (:mod:`bayesfric.compare.structure`).

    ``effect`` is in the response's SI ``unit``, ``effect_sd`` in noise sd; ``df`` the F-test's
    numerator degrees of freedom (0: the column is spanned by the law's inputs, not testable);
    ``rho`` the AR(1) coefficient the regression was prewhitened with (0: rows independent);
    ``threshold`` the Bonferroni level ``p`` is compared with.
    """

    column: str
    kind: str
    levels: int
    effect: float
    effect_sd: float
    p_value: float
    threshold: float
    flagged: bool
    suggestion: str
    unit: str
    conditioned_on: str
    rho: float
    df: int
    #: A group column's between-group sd at the same operating point, in response units: the sd
    #: over groups of their weighted mean residuals within one direction of motion (the larger
    #: direction's), less what the noise alone gives them; NaN for a numeric column.
    between_sd: float = float("nan")

    def sentence(self) -> str:
        """The finding in words, with its size, its test and what would model it."""
        if self.kind == "curvature":
            return self._curvature_sentence()
        what = (f"differs between the {self.levels} groups of '{self.column}'" if self.kind == "group"
                else f"trends with '{self.column}'")
        p = "< 1e-16" if self.p_value <= 0 else f"= {self.p_value:.2g}"
        ar1 = f", AR(1)-prewhitened, ρ = {self.rho:.2f}" if self.rho else ""
        unit = f" {self.unit.replace('*', '·')}" if self.unit else ""
        return (f"the response {what} by up to {self.effect:.2g}{unit} at the same "
                f"{self.conditioned_on or 'operating point'} ({self.effect_sd:.2g} noise sd; F-test p {p}{ar1})"
                + (f"; what would model it: {self.suggestion}" if self.suggestion else ""))


    def _curvature_sentence(self) -> str:
        way = "upward (convex: the data above the law at both ends" if self.effect > 0 else \
            "downward (concave: the data below the law at both ends"
        p = "< 1e-16" if self.p_value <= 0 else f"= {self.p_value:.2g}"
        unit = f" {self.unit.replace('*', '·')}" if self.unit else ""
        return (f"the residuals bend {way}) along '{self.column}' by {abs(self.effect):.2g}{unit} at the middle of "
                f"the tested range (t = {self.effect_sd:.1f}; F-test of u², u³ p {p}): the law's curve lacks a "
                "curvature the data show, and beyond the data it grows apart from them")


# -- the operating-point basis -----------------------------------------------------------------
def _bspline(x: np.ndarray, knots: int) -> np.ndarray:
    lo, hi = float(x.min()), float(x.max())
    inner = np.unique(np.quantile(x, np.linspace(0.0, 1.0, knots + 2)[1:-1])) if knots else np.zeros(0)
    t = np.r_[[lo] * 4, inner[(inner > lo) & (inner < hi)], [hi] * 4]
    return BSpline.design_matrix(np.clip(x, lo, hi), t, 3).toarray()


def _signed(name: str, x: np.ndarray) -> bool:
    """A velocity (or the direction of motion) that changes sign: friction is odd in it."""
    return (name.endswith("velocity") or name == DIRECTION) and bool((x > 0).any() and (x < 0).any())


def _block(name: str, x: np.ndarray, knots: int) -> np.ndarray:
    """One input's columns: factor levels, a B-spline, or one per direction of motion."""
    levels = np.unique(x)
    if levels.size < 2:
        return np.zeros((x.size, 0))
    if levels.size <= CATEGORICAL:
        return (x[:, None] == levels[None, 1:]).astype(float)
    if _signed(name, x):
        s = _bspline(np.abs(x), knots)
        out = np.hstack([s * (x > 0)[:, None], s * (x < 0)[:, None], (x == 0)[:, None].astype(float)])
        return out[:, np.any(out != 0, axis=0)]
    return _bspline(x, knots)


def _standard(x: np.ndarray) -> np.ndarray:
    sd = x.std()
    return (x - x.mean()) / (sd if sd > 0 else 1.0)


def operating_basis(inputs: Mapping[str, np.ndarray]) -> np.ndarray:
    """A smooth basis of a law's inputs: the null model of the residual-structure F-test.

    Per input a cubic B-spline with :data:`KNOTS` interior knots at quantiles (per direction of
    motion for a velocity that changes sign), or factor levels for an input with at most
    :data:`CATEGORICAL` values; every other input's columns also times the direction of motion
    (a velocity's sign, or :data:`DIRECTION`); pairwise products of the inputs' columns while the basis stays
    within n/4 columns (else products of their standardised values), fewer knots when the main
    effects alone would not. Why: it absorbs the law's misfit along its own inputs, so only what
    differs *at the same operating point* is left to the tested column.

    Parameters
    ----------
    inputs : mapping of str to ndarray
        The law's inputs by name (a ``trajectory_start`` flag is skipped).

    Returns
    -------
    ndarray, shape (n, columns)
        An intercept and the columns above (possibly collinear: the test works with its rank).

    Examples
    --------
    >>> import numpy as np
    >>> operating_basis({"velocity": np.linspace(-1, 1, 40)}).shape
    (40, 9)
    """
    arrays = {k: np.asarray(v, dtype=float).ravel() for k, v in inputs.items() if k != TRAJECTORY_START}
    n = len(next(iter(arrays.values()))) if arrays else 0
    budget, sign = max(4, n // 4), _direction(arrays)
    for knots in range(KNOTS, -1, -1):
        named = {k: b for k, x in arrays.items() if (b := _block(k, x, knots)).shape[1]}
        # every other input per direction of motion (a load or temperature acts on |friction|)
        signed = [b * sign[:, None] for k, b in named.items() if sign is not None and not _signed(k, arrays[k])]
        blocks = list(named.values())
        if 1 + sum(b.shape[1] for b in blocks + signed) <= budget:
            break
    cols = [np.ones((n, 1)), *blocks, *signed]
    products = [(a[:, :, None] * b[:, None, :]).reshape(n, -1) for i, a in enumerate(blocks) for b in blocks[i + 1:]]
    if sum(c.shape[1] for c in cols + products) <= budget:
        cols += products
    else:
        linear = [_standard(x) for x in arrays.values() if np.unique(x).size > CATEGORICAL]
        cols += [(a * b)[:, None] for i, a in enumerate(linear) for b in linear[i + 1:]]
    return np.hstack(cols)


# -- the F-test --------------------------------------------------------------------------------
def _projection(z: np.ndarray, x: np.ndarray) -> tuple[float, int, np.ndarray, float]:
    """``(residual sum of squares, rank, coefficients, log pseudo-determinant of xᵀx)`` of least
    squares of ``z`` on ``x``."""
    u, s, vt = np.linalg.svd(x, full_matrices=False)
    keep = s > s[0] * max(x.shape) * np.finfo(float).eps if s.size else s > 0
    u, s, vt = u[:, keep], s[keep], vt[keep]
    coef = u.T @ z
    return float(z @ z - coef @ coef), int(keep.sum()), vt.T @ (coef / s), 2.0 * float(np.log(s).sum())


def _ar1(z: np.ndarray, x: np.ndarray, starts: np.ndarray) -> float:
    """The AR(1) coefficient of the regression of ``z`` on ``x`` within trajectories, by REML
    (restricted likelihood of the Prais–Winsten-whitened regression): the plain lag-one
    correlation of the residuals is biased low when the basis absorbs slow variation, and an
    under-estimated ρ leaves correlation that the F-test reads as an effect."""
    n, trajectories = len(z), int(starts.sum())

    def restricted(rho: float) -> float:
        rss, rank, _, log_det = _projection(_whiten(z, rho, starts), _whiten(x, rho, starts))
        return (n - rank) * np.log(max(rss, 1e-300)) - trajectories * np.log(1.0 - rho**2) + log_det

    return float(optimize.minimize_scalar(restricted, bounds=(-RHO_MAX, RHO_MAX), method="bounded",
                                          options={"xatol": 1e-3}).x)


def _whiten(a: np.ndarray, rho: float, starts: np.ndarray) -> np.ndarray:
    """Prais–Winsten transform of ``a`` (rows) within each trajectory."""
    out = np.array(a, dtype=float)
    out[1:] = a[1:] - rho * a[:-1]
    out[starts] = np.sqrt(1.0 - rho**2) * a[starts]
    return out


def _direction(inputs: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """The sign of the first velocity input that changes sign (friction is odd in it), else None."""
    for name, x in inputs.items():
        x = np.asarray(x, dtype=float).ravel()
        if _signed(name, x):
            return np.sign(x)
    return None


def _terms(column: Column, direction: np.ndarray | None) -> np.ndarray:
    """The column's terms: group indicators, or x and x²; each also times the direction of motion
    when it changes sign (a Coulomb level that differs between runs is odd in velocity)."""
    v = np.asarray(column.values)
    if column.kind == "group":
        out = (v[:, None] == np.unique(v)[None, 1:]).astype(float)
    else:
        x = _standard(v.astype(float))
        out = np.column_stack([x, _standard(x**2)]) if np.unique(x).size > 2 else x[:, None]
    return out if direction is None else np.hstack([out, out * direction[:, None]])


def _effect(terms: np.ndarray, direction: np.ndarray | None, z0: np.ndarray, s: np.ndarray,
            groups: np.ndarray | None = None) -> tuple[float, float, float]:
    """(response units, noise sd, between-group sd) of the column's effect on the null model's
    residuals ``z0`` (standardised): the largest range, within one direction of motion, of their
    weighted least-squares fit on the column's terms (for a group: the range of the groups'
    weighted mean residuals), that range over the noise sd the weights average to,
    ``1/√mean(1/s²)``, and for a group column (``groups``: each row's level) the sd of the
    groups' means within a direction less their mean squared standard error (NaN otherwise)."""
    sign = np.ones(len(s)) if direction is None else direction
    x = np.column_stack([np.ones(len(s)), sign, terms])
    fitted = x @ np.linalg.lstsq(x / s[:, None], z0, rcond=None)[0]  # weighted fit of the residuals z0 · s
    effect = max(float(np.ptp(fitted[sign == d])) for d in np.unique(sign))
    return effect, effect * float(np.sqrt(np.mean(1.0 / s**2))), _between_sd(fitted, sign, s, groups)


def _between_sd(fitted: np.ndarray, sign: np.ndarray, s: np.ndarray, groups: np.ndarray | None) -> float:
    """The largest, over directions of motion, sd of the groups' fitted mean residuals with the
    noise's share removed, ``√max(0, var_g(m) − mean_g(1/Σ 1/s²))`` (NaN without groups or with
    fewer than two groups in every direction)."""
    if groups is None:
        return float("nan")
    out = float("nan")
    for d in np.unique(sign):
        rows = sign == d
        levels = np.unique(groups[rows])
        if levels.size < 2:
            continue
        means = np.array([fitted[rows & (groups == g)][0] for g in levels])
        se2 = np.array([1.0 / np.sum(1.0 / s[rows & (groups == g)] ** 2) for g in levels])
        value = float(np.sqrt(max(0.0, np.var(means, ddof=1) - se2.mean())))
        out = value if not np.isfinite(out) else max(out, value)
    return out


def _ftest(z: np.ndarray, x0: np.ndarray, terms: np.ndarray,
           starts: np.ndarray | None) -> tuple[float, int, float, np.ndarray]:
    """``(p, df, rho, null residuals)`` of the column's ``terms`` over the null basis ``x0``
    (all weighted by 1/s); prewhitened by AR(1) within trajectories when ``starts`` is given."""
    x1 = np.hstack([x0, terms])
    rho = 0.0
    if starts is not None:
        rho = _ar1(z, x1, starts)
        zw, x0w, x1w = (_whiten(a, rho, starts) for a in (z, x0, x1))
    else:
        zw, x0w, x1w = z, x0, x1
    rss0, k0, coef0, _ = _projection(zw, x0w)
    rss1, k1, _, _ = _projection(zw, x1w)
    df, df2 = k1 - k0, len(z) - k1
    z0 = z - x0 @ coef0
    if df <= 0 or df2 < MIN_DF or rss1 <= 0:
        return float("nan"), max(df, 0), rho, z0
    f = max(rss0 - rss1, 0.0) / df / (rss1 / df2)
    return float(stats.f.sf(f, df, df2)), int(df), rho, z0


def structure_tests(resid: np.ndarray, sd: np.ndarray, inputs: Mapping[str, np.ndarray], columns: Sequence[Column],
                    *, starts: np.ndarray | None = None, alpha: float = ALPHA, unit: str = "",
                    suggestions: Mapping[str, str] | None = None,
                    basis: np.ndarray | None = None) -> tuple[StructureCheck, ...]:
    """The residual-structure F-tests of ``columns`` on residuals ``resid`` with noise sd ``sd``.

    The statistic alone (module docstring, steps 2–5), so it can be checked by simulation
    without a fit.

    Parameters
    ----------
    resid, sd : ndarray, shape (n,)
        Residuals and each row's noise sd (:func:`fit_residuals`).
    inputs : mapping of str to ndarray
        The law's inputs: the operating point the test conditions on (:func:`operating_basis`).
    columns : sequence of Column
        The columns to test (:func:`columns_to_test`).
    starts : ndarray of bool, optional
        True where an ordered trajectory starts: the regression is AR(1)-prewhitened within each.
    alpha : float
        Per-fit false-alarm rate, split over the columns tested (Bonferroni).
    unit : str
        The response's unit; ``suggestions``: column -> what would model its effect.
    basis : ndarray, optional
        The null model's columns instead of :func:`operating_basis` of ``inputs`` (tests).

    Returns
    -------
    tuple of StructureCheck
        One per column, in order.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> v, run = np.tile(np.linspace(0.1, 2, 30), 3), np.repeat([0, 1, 2], 30)
    >>> r = rng.normal(size=90) + 3.0 * (run == 2)  # run 2 three noise sd high
    >>> c, = structure_tests(r, np.ones(90), {"velocity": v}, [Column("run", "group", run)])
    >>> c.flagged, round(c.effect_sd)
    (True, 3)
    """
    resid, sd = np.asarray(resid, dtype=float), np.asarray(sd, dtype=float)
    x0 = np.asarray(basis, dtype=float) if basis is not None else (
        operating_basis(inputs) if set(inputs) - {TRAJECTORY_START} else np.ones((resid.size, 1)))
    z, x0, direction = resid / sd, x0 / sd[:, None], _direction(inputs)
    rows = []
    with threadpool_limits(limits=1, user_api="blas"):  # small algebra: one BLAS thread is faster
        for column in columns:
            terms = _terms(column, direction)
            p, df, rho, z0 = _ftest(z, x0, terms / sd[:, None], starts)
            groups = np.asarray(column.values) if column.kind == "group" else None
            rows.append((column, p, df, rho, _effect(terms, direction, z0, sd, groups)))
    threshold = alpha / max(1, sum(np.isfinite(p) for _, p, *_ in rows))
    on = ", ".join(k for k in inputs if k != TRAJECTORY_START)
    return tuple(StructureCheck(c.name, c.kind, int(np.unique(np.asarray(c.values)).size), eff, eff_sd, p,
                                threshold, bool(np.isfinite(p) and p < threshold),
                                (suggestions or {}).get(c.name, ""), unit, on, rho, df, between)
                 for c, p, df, rho, (eff, eff_sd, between) in rows)
