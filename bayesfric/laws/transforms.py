"""The transformations a variant applies to a declared law (:mod:`bayesfric.laws.variants` says
what each means and builds variants from recipes): :func:`add` a part, split parameters by
direction (:func:`asymmetric`), :func:`fix` parameters, do :func:`without` an optional input, run
on force data (:func:`translational`, with :func:`translation_problem` and
:func:`translational_unit`). Each returns a new, unregistered law validated by
:func:`bayesfric.laws.base.declare`; each problem is a :class:`~bayesfric.laws.base.VariantError`.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import jax.numpy as jnp
import numpy as np

from bayesfric.laws.base import TRAJECTORY_START, Constant, Derived, Law, Param, VariantError, declare
from bayesfric.priors import MAX_LOG10, Prior
from bayesfric.quantities import parse_unit

__all__ = ["TRANSLATIONAL", "MOTION_NEUTRAL", "translational_unit", "translation_problem", "add", "asymmetric", "fix",
           "without", "translational", "mass_name"]

#: Rotary quantity -> its translational counterpart.
TRANSLATIONAL = {"velocity": "linear_velocity", "angle": "displacement", "torque": "force",
                 "acceleration": "linear_acceleration"}
#: Inputs whose meaning does not depend on the motion kind.
MOTION_NEUTRAL = ("time", "preload", "temperature", "normal_force", TRAJECTORY_START)


# -- units ---------------------------------------------------------------------------------------
def translational_unit(unit: str) -> str:
    """The translational form of a rotary SI unit: N·m → N, rad → m (powers kept).

    A unit whose newton and metre powers are equal carries torque (N·m)^a and becomes N^a;
    radians become metres. Anything else (a preload in N, a time, a temperature) is unchanged.

    >>> translational_unit("N*m*s/rad")
    'N*s/m'
    """
    powers = {str(k): float(v) for k, v in parse_unit(unit)._units.items()}
    torque = powers.get("newton", 0.0)
    changed = False
    if torque and powers.get("meter", 0.0) == torque:
        powers.pop("meter")
        changed = True
    if not torque and powers.get("kilogram") == 1 and powers.get("meter") == 2:  # J (kg·m²) -> M (kg)
        powers.pop("meter")
        changed = True
    if "radian" in powers:
        angle = powers.pop("radian")
        powers["meter"] = powers.get("meter", 0.0) + angle
        changed = True
    return _format_unit(powers) if changed else unit


_SYMBOL = {"newton": "N", "meter": "m", "second": "s", "kilogram": "kg", "kelvin": "K", "pascal": "Pa"}


def _format_unit(powers: Mapping[str, float]) -> str:
    def part(name: str, p: float) -> str:
        sym = _SYMBOL.get(name, name)
        p = abs(p)
        return sym if p == 1 else f"{sym}**{int(p) if float(p).is_integer() else p:g}"

    order = sorted((k for k, v in powers.items() if v), key=lambda k: list(_SYMBOL).index(k) if k in _SYMBOL else 99)
    num = "*".join(part(k, powers[k]) for k in order if powers[k] > 0) or "1"
    den = "*".join(part(k, powers[k]) for k in order if powers[k] < 0)
    return f"{num}/{den}" if den else num


# -- building blocks -----------------------------------------------------------------------------
def _rebuild(base: Law, call: Callable[[dict[str, Any]], Any], **changes: Any) -> Law:
    """A new (unregistered) law like ``base`` with ``changes``; its function calls ``call(kwargs)``."""
    # a declared steady state reads the declared law's names: a variant's is rebuilt from its recipe
    # (bayesfric.laws.steady.steady_state), never carried over
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(Law)} | {"steady": None} | changes
    names = list(fields["inputs"]) + list(fields["params"]) + list(fields["constants"])
    signature = inspect.Signature([inspect.Parameter(n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in names])

    def fn(*args, **kwargs):
        return call(dict(signature.bind(*args, **kwargs).arguments))

    fn.__signature__ = signature
    fn.__name__ = fn.__qualname__ = base.name
    fn.__doc__ = fields.pop("summary")
    fields.pop("fn")
    return declare(fn, **fields)


def _rewire(d: Derived, rename: Mapping[str, str], fixed: Mapping[str, float]) -> Derived:
    """``d`` reading its arguments under new names (``rename``: old -> new), some held fixed."""
    old = list(inspect.signature(d.fn).parameters)
    new = [rename.get(a, a) for a in old if a not in fixed]
    signature = inspect.Signature([inspect.Parameter(n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in new])

    def fn(*args, **kwargs):
        got = signature.bind(*args, **kwargs).arguments
        return d.fn(**{a: fixed[a] if a in fixed else got[rename.get(a, a)] for a in old})

    fn.__signature__ = signature
    return Derived(fn, d.unit, d.meaning)


def _reads(d: Derived) -> set[str]:
    return set(inspect.signature(d.fn).parameters)


# -- the operations ------------------------------------------------------------------------------
def add(law: Law, part: Law) -> Law:
    """``law + part``: a part's names the law already uses get the suffix ``_<part>``."""
    if law.response == "force" and part.response == "torque" and not translation_problem(part):
        part = translational(part)  # a law declared on force data (amontons) takes the terms' force form
    if part.response != law.response:
        raise VariantError(f"cannot add {part.name!r} ({part.response}) to law {law.name!r} ({law.response})",
                           "add")
    taken = set(law.params) | set(law.constants) | set(law.derived) | set(law.inputs)
    rename = {k: (f"{k}_{part.name}" if k in taken else k)
              for k in list(part.params) + list(part.constants) + list(part.derived)}
    inputs = law.inputs + tuple(i for i in part.inputs if i not in law.inputs)
    if TRAJECTORY_START in inputs:  # keep the structural input last, as declarations do
        inputs = tuple(i for i in inputs if i != TRAJECTORY_START) + (TRAJECTORY_START,)
    own = list(law.inputs) + list(law.params) + list(law.constants)
    theirs = list(part.inputs) + list(part.params) + list(part.constants)

    def call(kw):
        return law.fn(**{k: kw[k] for k in own}) + part.fn(**{k: kw[rename.get(k, k)] for k in theirs})

    return _rebuild(
        law, call, inputs=inputs, trajectory=law.trajectory or part.trajectory,
        params=dict(law.params) | {rename[k]: p for k, p in part.params.items()},
        constants=dict(law.constants) | {rename[k]: c for k, c in part.constants.items()},
        derived=dict(law.derived) | {rename[k]: _rewire(d, rename, {}) for k, d in part.derived.items()},
        optional=dict(law.optional) | dict(part.optional),
        sign_definite=law.sign_definite and part.sign_definite and part.name != "offset",
        rotary_only=law.rotary_only or part.rotary_only,
        summary=f"{law.summary} + {part.name}: {part.summary}",
    )


def asymmetric(law: Law, names: Sequence[str]) -> Law:
    """``law`` with one value of each named parameter per direction of motion (``_pos``, ``_neg``)."""
    direction = next((i for i in ("velocity", "linear_velocity") if i in law.inputs), None)
    if law.trajectory or direction is None:
        raise VariantError(f"law {law.name!r} must be a steady law that reads velocity "
                           "(a trajectory law would mix the two parameter sets along its state)", "asymmetric")
    unknown = [n for n in names if n not in law.params]
    if unknown:
        raise VariantError(f"law {law.name!r} has no parameter {unknown[0]!r} "
                           f"(parameters: {', '.join(law.params)})", "asymmetric")
    if any(law.params[n].shape for n in names):
        raise VariantError("vector-valued parameters cannot be split by direction", "asymmetric")
    params: dict[str, Param] = {}
    for k, p in law.params.items():
        if k in names:
            for side, text in (("pos", "velocity ≥ 0"), ("neg", "velocity < 0")):
                params[f"{k}_{side}"] = dataclasses.replace(p, meaning=f"{p.meaning}, direction {text}")
        else:
            params[k] = p
    derived: dict[str, Derived] = {}
    for k, d in law.derived.items():
        if _reads(d) & set(names):
            for side in ("pos", "neg"):
                derived[f"{k}_{side}"] = _rewire(d, {n: f"{n}_{side}" for n in names}, {})
        else:
            derived[k] = d
    own = list(law.inputs) + list(law.params) + list(law.constants)

    def call(kw):
        pos = law.fn(**{k: kw[f"{k}_pos"] if k in names else kw[k] for k in own})
        neg = law.fn(**{k: kw[f"{k}_neg"] if k in names else kw[k] for k in own})
        return jnp.where(jnp.asarray(kw[direction]) >= 0, pos, neg)

    return _rebuild(law, call, params=params, derived=derived,
                    summary=f"{law.summary} [direction-dependent {', '.join(names)}]")


def _support_problem(p: Param, value: float) -> str | None:
    """Why ``value`` lies outside the support of ``p``'s prior (None if inside)."""
    prior = Prior(p.prior.dist, **p.prior.args)  # support does not depend on the data scale
    # a NumPy value: numpyro's constraints then check it with NumPy. A JAX array would run (and
    # compile) JAX programs, and laws registered with a dropped part are fixed at import time,
    # so importing bayesfric.laws started the JAX backend and compiled two programs (45 ms).
    ok = bool(np.all(prior.to_numpyro().support.check(np.asarray(value, dtype=float))))
    return None if ok else f"outside the support of its prior {p.prior}"


def fix(law: Law, values: Mapping[str, float]) -> Law:
    """``law`` with parameters (or constants) held at ``values`` (SI) as constants."""
    params, constants, fixed_params = dict(law.params), dict(law.constants), {}
    for name, value in values.items():
        if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
            raise VariantError(f"must be a finite number, got {value!r}", f"fixed.{name}")
        if value and abs(math.log10(abs(value))) > MAX_LOG10:  # the bound of every number a model is given
            raise VariantError(f"{value:g} lies beyond 1e±{MAX_LOG10:g}, where the law's arithmetic overflows",
                               f"fixed.{name}")
        value = float(value)
        if name in constants:
            constants[name] = dataclasses.replace(constants[name], value=value)
        elif name in params:
            p = params.pop(name)
            if p.shape:
                raise VariantError("a vector-valued parameter cannot be fixed", f"fixed.{name}")
            if problem := _support_problem(p, value):
                raise VariantError(f"{value:g} is {problem}", f"fixed.{name}")
            constants[name] = Constant(value, p.unit, f"{p.meaning} (fixed)")
            fixed_params[name] = value
        else:
            raise VariantError(f"law {law.name!r} has no parameter or constant {name!r} "
                               f"(parameters: {', '.join(law.params) or 'none'}; constants: "
                               f"{', '.join(law.constants) or 'none'})", f"fixed.{name}")
    derived = {k: _rewire(d, {}, fixed_params) for k, d in law.derived.items() if _reads(d) - set(fixed_params)}
    own = list(law.inputs) + list(law.params) + list(law.constants)
    text = ", ".join(f"{k} = {v:g}" for k, v in values.items())
    return _rebuild(law, lambda kw: law.fn(**{k: kw[k] for k in own}), params=params, constants=constants,
                    derived=derived, summary=f"{law.summary} [fixed {text}]")


def without(law: Law, name: str) -> Law:
    """``law`` without its optional input ``name``: held at its reference, its parameters fixed at 0."""
    opt = law.optional[name]
    drops = {k: 0.0 for k in opt.drops if k in law.params}
    law = fix(law, drops) if drops else law
    constants = dict(law.constants) | {k: dataclasses.replace(law.constants[k], value=0.0)
                                       for k in opt.drops if k in law.constants and k not in drops}
    own = list(law.inputs) + list(law.params) + list(law.constants)

    def call(kw):
        return law.fn(**{k: kw[opt.fill] if k == name else kw[k] for k in own})

    return _rebuild(law, call, inputs=tuple(i for i in law.inputs if i != name), constants=constants,
                    optional={k: v for k, v in law.optional.items() if k != name},
                    summary=f"{law.summary} [no {name} input: held at {opt.fill}]")


def translation_problem(law: Law) -> str | None:
    """Why ``law`` cannot run on translational (force) data; None if it can."""
    if law.rotary_only:
        return law.rotary_only
    if law.response != "torque":
        return f"its response is {law.response}, not torque"
    other = [q for q in law.operating_inputs if q not in TRANSLATIONAL and q not in MOTION_NEUTRAL]
    if other:
        return f"it reads {', '.join(other)}, which has no translational counterpart"
    unscaled = [k for k, p in law.params.items() if p.translational is None and _angle_unscaled(p)]
    if unscaled:
        return (f"the prior of {', '.join(unscaled)} is stated in radians and declares no translational "
                "prior (Param.translational)")
    return None


def _angle_unscaled(p: Param) -> bool:
    """True if ``p``'s unit carries radians that its prior's data scaling does not supply."""
    rad = float(parse_unit(p.unit)._units.get("radian", 0.0))
    supplied = sum(v for k, v in p.prior.scaled_by.items() if k in ("velocity", "angle"))
    return rad != supplied


def translational(law: Law) -> Law:
    """``law`` on force data: translational inputs, response, units and priors."""
    if problem := translation_problem(law):
        raise VariantError(f"law {law.name!r} runs on rotary (torque) data only: {problem}")
    to = dict(TRANSLATIONAL) | mass_name(law)

    def param(p: Param) -> Param:
        prior = p.translational or Prior(
            p.prior.dist, scaled_by={to.get(k, k): v for k, v in p.prior.scaled_by.items()}, **p.prior.args)
        how = p.sampled_as and dataclasses.replace(
            p.sampled_as, scaled_by={to.get(k, k): v for k, v in p.sampled_as.scaled_by.items()})
        return dataclasses.replace(p, unit=translational_unit(p.unit), prior=prior, sampled_as=how,
                                   meaning=p.meaning.replace("torque", "force"))

    own = list(law.inputs) + list(law.params) + list(law.constants)
    return _rebuild(
        law, lambda kw: law.fn(**{k: kw[to.get(k, k)] for k in own}),
        inputs=tuple(to.get(i, i) for i in law.inputs), response="force",
        params={to.get(k, k): param(p) for k, p in law.params.items()},
        constants={to.get(k, k): dataclasses.replace(c, unit=translational_unit(c.unit))
                   for k, c in law.constants.items()},
        derived={k: dataclasses.replace(d, unit=translational_unit(d.unit),
                                        meaning=d.meaning.replace("torque", "force"))
                 for k, d in law.derived.items()},
        optional={to.get(k, k): v for k, v in law.optional.items()},
        summary=f"{law.summary} [translational: force in N, linear_velocity in m/s, displacement in m]",
    )


def mass_name(law: Law) -> dict[str, str]:
    """``{"J": "M"}`` when ``law`` has a moment of inertia ``J`` (kg·m²) that becomes a mass."""
    p = law.params.get("J") or law.constants.get("J")
    taken = "M" in law.params or "M" in law.constants
    return {"J": "M"} if p is not None and p.unit == "kg*m**2" and not taken else {}
