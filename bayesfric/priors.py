"""Priors as data: small printable, serialisable specs that become numpyro distributions.

A :class:`Prior` is a distribution name plus keyword arguments, e.g. ``Prior("LogNormal",
loc=0.0, scale=0.5)``. It prints as ``LogNormal(loc=0, scale=0.5)``, round-trips through a dict
(and so through TOML), and may be overridden by parameter name from Python or a study file.

Scaling rule for weakly-informative priors of generic coefficients
------------------------------------------------------------------
A generic coefficient (a Coulomb level, a viscous coefficient, a noise scale) has no literature
value; its natural size is set by the data. Such a prior is declared with ``scaled_by``: a mapping
from ``"response"`` and input-quantity names to powers, e.g. a viscous coefficient with unit
N·m·s/rad declares ``scaled_by={"response": 1, "velocity": -1}``. When the prior is resolved
against a dataset, the *data scale* is

    S = R^a · Π_k X_k^(b_k),

where R is the response scale and X_k the scale of input k (both: the largest absolute value in
the data, ignoring non-finite entries and falling back to 1 for an all-zero column), and a, b_k are
the declared powers. Location-scale arguments (``loc``, ``scale``, ``low``, ``high``) of the spec are
multiplied by S; for ``LogNormal`` (whose ``loc`` is on the log scale) ``log S`` is added to ``loc``
instead. Shape arguments (``df``, ``concentration`` ...) are left alone. Read: "a term of this
law, at the largest tested input, is of the order of the largest observed response" -- so
``HalfNormal(scale=1)`` scaled by the rule puts about 68 % of its mass on terms no larger than the
biggest observed response and leaves room for 2–3 times that. The rule is stated once, here; the
report prints both the declared spec and its resolved numbers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpyro.distributions as dist

__all__ = ["Prior", "DataScale", "PriorError", "DISTRIBUTIONS"]


class PriorError(ValueError):
    """An invalid prior spec (unknown distribution or argument)."""


# name -> (numpyro class, allowed args, location/scale args that the scaling rule multiplies)
DISTRIBUTIONS: dict[str, tuple[type, tuple[str, ...], tuple[str, ...]]] = {
    "Normal": (dist.Normal, ("loc", "scale"), ("loc", "scale")),
    "HalfNormal": (dist.HalfNormal, ("scale",), ("scale",)),
    "HalfCauchy": (dist.HalfCauchy, ("scale",), ("scale",)),
    "LogNormal": (dist.LogNormal, ("loc", "scale"), ()),  # loc shifted by log S, see module doc
    "TruncatedNormal": (dist.TruncatedNormal, ("loc", "scale", "low", "high"), ("loc", "scale", "low", "high")),
    "Uniform": (dist.Uniform, ("low", "high"), ("low", "high")),
    "Exponential": (dist.Exponential, ("rate",), ()),  # rate divided by S
    "Gamma": (dist.Gamma, ("concentration", "rate"), ()),  # rate divided by S
    "Beta": (dist.Beta, ("concentration1", "concentration0"), ()),
    "StudentT": (dist.StudentT, ("df", "loc", "scale"), ("loc", "scale")),
}
_RATE_ARGS = ("rate",)
#: Arguments that must be strictly positive in every distribution that takes them.
_POSITIVE_ARGS = ("scale", "rate", "concentration", "concentration1", "concentration0", "df")


def _finite(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


@dataclass(frozen=True)
class DataScale:
    """Response and input scales of a dataset, used to resolve data-scaled priors."""

    response: float
    inputs: Mapping[str, float] = field(default_factory=dict)

    @staticmethod
    def of(response: np.ndarray, inputs: Mapping[str, np.ndarray]) -> DataScale:
        """Compute scales as the largest finite absolute value (1.0 if that is zero)."""

        def scale(x) -> float:
            x = np.abs(np.asarray(x, dtype=float))
            x = x[np.isfinite(x)]
            m = float(x.max()) if x.size else 0.0
            return m if m > 0 else 1.0

        return DataScale(scale(response), {k: scale(v) for k, v in inputs.items()})

    def factor(self, powers: Mapping[str, float]) -> float:
        """S = R^a · Π X_k^(b_k) for the given powers (see the module docstring)."""
        s = 1.0
        for name, power in powers.items():
            if name == "response":
                s *= self.response**power
            elif name in self.inputs:
                s *= self.inputs[name] ** power
            else:
                raise PriorError(f"prior scaled by {name!r}, but the data has no such input")
        return s


@dataclass(frozen=True)
class Prior:
    """A prior distribution spec: ``Prior("HalfNormal", scale=2.0)``.

    Parameters
    ----------
    dist : str
        Name of a distribution in :data:`DISTRIBUTIONS`.
    scaled_by : mapping, optional
        Powers of the data scales this prior is expressed in (module docstring); empty for a
        prior stated in absolute SI numbers.
    **args
        The distribution's keyword arguments.
    """

    dist: str
    args: Mapping[str, float]
    scaled_by: Mapping[str, float]

    def __init__(self, dist: str, /, *, scaled_by: Mapping[str, float] | None = None, **args: float):
        if not isinstance(dist, str) or dist not in DISTRIBUTIONS:
            raise PriorError(f"unknown distribution {dist!r}; known: {', '.join(DISTRIBUTIONS)}")
        allowed = DISTRIBUTIONS[dist][1]
        unknown = set(args) - set(allowed)
        missing = set(allowed) - set(args)
        if unknown or missing:
            raise PriorError(
                f"{dist} takes arguments {', '.join(allowed)}; got {', '.join(sorted(args)) or 'none'}"
            )
        for k, v in args.items():
            if not _finite(v):
                raise PriorError(f"{dist} argument {k}={v!r} is not a finite number")
            if k in _POSITIVE_ARGS and not v > 0:
                raise PriorError(f"{dist} argument {k}={_fmt(v)} must be > 0")
        if "low" in args and "high" in args and not args["low"] < args["high"]:
            raise PriorError(f"{dist} arguments low={_fmt(args['low'])}, high={_fmt(args['high'])}: "
                             "low must be < high")
        if scaled_by is not None and not isinstance(scaled_by, Mapping):
            raise PriorError(f"scaled_by must be a table of powers by name, got {scaled_by!r}")
        for k, v in (scaled_by or {}).items():
            if not isinstance(k, str) or not _finite(v):
                raise PriorError(f"scaled_by {k}={v!r}: powers must be finite numbers")
        object.__setattr__(self, "dist", dist)
        object.__setattr__(self, "args", dict(args))
        object.__setattr__(self, "scaled_by", dict(scaled_by or {}))

    # -- printing and serialisation -------------------------------------------------------------
    def __str__(self) -> str:
        body = ", ".join(f"{k}={_fmt(v)}" for k, v in self.args.items())
        text = f"{self.dist}({body})"
        if self.scaled_by:
            text += " × " + _scale_text(self.scaled_by)
        return text

    __repr__ = __str__

    def to_dict(self) -> dict[str, Any]:
        """Serialise to a plain dict (TOML/JSON friendly)."""
        out: dict[str, Any] = {"dist": self.dist, **self.args}
        if self.scaled_by:
            out["scaled_by"] = dict(self.scaled_by)
        return out

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any]) -> Prior:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        PriorError
            ``spec`` is not a mapping, has no ``dist``, or describes an invalid prior (unknown
            distribution or argument, a non-finite number, a scale, rate, concentration or
            ``df`` that is not positive, ``low >= high``).
        """
        if not isinstance(spec, Mapping):
            example = '{"dist": "HalfNormal", "scale": 1.0}'
            raise PriorError(f"a prior spec must be a table/object such as {example}, "
                             f"got {type(spec).__name__} {spec!r}")
        spec = dict(spec)
        if "dist" not in spec:
            raise PriorError(f"prior spec {spec!r} has no 'dist' key")
        name = spec.pop("dist")
        scaled_by = spec.pop("scaled_by", None)
        return cls(name, scaled_by=scaled_by, **spec)

    # -- resolution -----------------------------------------------------------------------------
    def resolve(self, scale: DataScale | None) -> Prior:
        """Return an absolute prior (no ``scaled_by``) by applying the data-scaling rule."""
        if not self.scaled_by:
            return self
        if scale is None:
            raise PriorError(f"prior {self} is data-scaled but no data scale was given")
        s = scale.factor(self.scaled_by)
        multiplied = DISTRIBUTIONS[self.dist][2]
        args = {}
        for k, v in self.args.items():
            if k in multiplied:
                v = v * s
            elif k in _RATE_ARGS:
                v = v / s
            elif self.dist == "LogNormal" and k == "loc":
                v = v + math.log(s)
            args[k] = float(v)
        return Prior(self.dist, **args)

    def to_numpyro(self, scale: DataScale | None = None) -> dist.Distribution:
        """Build the numpyro distribution (resolving the data scale first if needed)."""
        p = self.resolve(scale)
        return DISTRIBUTIONS[p.dist][0](**p.args)


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _scale_text(powers: Mapping[str, float]) -> str:
    parts = []
    for name, power in powers.items():
        sym = "R" if name == "response" else f"X[{name}]"
        parts.append(sym if power == 1 else f"{sym}^{_fmt(power)}")
    return "·".join(parts)
