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
the declared powers. A position the data do not record but a law integrates from the speed and
time it reads (GMS's break-away deflections) takes the largest excursion of ∫v dt from each
trajectory's start (:data:`bayesfric.quantities.DERIVED_POSITIONS`,
:func:`bayesfric.datasets.views.data_scale`).
Location-scale arguments (``loc``, ``scale``, ``low``, ``high``) of the spec are multiplied by S;
for ``LogNormal`` (whose ``loc`` is on the log scale) ``log S`` is added to ``loc`` instead; a
rate (``Exponential``, ``Gamma``) is divided by S. Shape arguments (``df``, ``concentration`` ...)
are left alone. Read: "a term of this law, at the largest tested input, is
of the order of the largest observed response" -- so ``HalfNormal(scale=1)`` scaled by the rule
puts about 68 % of its mass on terms no larger than the biggest observed response and leaves room
for 2–3 times that.

Bounds: each power is a finite number in [-:data:`MAX_POWER`, :data:`MAX_POWER`] (a coefficient's
unit is a small power of the response's and the inputs' units) named ``"response"`` or an
operating quantity (:data:`bayesfric.quantities.QUANTITIES`), checked when the spec is made; S is
computed in logarithms and must lie within 1e±:data:`MAX_LOG10` (data scales lie within
1e±12, :data:`bayesfric.quantities.SCALE_RANGE`, so real data never come near it), and every
resolved argument must be a finite number (positive where the distribution needs it), checked
where priors are resolved (:meth:`Prior.resolve`). The rule is stated once, here; the
report prints both the declared spec and its resolved numbers.

Every problem is a :class:`PriorError` with a one-line ``problem`` and the ``key`` inside the spec
it concerns (``scaled_by.response``, ``scale``; with :meth:`PriorError.within` also the parameter,
``priors.T_C.scaled_by.response``), which callers prefix with the study file's entry or the option.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpyro.distributions as dist

from bayesfric.errors import UserError

__all__ = ["Prior", "DataScale", "PriorError", "DISTRIBUTIONS", "MAX_POWER", "MAX_LOG10", "resolve_all", "rescaled"]

#: Largest |power| of a data scale in ``scaled_by`` (module docstring).
MAX_POWER = 2.0
#: Largest |log10| of a number a model is given: a data-scale factor S, the bulk of a prior
#: (:meth:`Prior.reach`), a fixed parameter or constant (:mod:`bayesfric.laws.variants`). Within
#: 1e±100 squares and products with data (1e±12) stay far inside float64; a prior whose draws
#: reach 1e300 overflows the likelihood and leaves a fit of non-finite draws.
MAX_LOG10 = 100.0


class PriorError(UserError):
    """An invalid prior spec: a one-line ``problem`` and the ``key`` inside the spec it concerns
    (``scaled_by.response``, ``scale``; empty for the spec as a whole)."""

    def __init__(self, problem: str, key: str = ""):
        super().__init__(problem, key)


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
        """S = R^a · Π X_k^(b_k) for the given powers (see the module docstring), computed in logarithms.

        Raises
        ------
        PriorError
            The data has no such input, a scale is not a positive finite number, or S lies
            beyond 1e±:data:`MAX_LOG10`.
        """
        log10_s = 0.0
        for name, power in powers.items():
            if name != "response" and name not in self.inputs:
                raise PriorError(f"prior scaled by {name!r}, but the data has no such input", f"scaled_by.{name}")
            x = self.response if name == "response" else self.inputs[name]
            if not (math.isfinite(x) and x > 0):
                raise PriorError(f"the data scale of {name} is {x!r}, not a positive number", f"scaled_by.{name}")
            log10_s += power * math.log10(x)
        try:
            if abs(log10_s) > MAX_LOG10:
                raise OverflowError
            s = 1.0
            for name, power in powers.items():  # the product as stated (the logarithms only bound it)
                s *= (self.response if name == "response" else self.inputs[name]) ** power
        except OverflowError:
            raise PriorError(f"the data scale {_scale_text(powers)} is 1e{log10_s:+.0f}, beyond "
                             f"1e±{MAX_LOG10:g}: the powers do not fit this data", "scaled_by") from None
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
                raise PriorError(f"{dist} argument {k}={v!r} is not a finite number", k)
            if k in _POSITIVE_ARGS and not v > 0:
                raise PriorError(f"{dist} argument {k}={_fmt(v)} must be > 0", k)
        if "low" in args and "high" in args and not args["low"] < args["high"]:
            raise PriorError(f"{dist} arguments low={_fmt(args['low'])}, high={_fmt(args['high'])}: "
                             "low must be < high")
        if (reach := _reach_log10(dist, args)) > MAX_LOG10:
            body = ", ".join(f"{k}={_fmt(v)}" for k, v in args.items())
            shown = f"1e{reach:.0f}" if math.isfinite(reach) else "beyond float64"
            raise PriorError(f"{dist}({body}) reaches {shown}: the bulk of a prior (location ± 10 scales) "
                             f"must stay within ±1e{MAX_LOG10:g}")
        _check_powers(scaled_by)
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
        try:
            return Prior(self.dist, **args)
        except PriorError as exc:
            raise PriorError(f"scaled by the data scale {_scale_text(self.scaled_by)} = {s:.3g}: {exc.problem}",
                             exc.key) from None

    def to_numpyro(self, scale: DataScale | None = None) -> dist.Distribution:
        """Build the numpyro distribution (resolving the data scale first if needed)."""
        p = self.resolve(scale)
        return DISTRIBUTIONS[p.dist][0](**p.args)


def resolve_all(priors: Mapping[str, Prior], scale: DataScale | None) -> dict[str, Prior]:
    """Every prior of ``priors`` (parameter -> prior) resolved; an error's key names the parameter
    (``priors.T_C.scaled_by``)."""
    resolved = {}
    for name, prior in priors.items():
        try:
            resolved[name] = prior.resolve(scale)
        except PriorError as exc:
            raise exc.within(f"priors.{name}") from None
    return resolved


class _Scaled(dist.constraints.Constraint):
    """The support of :class:`_Rescaled`: the base support (closed under positive scaling), whose
    bijection from the unconstrained line is followed by a multiplication by ``factor``."""

    def __init__(self, base: dist.constraints.Constraint, factor: Any):
        self.base, self.factor, self.event_dim = base, factor, base.event_dim

    def __call__(self, x):
        return self.base(x)

    def feasible_like(self, prototype):
        return self.base.feasible_like(prototype)

    def tree_flatten(self):
        return (self.factor,), (("factor",), {"base": self.base, "event_dim": self.event_dim})


@dist.biject_to.register(_Scaled)
def _scaled_bijection(constraint: _Scaled) -> dist.transforms.Transform:
    return dist.transforms.ComposeTransform([dist.biject_to(constraint.base),
                                             dist.transforms.AffineTransform(0.0, constraint.factor)])


class _Rescaled(dist.Distribution):
    """``base`` unchanged (samples, density), with the unconstrained coordinate of ``value / factor``."""

    arg_constraints: dict = {}
    pytree_data_fields = ("base", "factor")

    def __init__(self, base: dist.Distribution, factor: Any):
        self.base, self.factor = base, factor
        super().__init__(batch_shape=base.batch_shape, event_shape=base.event_shape)

    @property
    def support(self):
        return _Scaled(self.base.support, self.factor)

    def sample(self, key, sample_shape=()):
        return self.base.sample(key, sample_shape)

    def log_prob(self, value):
        return self.base.log_prob(value)


def rescaled(distribution: dist.Distribution, factor: Any) -> dist.Distribution:
    """``distribution`` as it is, but sampled (NUTS, optimisers) on the unconstrained scale of
    ``value / factor``: a log scale ``log(value / factor)`` for a positive one.

    Why: where the data pin a parameter only through its product with a function of other
    parameters (``value / factor``), this makes the pinned combination a coordinate of the sampler,
    and a curved, thin ridge an axis-aligned one. Exact: the distribution, and so every prior and
    posterior, is unchanged; only the coordinates move (their Jacobian, ``log factor``, comes with
    the bijection). ``factor`` (> 0) may depend on parameters sampled before. A support not
    closed under positive scaling (an interval) is returned as it is.

    Parameters
    ----------
    distribution : numpyro Distribution
        A prior with support ``positive`` or ``real``.
    factor : array
        Positive; broadcast against the distribution's values.
    """
    if distribution.support not in (dist.constraints.positive, dist.constraints.real):
        return distribution
    return _Rescaled(distribution, factor)


def _check_powers(scaled_by: object) -> None:
    """``scaled_by``: None or a table of powers in [-MAX_POWER, MAX_POWER] by ``response`` or quantity."""
    from bayesfric.quantities import QUANTITIES

    if scaled_by is None:
        return
    if not isinstance(scaled_by, Mapping):
        raise PriorError(f"must be a table of powers by name, got {scaled_by!r}", "scaled_by")
    for k, v in scaled_by.items():
        if not isinstance(k, str) or (k != "response" and k not in QUANTITIES):
            raise PriorError(f"{k!r} is neither 'response' nor an operating quantity ({', '.join(QUANTITIES)})",
                             f"scaled_by.{k}")
        if not _finite(v) or abs(v) > MAX_POWER:
            raise PriorError(f"the power must be a number from {-MAX_POWER:g} to {MAX_POWER:g}, got {v!r}",
                             f"scaled_by.{k}")


def _reach_log10(dist: str, a: Mapping[str, float]) -> float:
    """log10 of the largest magnitude in the bulk of a prior: location ± 10 scales (``LogNormal``:
    of its exponent; a rate: 10 / rate), the bounds of a uniform or truncated one."""
    if dist == "LogNormal":
        return (abs(a["loc"]) + 10 * a["scale"]) / math.log(10)
    if dist in ("Exponential", "Gamma"):  # float arithmetic overflows to inf, never raises here
        shape = a.get("concentration", 1.0)
        peak = (shape + 10 * math.sqrt(shape)) / a["rate"]
    elif dist == "Beta":
        peak = 1.0
    else:
        peak = max([abs(a.get("loc", 0.0)) + 10 * a.get("scale", 0.0)] + [abs(a[k]) for k in ("low", "high") if k in a])
    return math.log10(peak) if peak > 0 else -math.inf


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _scale_text(powers: Mapping[str, float]) -> str:
    parts = []
    for name, power in powers.items():
        sym = "R" if name == "response" else f"X[{name}]"
        parts.append(sym if power == 1 else f"{sym}^{_fmt(power)}")
    return "·".join(parts)
