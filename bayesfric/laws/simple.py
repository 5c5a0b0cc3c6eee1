"""The short way to declare a law: a plain function plus units and priors.

:func:`simple_law` reads the law from the function's signature, as lmfit reads a model's
parameters: arguments named after an operating quantity of the vocabulary
(:data:`bayesfric.quantities.QUANTITIES`: ``velocity``, ``temperature``, ``load`` ...) are the
inputs, the other arguments without a default are the sampled parameters, and arguments with a
default are constants at that value. The arguments may come in any order. What it builds is
the same :class:`~bayesfric.laws.base.Law` the full :func:`~bayesfric.laws.base.law` decorator
builds (same checks, same registry), with defaults for what it does not ask:

- ``name``: the function's name; ``family``: ``"user"``; ``response``: ``"torque"``;
- ``source``: the file that declares it; a parameter's meaning: its name; the summary: the
  docstring's first line (or "user law <name>");
- a parameter without a prior gets ``HalfNormal(scale=1)`` scaled to the data by the powers of
  the response and the inputs that make up its unit (the scaling rule of
  :mod:`bayesfric.priors`), e.g. N·m·s/rad on torque-vs-velocity data is "response / velocity";
  a dimensionless one that no input explains gets ``LogNormal(loc=0, scale=1)``. Both are
  positive: give a prior for a coefficient that may be negative, or whose unit is not a product
  of the response's and the inputs' units.

Example
-------
>>> import jax.numpy as jnp
>>> def tanh_coulomb(velocity, T_C, v_eps=0.01):
...     '''Smooth Coulomb friction: T = T_C tanh(q̇ / q̇_eps).'''
...     return T_C * jnp.tanh(velocity / v_eps)
>>> law = simple_law(tanh_coulomb, units={"T_C": "N*m", "v_eps": "rad/s"}, register=False)
>>> law.inputs, list(law.params), law.constants["v_eps"].value
(('velocity',), ['T_C'], 0.01)
>>> str(law.params["T_C"].prior)
'HalfNormal(scale=1) × R'
"""

from __future__ import annotations

import functools
import inspect
import itertools
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from bayesfric.laws.base import REGISTRY, Constant, Law, LawDeclarationError, Param, declare, declared_in
from bayesfric.laws.plugins import remember
from bayesfric.priors import Prior
from bayesfric.quantities import QUANTITIES, RESPONSES, parse_unit

__all__ = ["simple_law", "default_prior"]

#: Powers of an input's unit tried when a prior's data scaling is read from a parameter's unit.
_POWERS = (0, -1, 1, -2, 2)
_GENERIC = "user law: generic data-scaled prior (bayesfric.laws.simple)"


def simple_law(
    fn: Callable[..., Any] | None = None,
    *,
    units: Mapping[str, str],
    priors: Mapping[str, Prior | Mapping[str, Any]] | None = None,
    response: str = "torque",
    name: str | None = None,
    family: str = "user",
    source: str | None = None,
    meanings: Mapping[str, str] | None = None,
    inputs: tuple[str, ...] | None = None,
    register: bool = True,
    **options: Any,
) -> Law | Callable[[Callable[..., Any]], Law]:
    """Declare a law from a plain function (see the module docstring); usable as a decorator.

    Parameters
    ----------
    fn : callable, optional
        The law's mean function in ``jax.numpy``; without it, a decorator is returned.
    units : mapping
        SI unit (pint syntax) of every parameter; constants default to ``"1"``.
    priors : mapping, optional
        Prior (a :class:`~bayesfric.priors.Prior` or its dict form) by parameter name; the
        others get the default of :func:`default_prior`.
    response : str
        ``"torque"``, ``"force"`` or ``"velocity"``.
    name, family, source, meanings
        Defaults: the function's name, ``"user"``, its file, the parameter names.
    inputs : tuple of str, optional
        The inputs, when arguments named after a quantity should be parameters instead.
    register : bool
        Register the law under its name, as :func:`bayesfric.laws.law` does (listed with the
        package's laws; a name is registered once per process). Unregistered, it is still found
        by its name in this process, and in any process that loads the file declaring it
        (:func:`bayesfric.laws.plugins.unregistered_law`), so studies and fits can use it either way.
    **options
        Further keywords of :func:`bayesfric.laws.base.declare` (``notes``, ``derived``,
        ``sign_definite``, ``rotary_only``, ``constants`` meanings are their names).

    Returns
    -------
    Law
        The declared law (or a decorator that returns it).

    Raises
    ------
    LawDeclarationError
        A parameter without a unit, a prior that cannot be defaulted, or any check of
        :func:`~bayesfric.laws.base.declare`; a name already registered.
    """
    if fn is None:
        return functools.partial(simple_law, units=units, priors=priors, response=response, name=name, family=family,
                                 source=source, meanings=meanings, inputs=inputs, register=register, **options)
    name = name or fn.__name__
    where = f"law {name!r} ({declared_in(fn)})"
    found, params, consts = _read_signature(where, fn, inputs, units, priors or {})
    origin = source or Path(declared_in(fn)).name
    meanings = dict(meanings or {})
    declared = {p: Param(units[p], _prior(where, p, (priors or {}).get(p), units[p], response, found),
                         meanings.get(p, p), origin if p in (priors or {}) else _GENERIC) for p in params}
    constants = {c: Constant(float(v), units.get(c, "1"), meanings.get(c, c)) for c, v in consts.items()}
    wrapped = _positional(fn, [*found, *params, *constants])
    doc = inspect.getdoc(fn) or f"user law {name}"
    law = declare(wrapped, name=name, family=family, inputs=found, response=response, source=origin,
                  params=declared, constants=constants, summary=doc.splitlines()[0], **options)
    if register:
        if name in REGISTRY:
            raise LawDeclarationError(f"{where}: a law named {name!r} is already registered "
                                      f"(in {declared_in(REGISTRY[name].fn)}): a law name is defined once")
        REGISTRY[name] = law
    else:  # found by name in this process, not registered (bayesfric.laws.plugins.unregistered_law)
        remember(law)
    return law


def _read_signature(where: str, fn: Callable[..., Any], inputs: tuple[str, ...] | None, units: Mapping[str, str],
                    priors: Mapping[str, Any]) -> tuple[tuple[str, ...], list[str], dict[str, Any]]:
    """(inputs, parameters, constants with their defaults) of ``fn``, checked against ``units``
    and ``priors``."""
    signature = inspect.signature(fn)
    found = tuple(a for a in signature.parameters if a in QUANTITIES) if inputs is None else tuple(inputs)
    params = [a for a, p in signature.parameters.items() if a not in found and p.default is inspect.Parameter.empty]
    consts = {a: p.default for a, p in signature.parameters.items() if a not in found and a not in params}
    missing = [p for p in params if p not in units]
    if missing:
        raise LawDeclarationError(f"{where}: parameter {missing[0]!r} needs a unit (units={{{missing[0]!r}: ...}})")
    unknown = (set(units) - set(params) - set(consts)) | (set(priors) - set(params))
    if unknown:
        raise LawDeclarationError(f"{where}: {sorted(unknown)[0]!r} is not a parameter of the function "
                                  f"(parameters: {', '.join(params)})")
    bad = [c for c, v in consts.items() if isinstance(v, bool) or not isinstance(v, int | float)]
    if bad:
        raise LawDeclarationError(f"{where}: argument {bad[0]!r} has a default that is not a number: a constant's "
                                  "default is its value")
    return found, params, consts


def default_prior(unit: str, response: str, inputs: tuple[str, ...]) -> Prior | None:
    """The default prior of a parameter with ``unit`` (module docstring); None if there is none.

    Parameters
    ----------
    unit : str
        The parameter's unit.
    response : str
        The law's response quantity.
    inputs : tuple of str
        The law's inputs (quantity names).

    Returns
    -------
    Prior or None
        ``HalfNormal(scale=1)`` scaled by the smallest powers of the response's and the inputs'
        units whose product is ``unit`` (the response's first where two products agree);
        ``LogNormal(0, 1)`` for a dimensionless unit no input explains; None when no such powers
        exist.
    """
    target = parse_unit(unit)
    quantities = [q for q in inputs if q in QUANTITIES]
    combos = itertools.product((0, 1), *[_POWERS] * len(quantities))
    for a, *bs in sorted(combos, key=lambda c: (sum(abs(x) for x in c), -c[0])):  # smallest; the response first
        product = parse_unit(QUANTITIES[response].unit) ** a if a else parse_unit("1")
        for q, b in zip(quantities, bs, strict=True):
            product = product * parse_unit(QUANTITIES[q].unit) ** b if b else product
        if product._units == target._units:
            powers = {"response": a} | {q: b for q, b in zip(quantities, bs, strict=True)}
            powers = {k: float(v) for k, v in powers.items() if v}
            if not powers:
                return Prior("LogNormal", loc=0.0, scale=1.0)
            return Prior("HalfNormal", scale=1.0, scaled_by=powers)
    return None


def _prior(where: str, pname: str, given: Prior | Mapping[str, Any] | None, unit: str, response: str,
           inputs: tuple[str, ...]) -> Prior:
    if isinstance(given, Prior):
        return given
    if given is not None:
        return Prior.from_dict(given)
    if response not in RESPONSES:
        raise LawDeclarationError(f"{where}: response {response!r} not one of {RESPONSES}")
    try:
        found = default_prior(unit, response, inputs)
    except Exception:  # noqa: BLE001 - a unit that does not parse is reported by declare()
        return Prior("HalfNormal", scale=1.0)
    if found is None:
        raise LawDeclarationError(f"{where}: parameter {pname!r}: give a prior (priors={{{pname!r}: ...}}): its unit "
                                  f"{unit!r} is not a product of powers of the response's and the inputs' units")
    return found


def _positional(fn: Callable[..., Any], order: list[str]) -> Callable[..., Any]:
    """``fn`` itself if its arguments come in ``order``; else a wrapper that takes them so."""
    if list(inspect.signature(fn).parameters) == order:
        return fn
    signature = inspect.Signature([inspect.Parameter(n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in order])

    @functools.wraps(fn)
    def in_order(*args, **kwargs):
        return fn(**signature.bind(*args, **kwargs).arguments)

    in_order.__signature__ = signature
    return in_order
