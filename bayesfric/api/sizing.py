"""Public API: actuator sizing from one fit or from a study's result.

The same functions answer ``bayesfric size`` (:mod:`bayesfric.sizing.single` for a fit,
:mod:`bayesfric.study.resize` for a study's report); here every key of the question is checked
where it is given, and an error names the argument (``at.velocity``, ``capacity``,
``confidence``): a capacity is never dropped, an input never held at a default.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import xarray as xr

from bayesfric.errors import UserError
from bayesfric.sizing import SizingError, SizingQuestion
from bayesfric.sizing.result import SizingAnswer

__all__ = ["size", "question", "time_to_exceed"]

_NO_KEYS: dict[str, str] = {}  # errors name the keys as the arguments: at.velocity, capacity, confidence


def question(at: Mapping[str, Any] | str, *, capacity: Any = None, confidence: float | None = None,
             energy_rotation: Any = None, label: str = "") -> SizingQuestion:
    """A sizing question from Python values; its data-independent checks run here.

    Values are ``"2 rad/s"``, ``(2, "rad/s")`` or a range ``(0.5, 6, "rad/s")`` (sized at 25
    points); ``at`` may also be the command line's text, ``"velocity=2 rad/s, temperature=40 degC"``.

    Raises
    ------
    SizingError
        One line naming the argument: a value without a unit or with one of another dimension,
        an unknown input quantity, a confidence outside (0, 1), a capacity that is not positive.

    Examples
    --------
    >>> from bayesfric.api.sizing import question
    >>> q = question({"velocity": (0.5, 6, "rad/s")}, capacity=(40, "N*m"))
    >>> q.describe(), q.capacity_text, q.confidence
    ('velocity = 0.5..6 rad/s', '40 N*m', 0.99)
    >>> question({"velocity": 2})
    Traceback (most recent call last):
    ...
    bayesfric.sizing.points.SizingError: at.velocity: 2 has no unit; give it as (2, "rad/s") or "2 rad/s"
    """
    from bayesfric.sizing import make_question, parse_at
    from bayesfric.sizing.points import value_text

    if isinstance(at, str):
        texts: dict[str, Any] = parse_at(at, "at")
    elif isinstance(at, Mapping):
        texts = {str(k): value_text(v, f"at.{k}", str(k)) for k, v in at.items()}
    else:
        raise SizingError("at", f"expected a dict of input -> value, e.g. {{'velocity': (2, 'rad/s')}}, got {at!r}")
    level = 0.99 if confidence is None else confidence
    if isinstance(level, bool) or not isinstance(level, int | float):
        raise SizingError("confidence", f"must be a number in (0, 1), got {level!r}")
    cap = value_text(capacity, "capacity", "torque") if capacity is not None else None
    rotation = value_text(energy_rotation, "energy_rotation", "angle") if energy_rotation is not None else None
    return make_question(texts, float(level), label=label, capacity=cap, energy_rotation=rotation, keys=_NO_KEYS)


def size(source: Any, at: Mapping[str, Any] | str | None = None, *, capacity: Any = None,
         confidence: float | None = None, energy_rotation: Any = None, reports: str | Path = "reports",
         seed: int = 0) -> SizingAnswer:
    """The friction torque (or force) a drive must deliver at operating points, and how sure that is.

    Parameters
    ----------
    source : xarray.DataTree, StudyResult, Study, str or Path
        A fit (:func:`bayesfric.fit`; its law is rebuilt from what the fit records: a
        registered law, a variant, or a user's law found by name or through its file), a study's result
        (:func:`bayesfric.run`), a study whose report exists in ``reports``, or a file: a fit
        (``.nc``) or a study (``.toml``).
    at : mapping or str, optional
        Input -> value: ``{"velocity": (0.5, 6, "rad/s")}`` (a range), ``{"velocity": "2 rad/s"}``.
        Every input the law(s) read must be given. Required with a fit; without it a study
        answers its own ``[[sizing]]`` questions.
    capacity : str or (number, unit), optional
        The drive's torque or force: the answer gives P(|T| > capacity) at every point.
    confidence : float, optional
        Size for this quantile of |T|, in (0, 1) (default 0.99).
    energy_rotation : str or (number, unit), optional
        Friction energy of one rotation through this angle (torque data).
    reports : str or Path
        Reports root of a study given as a Study or a file.
    seed : int
        Seed of the predictive draws.

    Returns
    -------
    SizingAnswer
        One Dataset (``.dataset``, SI) over ``law`` (every law, then ``average`` and
        ``average_loo``) × ``point`` (every point of every question) × ``quantile``: ``required``,
        ``p_exceed`` (± ``p_exceed_se``), the quantiles ``mean_fn`` and ``noisy`` and their
        ``calibrated_`` forms; attrs say what the answer is for.
        ``.to_dataframe()`` gives one row per law and point, ``.q(p)`` the quantile at any level
        from the kept draws; ``bayesfric.report.sizing.text_report`` prints it as ``bayesfric
        size`` does (:class:`~bayesfric.sizing.result.SizingAnswer`).

    Raises
    ------
    UserError
        One line naming the argument: ``at.velocity`` (no unit, another dimension, not an input
        of the law or data), ``at`` (an input the laws read is missing), ``capacity`` (not of the
        response quantity, not positive), ``confidence``; ``capacity``/``confidence`` without ``at``.

    Examples
    --------
    >>> import bayesfric
    >>> f = bayesfric.fit("coulomb_viscous", "robot_joint", draws=100, tune=100, chains=2)
    >>> result = bayesfric.size(f, at={"velocity": (5, "rad/s")}, capacity=(40, "N*m"))
    >>> answer = result.dataset.sel(law="coulomb_viscous", point=0)
    >>> bool(0 <= answer["p_exceed"] <= 1), bool(answer["required"] > 0)
    (True, True)
    >>> bool(result.q(0.999).sel(law="coulomb_viscous", point=0) > answer["required"])  # any level
    True
    """
    from bayesfric.api.studies import StudyResult, as_study

    if at is None:
        for name, value in (("capacity", capacity), ("confidence", confidence), ("energy_rotation", energy_rotation)):
            if value is not None:
                raise SizingError(name, "applies only with at (a study's [[sizing]] questions carry their own)")
        asked = None
    else:
        asked = question(at, capacity=capacity, confidence=confidence, energy_rotation=energy_rotation)
    if isinstance(source, str | Path) and str(source).endswith(".nc"):
        from bayesfric.sizing.single import read_fit

        return _size_fit(read_fit(source), asked, Path(source).name, seed)
    if isinstance(source, xr.DataTree):
        return _size_fit(source, asked, f"of {source.attrs.get('law', '?')}", seed)
    if isinstance(source, StudyResult):
        source, reports = source.study, source.folder.parent
    study = as_study(source, "source")
    from bayesfric.study.resize import size_from_report

    return size_from_report(study, [asked] if asked is not None else None, reports, keys=_NO_KEYS,
                            run_hint=f"bayesfric.run(study, out={str(reports)!r})")


def _size_fit(fit: xr.DataTree, asked: SizingQuestion | None, name: str, seed: int) -> SizingAnswer:
    from bayesfric.sizing.single import answer_fit

    if asked is None:
        raise UserError("at: required with a fit, e.g. at={'velocity': (2, 'rad/s')}")
    return answer_fit(fit, asked, name=name, keys=_NO_KEYS, where=f"fit {name}", seed=seed)


def time_to_exceed(source: xr.DataTree | str | Path, at: Mapping[str, Any] | str, *, capacity: Any, horizon: Any,
                   unit: str = "", seed: int = 0) -> xr.Dataset:
    """When will friction at an operating point first exceed the drive's capacity, for a law whose
    parameters follow a trend over service time (:meth:`Law.trend <bayesfric.laws.base.Law.trend>`)?

    Parameters
    ----------
    source : xarray.DataTree, str or Path
        A fit (:func:`bayesfric.fit`) of a law with a trend, or its file (``.nc``).
    at : mapping or str
        One operating point: ``{"velocity": "1400 rpm"}`` or ``"velocity=1400 rpm"``.
    capacity : str or (number, unit)
        The drive's torque or force.
    horizon : str, number or (number, unit)
        The latest service time to forecast to: ``"20000 h"`` or ``(20000, "h")``, converted to
        the service coordinate's unit (a unit of another dimension, ``"20000 rpm"``, is refused),
        or a number in that unit.
    unit : str
        The service coordinate's unit, to convert ``horizon`` into; default the one the fit
        records (the data column's ``unit``). The answer is in this unit.
    seed : int
        Seed of a random walk's paths and of the new campaigns' scatter.

    Returns
    -------
    xarray.Dataset
        ``crossing_q`` (quantiles of the time to exceed, ``inf`` beyond the horizon), ``p_exceed``
        over ``service`` time, the fans ``fan`` (the typical campaign) and ``fan_new`` (a new
        campaign), ``campaign_q`` (the fitted campaigns) and each draw's ``crossing``
        (:func:`bayesfric.sizing.exceed.time_to_exceed`). Attrs say what the answer is for.

    Raises
    ------
    SizingError
        One line naming the argument: a point without a unit, a bad capacity or horizon, a law
        without a trend.

    Examples
    --------
    >>> import bayesfric
    >>> oring = bayesfric.law("coastdown_oring_closed_form").trend("hours", "T_C", "c_v")  # doctest: +SKIP
    >>> f = bayesfric.fit(oring, "drum_campaigns")                                      # doctest: +SKIP
    >>> out = bayesfric.time_to_exceed(f, {"velocity": "1400 rpm"}, capacity="1.8 N*m",
    ...                                horizon="20000 h")                               # doctest: +SKIP
    >>> out["crossing_q"].sel(quantile=[0.05, 0.5, 0.95]).values                         # doctest: +SKIP
    """
    from bayesfric.sizing.exceed import time_to_exceed as answer
    from bayesfric.sizing.points import value_text

    if isinstance(source, str | Path):
        from bayesfric.sizing.single import read_fit

        source = read_fit(source)
    asked = question(at, capacity=capacity)
    if asked.axis is not None:
        raise SizingError("at", f"a time to exceed is asked at one point, not a range of {asked.axis}")
    if isinstance(horizon, tuple | list):  # (20000, "h"), as the other quantities are given
        horizon = value_text(horizon, "horizon", "time")
    cap = value_text(capacity, "capacity", "torque") if not isinstance(capacity, str) else capacity
    return answer(source, {k: v.lo for k, v in asked.at.items()}, cap, horizon, unit=unit,
                  seed=seed).drop_vars(["curve", "curve_new"])
