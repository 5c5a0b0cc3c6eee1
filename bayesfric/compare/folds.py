"""Fold builders for cross-validation: random K-fold, grouped, and blocked extrapolation folds.

Every builder returns :class:`Folds`: boolean TRAIN masks of shape ``(K, n_obs)`` and the
matching HELD-OUT masks, plus a one-line description of the scheme.

Trajectory rule
---------------
When the dataset is made of ordered trajectories (``ds.attrs["trajectory"]`` names the group
coordinate delimiting them: Dahl hysteresis loops, coast-down runs), a stateful law integrates
along each trajectory, so a point cannot be removed from inside one. Every builder therefore
assigns **whole trajectories** to folds, never single points: random K-fold shuffles
trajectories, grouped folds require every trajectory to lie inside one group level, and blocked
folds block on the per-trajectory value of the axis (its maximum for ``direction="upper"``, its
minimum for ``direction="lower"``), so a training trajectory lies entirely inside the envelope.

Leave-future-out
----------------
``blocked_masks(ds, "time", threshold=12.0, future=True)`` is the one exception to the trajectory
rule: it splits *inside* each trajectory, at the first sample (in recording order) beyond the cut,
trains on the past and scores the future. The likelihood mask only drops terms: a stateful law
still integrates every trajectory from its start, so the state at the split is the one the past
inputs produced, and the scored predictive is that of the future given the past. A single long
recording can so be cross-validated. (With AR(1) residuals the first future point is scored given
the last past residual, the model's own conditional.)

Blocked extrapolation folds
---------------------------
``blocked_masks(ds, "velocity", quantile=0.8)`` trains on the inner part of the operating
envelope and scores the outer part. With threshold ``t`` on the axis value ``a`` (or ``|a|``):

* ``direction="upper"``: train where ``a <= t``, score where ``a > t`` (extrapolate upwards:
  the top load steps, the highest speeds, temperatures or preloads);
* ``direction="lower"``: train where ``a >= t``, score where ``a < t``.

So every training value lies inside ``t`` and every scored value strictly outside. A
``quantile`` q sets ``t`` to the q-quantile of the (per-point or per-trajectory) axis values. For
odd laws measured in both directions of motion, blocking must use the speed ``|velocity|``:
``use_abs=None`` (default) detects an axis with both signs and uses its absolute value.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import xarray as xr

from bayesfric.datasets.loader import OBS_DIM, DataError
from bayesfric.errors import UserError

__all__ = ["Folds", "kfold_masks", "grouped_masks", "forecast_masks", "blocked_masks"]


@dataclass(frozen=True)
class Folds:
    """Train and held-out masks of a cross-validation scheme.

    Attributes
    ----------
    train, heldout : ndarray of bool
        ``(K, n_obs)``.
    scheme : str
        Human-readable description, e.g. ``"blocked velocity |v| > 2.1 rad/s (upper)"``.
    labels : list of str
        One label per fold (group level, threshold ...).
    """

    train: np.ndarray
    heldout: np.ndarray
    scheme: str
    labels: list[str]

    def __post_init__(self):
        if self.train.shape != self.heldout.shape or self.train.ndim != 2:
            raise UserError("train and held-out masks must both be (K, n_obs)")
        if (self.train & self.heldout).any():
            raise UserError(f"{self.scheme}: a point is both trained on and held out")
        empty = [self.labels[k] for k in range(self.n_folds)
                 if not self.train[k].any() or not self.heldout[k].any()]
        if empty:
            raise DataError(f"{self.scheme}: fold(s) {empty} have no training or no held-out point")

    @property
    def n_folds(self) -> int:
        return int(self.train.shape[0])


def _future_fold(ds: xr.Dataset, axis: str, values: np.ndarray, threshold: float | None,
                 quantile: float | None, direction: str, use_abs: bool) -> Folds:
    """The leave-future-out fold of :func:`blocked_masks` (``future=True``)."""
    if use_abs:
        values = np.abs(values)
    if quantile is not None:
        if not 0 < quantile < 1:
            raise UserError(f"must lie in (0, 1); got {quantile}", "quantile")
        threshold = float(np.quantile(values, quantile))
    key = ds.attrs.get("trajectory")
    unit = (np.unique(np.asarray(ds[key].values), return_inverse=True)[1] if key
            else np.zeros(values.size, dtype=int))
    beyond = values > threshold if direction == "upper" else values < threshold
    heldout = np.zeros(values.size, dtype=bool)
    for u in np.unique(unit):
        rows = np.flatnonzero(unit == u)  # a trajectory's rows are contiguous, in time order (loader)
        crossed = np.flatnonzero(beyond[rows])
        if crossed.size:
            heldout[rows[crossed[0]:]] = True
    name = f"|{axis}|" if use_abs else axis
    sign = ">" if direction == "upper" else "<"
    units = ds[axis].attrs.get("units", "")
    how = f" (q={quantile})" if quantile is not None else ""
    where = "each trajectory" if key else "the record"
    scheme = (f"leave-future-out: {where} split where {name} first {sign} {threshold:.4g} {units}{how}"
              .replace("  ", " "))
    return Folds(~heldout[None], heldout[None], scheme, [f"{name} {sign} {threshold:.4g}, future"])


def _units(ds: xr.Dataset) -> tuple[np.ndarray, int]:
    """Per-observation unit index (trajectory label index, or the observation itself)."""
    n = ds.sizes[OBS_DIM]
    key = ds.attrs.get("trajectory")
    if not key:
        return np.arange(n), n
    _, index = np.unique(np.asarray(ds[key].values), return_inverse=True)
    return index, int(index.max()) + 1


def _from_assignment(fold_of_unit: np.ndarray, unit: np.ndarray, k: int):
    heldout = np.stack([fold_of_unit[unit] == f for f in range(k)])
    return ~heldout, heldout


def kfold_masks(ds: xr.Dataset, k: int = 10, *, seed: int = 0) -> Folds:
    """Exact random K-fold: each point (or trajectory) is held out exactly once.

    Parameters
    ----------
    ds : xarray.Dataset
        The data (only its size and trajectory structure are read).
    k : int
        Number of folds, at most the number of points (or trajectories).
    seed : int
        Seed of the random assignment (NumPy ``default_rng``).
    """
    unit, n_units = _units(ds)
    if not 2 <= k <= n_units:
        raise UserError(f"K-fold needs 2 <= k <= {n_units} (points or trajectories); got {k}", "k")
    rng = np.random.default_rng(seed)
    fold_of_unit = np.empty(n_units, dtype=int)
    fold_of_unit[rng.permutation(n_units)] = np.arange(n_units) % k
    train, heldout = _from_assignment(fold_of_unit, unit, k)
    what = "trajectories" if ds.attrs.get("trajectory") else "points"
    return Folds(train, heldout, f"random {k}-fold over {what} (seed {seed})",
                 [f"fold {f}" for f in range(k)])


def grouped_masks(ds: xr.Dataset, group: str) -> Folds:
    """Leave one level of a group coordinate (series, preload, run ...) out per fold.

    Raises
    ------
    DataError
        ``group`` is not a coordinate, has a single level, or splits a trajectory.
    """
    if group not in ds.coords:
        raise DataError(f"dataset has no coordinate {group!r} to group folds by")
    levels, index = np.unique(np.asarray(ds[group].values), return_inverse=True)
    if levels.size < 2:
        raise DataError(f"group {group!r} has a single level; nothing to leave out")
    unit, _ = _units(ds)
    for u in np.unique(unit):
        if np.unique(index[unit == u]).size > 1:
            raise DataError(f"group {group!r} splits a trajectory; folds must hold out whole "
                            "trajectories")
    heldout = np.stack([index == f for f in range(levels.size)])
    return Folds(~heldout, heldout, f"leave one {group} out", [f"{group}={v}" for v in levels])


def forecast_masks(ds: xr.Dataset, column: str, first: int = 2) -> Folds:
    """Leave-future-out over ordered campaigns: fold ``k`` trains on the campaigns before the
    ``k``-th (in the order of the service coordinate ``column``) and scores the ``k``-th, for
    ``k = first … K−1``: the forecast a user makes of the next campaign, scored on each.

    Later campaigns are neither trained on nor scored (their levels stay at their prior, which
    does not touch the scored forecast). Each campaign must hold whole trajectories.

    Raises
    ------
    DataError
        ``column`` is not a coordinate, its values are not numbers, there are not more than
        ``first`` campaigns, or a trajectory spans two campaigns.

    Examples
    --------
    >>> forecast_masks(ds, "hours", first=3).labels     # doctest: +SKIP
    ['hours=3000', 'hours=4000']
    """
    if column not in ds.coords:
        raise DataError(f"dataset has no coordinate {column!r} to forecast along")
    labels, index = np.unique(np.asarray(ds[column].values).astype(str), return_inverse=True)
    try:
        order = np.argsort([float(v) for v in labels], kind="stable")
    except ValueError:
        raise DataError(f"campaign column {column!r} must hold one number per campaign (hours, cycles); "
                        f"got {labels[0]!r}") from None
    rank = np.empty(labels.size, dtype=int)
    rank[order] = np.arange(labels.size)
    position = rank[np.asarray(index).reshape(-1)]
    if labels.size <= first:
        raise DataError(f"{column!r} has {labels.size} campaigns; leave-future-out needs more than {first} "
                        "(the first ones to train on)")
    unit, _ = _units(ds)
    for u in np.unique(unit):
        if np.unique(position[unit == u]).size > 1:
            raise DataError(f"campaign {column!r} splits a trajectory; each campaign must hold whole trajectories")
    ks = range(first, labels.size)
    train = np.stack([position < k for k in ks])
    heldout = np.stack([position == k for k in ks])
    return Folds(train, heldout, f"leave future {column} out (each campaign forecast from those before it; "
                 f"the first {first} only trained on)", [f"{column}={labels[order[k]]}" for k in ks])


def blocked_masks(
    ds: xr.Dataset,
    axis: str,
    *,
    threshold: float | None = None,
    quantile: float | None = None,
    direction: Literal["upper", "lower"] = "upper",
    use_abs: bool | None = None,
    future: bool = False,
) -> Folds:
    """One blocked extrapolation fold along an operating input (see the module docstring).

    Parameters
    ----------
    ds : xarray.Dataset
        Data with the input coordinate ``axis``.
    axis : str
        Operating input coordinate: ``"bending_moment"``, ``"velocity"``, ``"temperature"``,
        ``"preload"`` ...
    threshold : float, optional
        Boundary in canonical SI units (of ``|axis|`` when the absolute value is used).
    quantile : float, optional
        Boundary as a quantile in (0, 1) of the axis values; give exactly one of the two.
    direction : {"upper", "lower"}
        ``"upper"``: train at or below, score above; ``"lower"``: train at or above, score below.
    use_abs : bool, optional
        Block on ``|axis|``; default: automatically when the axis has both signs (never under
        ``future``, where the sign is part of the path).
    future : bool
        Leave-future-out: split *inside* every trajectory, at its first sample beyond the cut in
        recording order; train on what came before, score that sample and everything after it
        (see "Leave-future-out" in the module docstring). Data without trajectories are one
        sequence in row order.

    Raises
    ------
    DataError
        Unknown axis, or a threshold that leaves no training or no held-out point.
    """
    if axis not in ds.coords:
        have = [k for k, v in ds.coords.items() if v.attrs.get("role") == "input"]
        raise DataError(f"no input {axis!r} to block on; inputs: {', '.join(have)}")
    if (threshold is None) == (quantile is None):
        raise UserError("give exactly one of threshold= or quantile=")
    if direction not in ("upper", "lower"):
        raise UserError(f"must be 'upper' or 'lower'; got {direction!r}", "direction")
    values = np.asarray(ds[axis].values, dtype=float)
    if future:
        return _future_fold(ds, axis, values, threshold, quantile, direction, bool(use_abs))
    if use_abs is None:
        use_abs = bool((values < 0).any() and (values > 0).any())
    if use_abs:
        values = np.abs(values)
    unit, n_units = _units(ds)
    reduce = np.maximum if direction == "upper" else np.minimum
    per_unit = np.full(n_units, -np.inf if direction == "upper" else np.inf)
    reduce.at(per_unit, unit, values)
    if quantile is not None:
        if not 0 < quantile < 1:
            raise UserError(f"must lie in (0, 1); got {quantile}", "quantile")
        threshold = float(np.quantile(per_unit, quantile))
    point_value = per_unit[unit]
    outside = point_value > threshold if direction == "upper" else point_value < threshold
    name = f"|{axis}|" if use_abs else axis
    sign = ">" if direction == "upper" else "<"
    units = ds[axis].attrs.get("units", "")
    how = f" (q={quantile})" if quantile is not None else ""
    scheme = f"blocked {name} {sign} {threshold:.4g} {units}{how}".replace("  ", " ")
    return Folds(~outside[None], outside[None], scheme, [f"{name} {sign} {threshold:.4g}"])
