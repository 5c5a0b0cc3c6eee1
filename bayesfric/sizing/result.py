"""What :func:`bayesfric.size` returns: every sizing answer as one tidy Dataset, with a data
frame of it and the quantile at any level from the kept draws.

The Dataset (:mod:`bayesfric.sizing.tidy`) is the answer; ``sizing.csv``, the report's sizing
section and ``bayesfric size`` render this one object (computed once, rendered many times).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import xarray as xr

from bayesfric.errors import UserError
from bayesfric.sizing.compute import Answer, SizingResult, weighted_quantiles
from bayesfric.sizing.tidy import DRAW_VARS, QUANTILE_VARS, build_dataset

__all__ = ["SizingAnswer", "as_answer"]

_KINDS = ("noisy", "mean_fn")


@dataclass(frozen=True, eq=False)
class SizingAnswer:
    """Sizing answers as one :class:`xarray.Dataset` (law × point × quantile), frozen.

    ``dataset`` holds, per law and per average (``law``: the laws, then ``average`` and
    ``average_loo``) and per point of every question (``point``), the required capacity at the
    question's confidence (``required``, ``calibrated_required``), ``P(|T| > capacity)`` with
    its Monte Carlo error (``p_exceed``, ``p_exceed_se``, ``p_exceed_bound``; ``calibrated_``),
    the quantiles of ``|T|`` of the mean function and with noise (``mean_fn``, ``noisy``,
    ``calibrated_mean_fn``, ``calibrated_noisy`` along ``quantile``), the weights, the variance
    split and the draws they all come from. Its attrs say what the answer is for (a new run or
    unit of a grouped fit, a steady state, within-model or calibrated, Monte Carlo). SI units.

    Why one object: the numbers are computed once; the data frame, ``sizing.csv``, the report's
    sizing tables and ``bayesfric size`` all render it, so they cannot disagree.

    Examples
    --------
    >>> import bayesfric
    >>> f = bayesfric.fit("coulomb_viscous", "robot_joint", draws=100, tune=100, chains=2)  # doctest: +SKIP
    >>> s = bayesfric.size(f, at={"velocity": (5, "rad/s")}, capacity=(40, "N*m"))           # doctest: +SKIP
    >>> s["required"].sel(law="coulomb_viscous").values        # N·m at each point          # doctest: +SKIP
    >>> s.q(0.999).sel(law="coulomb_viscous").values           # any level, from the draws  # doctest: +SKIP
    >>> s.to_dataframe()[["law", "velocity", "required", "p_exceed"]]                         # doctest: +SKIP
    """

    dataset: xr.Dataset
    #: The per-question structure the report's text renders (questions, basis notes, fans).
    result: SizingResult = field(repr=False)

    def __getitem__(self, name: str) -> xr.DataArray:
        return self.dataset[name]

    def __repr__(self) -> str:
        ds = self.dataset
        laws = [str(k) for k, r in zip(ds["law"].values, ds["role"].values, strict=True) if r == "law"]
        return (f"<SizingAnswer from {self.source}: {int(ds['question'].max()) if ds.sizes['point'] else 0} "
                f"question(s), {ds.sizes['point']} point(s), laws {', '.join(laws)}; |{self.response}| in SI>")

    # -- the structure the renderings read (kept for callers of the earlier result) --------------
    @property
    def answers(self) -> list[Answer]:
        """Each question's answer as computed (questions, basis, warnings, fan bands)."""
        return self.result.answers

    @property
    def response(self) -> str:
        return self.result.response

    @property
    def response_unit(self) -> str:
        return self.result.response_unit

    @property
    def response_scale(self) -> float:
        return self.result.response_scale

    @property
    def provenance(self) -> str:
        return self.result.provenance

    @property
    def source(self) -> str:
        return self.result.source

    def q(self, p: float, *, of: str = "noisy", calibrated: bool = False) -> xr.DataArray:
        """The ``p``-quantile of ``|T|`` per law, average and point, from the kept draws.

        A law's is the quantile of its draws (``numpy.quantile``); an average's inverts the
        weighted empirical CDF of its laws' draws: exactly how the kept quantiles were computed,
        so ``q(0.95)`` equals ``dataset["noisy"].sel(quantile=0.95)`` and ``q(confidence)`` the
        ``required`` capacity, bit for bit.

        Parameters
        ----------
        p : float
            The level, in (0, 1).
        of : {"noisy", "mean_fn"}
            With observation noise (what the drive meets), or the mean function alone.
        calibrated : bool
            With the measured model-form error added (NaN where none was measured).

        Returns
        -------
        xarray.DataArray
            ``(law, point)``, SI; NaN where a row has no answer at a point.

        Raises
        ------
        UserError
            ``p`` is not a number in (0, 1), or ``of`` is not one of the two.

        Examples
        --------
        >>> s.q(0.999, calibrated=True).sel(law="average")   # doctest: +SKIP
        """
        if isinstance(p, bool) or not isinstance(p, numbers.Real) or not 0 < float(p) < 1:
            raise UserError(f"p: a quantile level must be a number in (0, 1), got {p!r}")
        if of not in _KINDS:
            raise UserError(f"of: must be one of {', '.join(_KINDS)}, got {of!r}")
        return _quantile(self.dataset, float(p), ("calibrated_" if calibrated else "") + of)

    def to_dataframe(self) -> pd.DataFrame:
        """One row per law (or average) and point that has an answer, one column per variable
        and coordinate (a quantile's as ``<variable>_q<percent>``, e.g. ``noisy_q95``); SI.

        The draws are left out (:meth:`q` reads them).

        Examples
        --------
        >>> s.to_dataframe().query("role == 'average'")[["velocity", "calibrated_required"]]  # doctest: +SKIP
        """
        ds = self.dataset.drop_vars([v for v in DRAW_VARS if v in self.dataset])
        flat = ds.drop_vars([*QUANTILE_VARS, "quantile"]).drop_dims(["component", "sample"], errors="ignore")
        frame = flat.to_dataframe()
        for var in QUANTILE_VARS:
            for level in ds["quantile"].values:
                frame[f"{var}_q{float(level) * 100:g}"] = ds[var].sel(quantile=level).to_series()
        frame = frame[frame["name"] != ""].reset_index()
        where = [str(c) for c in ds.coords if ds[c].dims == ("point",) and c != "point"]
        front = ["question", "question_point", "point", *where, "law", "role", "name"]
        return frame[list(dict.fromkeys(front + list(frame.columns)))]


def _quantile(ds: xr.Dataset, p: float, kind: str) -> xr.DataArray:
    prefix = "calibrated_" if kind.startswith("calibrated_") else ""
    draws, weights = ds[f"{prefix}draws_{kind.removeprefix(prefix)}"].values, ds[f"{prefix}mix_weight"].values
    n_draws, roles, names = ds["n_draws"].values, ds["role"].values, ds["name"].values
    out = np.full((ds.sizes["law"], ds.sizes["point"]), np.nan)
    questions = ds["question"].values
    for i in dict.fromkeys(questions):
        cols = np.flatnonzero(questions == i)
        for r, role in enumerate(roles):
            if names[r, cols[0]] == "":
                continue
            w = weights[r, :, cols[0]]
            picked = [k for k in range(len(w)) if w[k] > 0 and n_draws[k] > 0]
            if not picked:
                continue
            parts = [draws[k, :n_draws[k]][:, cols] for k in picked]
            if any(np.isnan(x).any() for x in parts):
                continue
            if role == "law":
                out[r, cols] = np.quantile(parts[0], p, axis=0)
            else:
                per_draw = np.concatenate([np.full(n_draws[k], w[k] / n_draws[k]) for k in picked])
                out[r, cols] = weighted_quantiles(np.concatenate(parts), per_draw, [p])[p]
    return xr.DataArray(out, coords={"law": ds["law"], "point": ds["point"]}, dims=("law", "point"),
                        name=f"{kind}_q{p * 100:g}", attrs={"units": ds.attrs.get("unit", ""), "quantile": p})


def as_answer(result: SizingResult) -> SizingAnswer:
    """The :class:`SizingAnswer` of computed answers (their draws kept)."""
    return SizingAnswer(build_dataset(result), result)
