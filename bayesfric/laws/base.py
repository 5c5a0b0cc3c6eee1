"""Declaration machinery for friction laws: a law is stated once, everything else derives from it.

A law is a pure ``jax.numpy`` function whose positional signature is *inputs, then parameters,
then constants* (lmfit-style: the declaration is checked against the signature at import). The
:func:`law` decorator attaches the metadata -- name, family, operating inputs from the fixed
vocabulary in :mod:`bayesfric.quantities`, response, and per parameter its unit, prior, meaning
and literature source -- validates it, and registers the law. The registry, the CLI listing,
the report tables and the generic probabilistic program all read this one declaration.

Example
-------
>>> @law(
...     name="coulomb", family="classical", inputs=("velocity",), response="torque",
...     source="seed 004, Eq. 1",
...     params={"T_C": Param("N*m", Prior("HalfNormal", scale=1.0, scaled_by={"response": 1}),
...                          "Coulomb friction torque", "generic (data-scaled)")},
... )
... def coulomb(velocity, T_C):
...     '''Coulomb friction: T = sign(v) T_C.'''
...     return jnp.sign(velocity) * T_C
"""

from __future__ import annotations

import contextlib
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import jax.numpy as jnp

from bayesfric.laws.errors import LawDeclarationError, VariantError
from bayesfric.priors import Prior
from bayesfric.quantities import DERIVED_POSITIONS, QUANTITIES, RESPONSES, UnitError, parse_unit

__all__ = [
    "Param",
    "SampledAs",
    "Constant",
    "Derived",
    "Law",
    "LawDeclarationError",
    "law",
    "REGISTRY",
    "get_law",
    "TRAJECTORY_START",
    "OptionalInput",
    "declare",
    "register_resolver",
    "declared_in",
    "VariantError",
    "set_variant_builder",
    "Steady",
]

#: Structural input of trajectory (stateful) laws: True at the first sample of each ordered
#: trajectory, where the internal state is reset. Built by the dataset, not measured.
TRAJECTORY_START = "trajectory_start"


@dataclass(frozen=True)
class Param:
    """A sampled parameter of a law.

    Parameters
    ----------
    unit : str
        SI unit in pint syntax (``"N*m"``, ``"N*m*s/rad"``, ``"1"`` for dimensionless).
    prior : Prior
        Default prior (absolute or data-scaled, see :mod:`bayesfric.priors`).
    meaning : str
        Physical meaning, one line.
    source : str
        Literature source of the parameter and of its prior.
    shape : tuple of int
        Shape of a vector-valued parameter (e.g. spline knot increments); ``()`` for a scalar.
    translational : Prior, optional
        Its prior when the law runs on translational data, where the rotary prior's numbers do
        not carry over (a knee angle in rad is no knee displacement in m). Required for a
        parameter whose unit has radians that its prior does not scale by a rotary input
        (:func:`bayesfric.laws.variants.translation_problem`); otherwise the rotary prior is used
        with its data scaling renamed.
    """

    unit: str
    prior: Prior
    meaning: str
    source: str
    shape: tuple[int, ...] = ()
    translational: Prior | None = None
    sampled_as: SampledAs | None = None


@dataclass(frozen=True)
class SampledAs:
    """The coordinate the sampler moves a parameter ``p`` on: the unconstrained scale of ``p / c``
    (``log(p / c)`` for a positive ``p``), ``c = fn(reference, **others) > 0``.

    Why: where the data pin ``p`` only in a combination ``p / c`` with other parameters (LuGre's
    Stribeck curve at the one speed of a drive), that combination becomes a coordinate and a thin,
    curved ridge of the posterior an axis-aligned one. The model is unchanged: ``p`` keeps its
    prior, the posterior is the same; only the sampler's coordinates move
    (:func:`bayesfric.priors.rescaled`).

    Parameters
    ----------
    fn : callable
        ``fn(reference, **others)``: ``reference`` the data scale of ``scaled_by`` (the priors'
        rule, :class:`bayesfric.priors.DataScale`), ``others`` parameters or constants of the law
        by name. A law without one of them (a variant that split or renamed it), or a ``p`` that
        varies between groups, is sampled on its own scale.
    scaled_by : mapping
        Powers of the data scales that make ``reference``, as a prior's ``scaled_by``.
    meaning : str
        What ``p / c`` is, one line.
    """

    fn: Callable[..., Any]
    scaled_by: Mapping[str, float]
    meaning: str

    @property
    def reads(self) -> tuple[str, ...]:
        """The parameters or constants ``fn`` reads (its arguments after ``reference``)."""
        return tuple(p for p in inspect.signature(self.fn).parameters if p != "reference")


@dataclass(frozen=True)
class Constant:
    """A fixed, non-sampled setting of a law (geometry, a fixed exponent); overridable per study."""

    value: float
    unit: str
    meaning: str


@dataclass(frozen=True)
class Derived:
    """A quantity computed from the parameters and reported with the posterior (e.g. T_s = T_C + ΔT)."""

    fn: Callable[..., Any]
    unit: str
    meaning: str


@dataclass(frozen=True)
class OptionalInput:
    """An input the law can do without: a dependence that data which do not vary it cannot inform.

    When the data lack the input, it is held at the law's constant ``fill`` (so the law's factor
    for it is 1 when the law is written relative to that reference), and the parameters named in
    ``drops`` -- which then have no effect -- are fixed at 0 instead of sampled
    (:func:`bayesfric.laws.variants.for_data`).
    """

    fill: str
    drops: tuple[str, ...] = ()


@dataclass(frozen=True)
class Steady:
    """A trajectory law's friction at constant speed, derived from its own equations.

    ``fn``'s signature is *steady inputs, then the law's parameters, then its constants* (the same
    names): the steady inputs are what the friction reads once the transient has settled (the
    velocity, for its direction and Stribeck curve; a preload, a normal force). ``response``: the
    quantity it returns ("" : the law's own; a coast-down, which predicts speed, gives ``"torque"``).
    :func:`bayesfric.laws.steady.steady_state` builds the elementwise law sizing evaluates from it.

    Examples
    --------
    >>> Steady(lambda velocity, T_C: T_C * jnp.sign(velocity)).response
    ''
    """

    fn: Callable[..., Any]
    response: str = ""
    sign_definite: bool = True
    inputs: tuple[str, ...] = ()  # filled by declare from fn's signature


@dataclass(frozen=True)
class Law:
    """A declared friction law. Call it like its function; use :meth:`mean` with mappings."""

    name: str
    family: str
    inputs: tuple[str, ...]
    response: str
    params: Mapping[str, Param]
    fn: Callable[..., Any]
    source: str
    summary: str
    constants: Mapping[str, Constant] = field(default_factory=dict)
    derived: Mapping[str, Derived] = field(default_factory=dict)
    trajectory: bool = False
    notes: str = ""
    sign_definite: bool = True
    #: Why the law runs on rotary data only ("" : it also runs on translational data, see
    #: :mod:`bayesfric.laws.variants`).
    rotary_only: str = ""
    optional: Mapping[str, OptionalInput] = field(default_factory=dict)
    #: How a variant was made from a registered law (:mod:`bayesfric.laws.variants`); empty for a
    #: law declared by its own function.
    recipe: Mapping[str, Any] = field(default_factory=dict)
    #: A trajectory law's friction at constant speed (:class:`Steady`); None if it declares none.
    steady: Steady | None = None
    #: The trajectory law whose steady state this law is (:mod:`bayesfric.laws.steady`); "" for a
    #: law in its own right. Its priors are that law's, scaled by that law's data.
    steady_of: str = ""

    def __call__(self, *args, **kwargs):
        return self.fn(*args, **kwargs)

    @property
    def operating_inputs(self) -> tuple[str, ...]:
        """Inputs that are physical operating quantities (excludes ``trajectory_start``)."""
        return tuple(i for i in self.inputs if i != TRAJECTORY_START)

    def mean(
        self,
        inputs: Mapping[str, Any],
        params: Mapping[str, Any],
        constants: Mapping[str, float] | None = None,
    ):
        """Evaluate the law: ``inputs`` and ``params`` by name, constants default to declared."""
        consts = {k: c.value for k, c in self.constants.items()}
        if constants:
            unknown = set(constants) - set(consts)
            if unknown:
                raise KeyError(f"law {self.name!r} has no constant(s) {sorted(unknown)}")
            consts.update(constants)
        args = [inputs[k] for k in self.inputs] + [params[k] for k in self.params]
        return self.fn(*args, **consts)

    def derived_values(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """Evaluate every derived quantity from a parameter mapping."""
        return {k: d.fn(**{p: params[p] for p in inspect.signature(d.fn).parameters})
                for k, d in self.derived.items()}

    @property
    def base_name(self) -> str:
        """The registered law this one was made from (its own name if it is not a variant)."""
        return str(self.recipe.get("base", self.name))

    def default_priors(self) -> dict[str, Prior]:
        return {k: p.prior for k, p in self.params.items()}

    # composition: variants (bayesfric.laws.variants) of laws found by name, as objects
    def fix(self, **values: float) -> Law:
        """This law with parameters held at ``values`` (SI) instead of sampled, e.g. ``.fix(delta=1)``,
        named after them (``stribeck_delta_eq_1``: :func:`bayesfric.laws.variants.variant_name`)."""
        return self._vary(fixed=values)

    def asymmetric(self, *names: str) -> Law:
        """This law with one value of each named parameter per direction of motion (``T_C_pos``,
        ``T_C_neg``), named after them (``coulomb_asym_T_C``)."""
        return self._vary(asymmetric=names)

    def vary_by(self, group: str, *names: str) -> Law:
        """This law with the named parameters varying between the levels of the data column ``group``
        (a run, series or unit), partially pooled: ``law.vary_by("run", "T_C", "c_v")``.

        Each named parameter keeps its prior as the prior of its *typical* value (the median over
        groups); each level's value scatters about it on the parameter's unconstrained scale (log
        for a positive parameter) with a between-group spread ``<p>_sd`` of its own prior
        (:mod:`bayesfric.hierarchy`). Predictions then answer for a new level by default. The
        variant is named ``<law>_by_<group>``.

        Examples
        --------
        >>> from bayesfric.laws import get_law
        >>> get_law("coulomb_viscous").vary_by("run", "T_C").varying
        {'T_C': 'run'}
        """
        name = self.name if self.name.endswith(f"_by_{group}") else f"{self.name}_by_{group}"
        return self._vary(vary_by={group: list(names)}, name=name)

    def trend(self, coordinate: str, *names: str, form: str = "linear") -> Law:
        """This law with the named parameters following a trend over a service coordinate (the
        operating hours, cycles or date of each test campaign), partially pooled about it:
        ``law.trend("hours", "T_C", form="linear")``.

        The data column ``coordinate`` holds one number per campaign; each campaign is a level whose
        values scatter about the trend as :meth:`vary_by`'s levels scatter about the typical value.
        ``form``: ``"linear"`` (the parameter grows by a fixed amount per unit of service),
        ``"loglinear"`` (by a fixed factor) or ``"walk"`` (a random walk: no trend shape assumed)
        (:mod:`bayesfric.trend`). Forecasts answer for a new campaign at a later service time. The
        variant is named ``<law>_trend_<coordinate>``.

        Examples
        --------
        >>> from bayesfric.laws import get_law
        >>> get_law("coulomb_viscous").trend("hours", "T_C").trending
        {'T_C': 'hours'}
        """
        name = self.name if self.name.endswith(f"_trend_{coordinate}") else f"{self.name}_trend_{coordinate}"
        return self._vary(trend={coordinate: list(names)}, trend_form=form, name=name)

    @property
    def varying(self) -> dict[str, str]:
        """Parameter -> the data column whose levels it varies between (:meth:`vary_by`, and the
        service coordinate of a :meth:`trend`); empty if none."""
        return {p: col for key in ("vary_by", "trend") for col, names in self.recipe.get(key, {}).items()
                for p in names}

    @property
    def trending(self) -> dict[str, str]:
        """Parameter -> the service coordinate it follows a trend over (:meth:`trend`); empty if none."""
        return {p: col for col, names in self.recipe.get("trend", {}).items() for p in names}

    @property
    def trend_form(self) -> str:
        """The form of the law's trends: ``linear``, ``loglinear`` or ``walk`` (:mod:`bayesfric.trend`)."""
        return str(self.recipe.get("trend_form", "linear"))

    def __add__(self, other: Law | str) -> Law:
        """This law plus another law or a term (``"offset"``, ``"viscous"``), named ``a+b``."""
        part = other if isinstance(other, str) else other.name
        if isinstance(other, Law):
            _check_found(other, "add")
        return self._vary(add=[part], name=f"{self.name}+{part}")

    def _vary(self, **options: Any) -> Law:
        if not self.recipe:
            _check_found(self, next(iter(options)))
        return _VARIANT_BUILDER[0](self, **options)


def _check_found(law: Law, key: str) -> None:
    """A variant is a recipe over names: ``law`` must be the law its name finds in this process
    (registered, or declared without registering: :func:`bayesfric.laws.plugins.unregistered_law`),
    else the variant would be built, here or in a worker, from another law of that name."""
    try:
        found = get_law(law.name)
    except KeyError:
        found = None
    if found is not law:
        raise VariantError(f"law {law.name!r} is not the law its name finds in this process (another law of "
                           "that name was declared later, or it was not declared with law(), simple_law() or "
                           "bayesfric.law()): declare it again to build variants of it", key)


REGISTRY: dict[str, Law] = {}
#: Functions name -> Law | None that declare a parametrised law on first use (e.g. ``gms_n6``).
_RESOLVERS: list[Callable[[str], Law | None]] = []


#: What builds :meth:`Law.fix`, ``.asymmetric`` and ``+``: :func:`bayesfric.laws.variants.vary`, installed by
#: that module, which builds on this one; the package's ``__init__`` (run before any of its modules) imports it.
_VARIANT_BUILDER: list[Callable[..., Law]] = []


def set_variant_builder(vary: Callable[..., Law]) -> None:
    """Install the function that builds a law's variants (:func:`bayesfric.laws.variants.vary`)."""
    _VARIANT_BUILDER[:] = [vary]


def register_resolver(resolve: Callable[[str], Law | None]) -> None:
    """Let ``resolve(name)`` declare laws of a family whose size is chosen by name (``gms_n6``)."""
    _RESOLVERS.append(resolve)


def get_law(name: str) -> Law:
    """Look up a registered law by name (or declare it through a resolver); a clear error lists
    the known names. The package's ``__init__`` registered every family and, as the last resolver,
    :func:`bayesfric.laws.plugins.entry_point_law` (installed packages' laws)."""
    try:
        return REGISTRY[name]
    except KeyError:
        for resolve in _RESOLVERS:
            if (found := resolve(name)) is not None:
                return found
        raise KeyError(f"unknown law {name!r}; known laws: {', '.join(sorted(REGISTRY))}") from None


def law(
    *,
    name: str,
    family: str,
    inputs: tuple[str, ...],
    response: str,
    source: str,
    params: Mapping[str, Param],
    constants: Mapping[str, Constant] | None = None,
    derived: Mapping[str, Derived] | None = None,
    trajectory: bool = False,
    notes: str = "",
    sign_definite: bool = True,
    rotary_only: str = "",
    optional: Mapping[str, OptionalInput] | None = None,
    steady: Steady | Callable[..., Any] | None = None,
) -> Callable[[Callable[..., Any]], Law]:
    """Declare and register a friction law (see the module docstring).

    ``sign_definite=False`` marks purely empirical curve fits (e.g. polynomial surfaces) whose
    prior admits friction of the wrong sign; the prior-predictive checks then report the
    fraction of implausible draws instead of requiring none. ``notes`` holds identifiability
    remarks the report prints. A law declared on rotary quantities (torque, ``velocity``,
    ``angle``) also runs on translational data (force, ``linear_velocity``, ``displacement``)
    unless ``rotary_only`` says why it cannot (:mod:`bayesfric.laws.variants`). ``optional``
    names inputs the law can do without (:class:`OptionalInput`). ``steady`` (a trajectory law's
    :class:`Steady`, or its function) gives the law's friction at constant speed, which sizing
    answers from (:func:`bayesfric.laws.steady.steady_state`).

    Raises
    ------
    LawDeclarationError
        At import, if the function signature is not ``inputs + params + constants`` in that
        order, an input or the response is not in the vocabulary, a unit does not parse, a
        parameter lacks a meaning or source, or the name is already registered.
    """

    def wrap(fn: Callable[..., Any]) -> Law:
        if name in REGISTRY:
            raise LawDeclarationError(f"law {name!r} ({declared_in(fn)}): a law named {name!r} is already registered "
                                      f"(in {declared_in(REGISTRY[name].fn)}): a law name is defined once")
        declared = declare(fn, name=name, family=family, inputs=inputs, response=response, source=source,
                           params=params, constants=constants, derived=derived, trajectory=trajectory,
                           notes=notes, sign_definite=sign_definite, rotary_only=rotary_only,
                           optional=optional, steady=steady)
        REGISTRY[name] = declared
        return declared

    return wrap


def _check_param(where: str, pname: str, p: Param, inputs: tuple[str, ...]) -> None:
    """A declared parameter: a :class:`Param` with a unit, meaning, source and a prior scaled
    only by what the law reads (or by a position it integrates from the speed and time it reads,
    :data:`bayesfric.quantities.DERIVED_POSITIONS`)."""
    if not isinstance(p, Param):
        raise LawDeclarationError(f"{where}: parameter {pname!r} is not a Param")
    _check_unit(where, pname, p.unit)
    if not p.meaning.strip() or not p.source.strip():
        raise LawDeclarationError(f"{where}: parameter {pname!r} needs a meaning and a source")
    if not isinstance(p.prior, Prior):
        raise LawDeclarationError(f"{where}: parameter {pname!r} prior is not a Prior spec")
    for key in p.prior.scaled_by:
        derived = key in DERIVED_POSITIONS and {DERIVED_POSITIONS[key], "time"} <= set(inputs)
        if key != "response" and key not in inputs and not derived:
            raise LawDeclarationError(
                f"{where}: prior of {pname!r} is scaled by {key!r}, which the law does not read"
            )


def declare(
    fn: Callable[..., Any],
    *,
    name: str,
    family: str,
    inputs: tuple[str, ...],
    response: str,
    source: str,
    params: Mapping[str, Param],
    constants: Mapping[str, Constant] | None = None,
    derived: Mapping[str, Derived] | None = None,
    trajectory: bool = False,
    notes: str = "",
    sign_definite: bool = True,
    rotary_only: str = "",
    optional: Mapping[str, OptionalInput] | None = None,
    recipe: Mapping[str, Any] | None = None,
    summary: str | None = None,
    steady: Steady | Callable[..., Any] | None = None,
    steady_of: str = "",
) -> Law:
    """Validate a declaration and build its :class:`Law` without registering it (see :func:`law`).

    Variants (:mod:`bayesfric.laws.variants`) are built here, so they pass the same checks.
    ``summary`` stands in for a docstring (:mod:`bayesfric.laws.simple`).
    """
    where = f"law {name!r} ({fn.__module__}.{fn.__qualname__})"
    consts = dict(constants or {})
    sig = list(inspect.signature(fn).parameters)
    expected = list(inputs) + list(params) + list(consts)
    if sig != expected:
        raise LawDeclarationError(
            f"{where}: function signature {sig} does not match the declaration "
            f"(inputs + params + constants = {expected})"
        )
    _check_inputs(where, inputs, response, trajectory)
    for pname, p in params.items():
        # a steady-state law keeps its trajectory law's priors, scaled by that law's data
        _check_param(where, pname, p, inputs if not steady_of else (*inputs, *p.prior.scaled_by))
    for cname, c in consts.items():
        _check_unit(where, cname, c.unit)
    for dname, d in (derived or {}).items():
        _check_unit(where, dname, d.unit)
        missing = set(inspect.signature(d.fn).parameters) - set(params)
        if missing:
            raise LawDeclarationError(f"{where}: derived {dname!r} reads unknown {sorted(missing)}")
    for iname, opt in (optional or {}).items():
        if iname not in inputs or opt.fill not in consts or not set(opt.drops) <= set(params) | set(consts):
            raise LawDeclarationError(f"{where}: optional input {iname!r} must be an input, its fill a "
                                      "constant and its drops parameters or constants of the law")
    doc = summary or inspect.getdoc(fn) or ""
    if not doc:
        raise LawDeclarationError(f"{where}: needs a docstring (its first line is the summary)")
    return Law(
        name=name, family=family, inputs=tuple(inputs), response=response, params=dict(params), fn=fn,
        source=source, summary=doc.splitlines()[0], constants=consts, derived=dict(derived or {}),
        trajectory=trajectory, notes=notes, sign_definite=sign_definite, rotary_only=rotary_only,
        optional=dict(optional or {}), recipe=dict(recipe or {}),
        steady=_check_steady(where, steady, trajectory, list(params) + list(consts), response, optional or {}),
        steady_of=steady_of,
    )


def _check_steady(where: str, steady: Steady | Callable[..., Any] | None, trajectory: bool, names: list[str],
                  response: str, optional: Mapping[str, OptionalInput]) -> Steady | None:
    """A trajectory law's :class:`Steady`, its inputs read from its function's signature: steady
    inputs from the vocabulary, then the law's parameters and constants; it reads every optional
    input of the law (so :func:`bayesfric.laws.transforms.without` applies to it as to the law)."""
    if steady is None:
        return None
    steady = steady if isinstance(steady, Steady) else Steady(steady)
    if not trajectory:
        raise LawDeclarationError(f"{where}: a steady state is declared by a trajectory law only")
    sig = list(inspect.signature(steady.fn).parameters)
    inputs = tuple(sig[:len(sig) - len(names)])
    if sig[len(inputs):] != names or any(i not in QUANTITIES for i in inputs):
        raise LawDeclarationError(f"{where}: steady-state signature {sig} is not steady inputs (from the "
                                  f"vocabulary) + the law's parameters and constants {names}")
    if not set(optional) <= set(inputs) or (steady.response or response) not in RESPONSES:
        raise LawDeclarationError(f"{where}: the steady state must read every optional input "
                                  f"({', '.join(optional)}) and return a response of {RESPONSES}")
    return Steady(steady.fn, steady.response or response, steady.sign_definite, inputs)


def declared_in(fn: Callable[..., Any]) -> str:
    """Where the function ``fn`` is written: its source file, else its module and name."""
    with contextlib.suppress(TypeError):
        if found := inspect.getsourcefile(fn):
            return found
    return f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', '?')}"


def _check_inputs(where: str, inputs: tuple[str, ...], response: str, trajectory: bool) -> None:
    for i in inputs:
        if i == TRAJECTORY_START:
            if not trajectory:
                raise LawDeclarationError(f"{where}: {TRAJECTORY_START} needs trajectory=True")
            continue
        if i not in QUANTITIES:
            raise LawDeclarationError(
                f"{where}: unknown input {i!r}; the vocabulary is {', '.join(QUANTITIES)}"
            )
    if trajectory and TRAJECTORY_START not in inputs:
        raise LawDeclarationError(f"{where}: trajectory laws must read {TRAJECTORY_START}")
    if response not in RESPONSES:
        raise LawDeclarationError(f"{where}: response {response!r} not one of {RESPONSES}")


def _check_unit(where: str, what: str, unit: str) -> None:
    if not unit or not unit.strip():
        raise LawDeclarationError(f"{where}: {what!r} has no unit (use '1' for dimensionless)")
    try:
        parse_unit(unit)
    except UnitError as exc:
        raise LawDeclarationError(f"{where}: {what!r} unit: {exc}") from None


def smooth_sign(x, eps: float = 0.0):
    """``sign(x)``; with ``eps > 0`` the smooth ``tanh(x/eps)`` (used only where a law says so)."""
    if eps > 0:
        return jnp.tanh(x / eps)
    return jnp.sign(x)
