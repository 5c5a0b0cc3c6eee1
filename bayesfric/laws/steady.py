"""Steady state of trajectory (stateful) laws: the friction at constant speed once the transient
has settled, derived from each law's own equations.

A trajectory law declares it with ``steady=`` (:class:`bayesfric.laws.base.Steady`): LuGre's
``(P/P_ref)^γ g(v) sgn v + σ2 v`` (ż = 0), Dahl's ``F_c sgn v``, elasto-plastic's and GMS's
Stribeck curve ``s(v) sgn v + σ2 v``, Maxwell-slip's ``Σ α_i F_c sgn v`` (every element at its
break-away torque), and every coast-down law's friction law ``T_f(ω)``, the torque that would
hold the speed constant (its response is then torque, where the coast-down predicts speed).
:func:`steady_state` turns it into an elementwise :class:`~bayesfric.laws.base.Law` with the
trajectory law's parameters, priors and constants, so a fit's posterior draws evaluate it as
they are; sizing answers a stateful law's question from it (:mod:`bayesfric.sizing.compute`).

A variant's steady state is its recipe replayed on the base law's steady state (an added law
by its own steady state; fixed parameters, the optional inputs the data lack, the motion kind),
keeping the recipe, so group terms (``vary_by``) still name their parameters (``.varying``) and
sizing answers for a new level as it does for a steady law.
"""

from __future__ import annotations

import dataclasses

from bayesfric.laws import transforms as ops
from bayesfric.laws.base import Law, LawDeclarationError, declare, get_law
from bayesfric.laws.variants import TERMS, term_names

__all__ = ["STEADY_NOTE", "steady_state"]

#: What a steady-state answer is, said wherever one is printed or stored.
STEADY_NOTE = ("steady state at constant speed: the friction a drive must overcome once the transient has "
               "settled; start-up and reversal transients are not included")


def steady_state(law: Law) -> Law | None:
    """The elementwise law of ``law``'s friction at constant speed, or None if it declares none.

    A law that is not a trajectory law is its own steady state (returned as is). For a trajectory
    law the result has the same parameter names, priors and constants; its inputs are the steady
    operating inputs (the velocity, and e.g. the preload it reads at steady state) and its
    response the friction (torque or force; a coast-down's friction torque).

    Parameters
    ----------
    law : Law
        A registered law or a variant of one (its recipe is replayed on its base's steady state).

    Returns
    -------
    Law or None
        Named ``<law>_steady``, with ``steady_of`` the law's name; None when the law, its base or
        a law it adds declares no steady state.

    Raises
    ------
    LawDeclarationError
        The steady state came out with other parameters or constants than the law's.

    Examples
    --------
    >>> from bayesfric.laws import get_law
    >>> lugre = steady_state(get_law("lugre"))
    >>> lugre.inputs, lugre.trajectory
    (('velocity', 'preload'), False)
    >>> steady_state(get_law("dahl").vary_by("run", "F_c0")).varying
    {'F_c0': 'run'}
    >>> steady_state(get_law("coastdown_coulomb_viscous_closed_form")).response
    'torque'
    """
    if not law.trajectory:
        return law
    if not law.recipe:
        return _declared(law)
    steady = _replayed(law)
    if steady is None:
        return None
    if set(steady.params) != set(law.params) or set(steady.constants) != set(law.constants):
        raise LawDeclarationError(f"law {law.name!r}: its steady state has parameters {sorted(steady.params)} and "
                                  f"constants {sorted(steady.constants)}, not the law's")
    return dataclasses.replace(steady, name=f"{law.name}_steady", recipe=dict(law.recipe), steady_of=law.name)


def _declared(law: Law) -> Law | None:
    """The steady law of a law declared with ``steady=`` (None without)."""
    s = law.steady
    if s is None:
        return None
    return declare(s.fn, name=f"{law.name}_steady", family=law.family, inputs=s.inputs, response=s.response,
                   source=law.source, params=law.params, constants=law.constants, derived=law.derived,
                   notes=f"{STEADY_NOTE}. {law.notes}".strip(), sign_definite=s.sign_definite,
                   rotary_only=law.rotary_only, optional=law.optional,
                   summary=f"Steady state at constant speed of {law.name}: {law.summary}", steady_of=law.name)


def _part(name: str) -> Law | None:
    """The steady state of a part a recipe adds (a term or a law)."""
    return steady_state(TERMS[name] if name in term_names() else get_law(name))


def _replayed(law: Law) -> Law | None:
    """``law``'s recipe (:mod:`bayesfric.laws.variants`, in its order) applied to its base's steady state."""
    recipe = law.recipe
    base = steady_state(get_law(recipe["base"]))
    if base is None:
        return None
    steady = dataclasses.replace(base, steady_of=law.name)  # its priors stay the trajectory law's
    for name in recipe.get("add", ()):
        if (part := _part(name)) is None:
            return None
        steady = ops.add(steady, part)
    if recipe.get("asymmetric"):
        steady = ops.asymmetric(steady, list(recipe["asymmetric"]))
    if recipe.get("fixed"):
        mass = ops.mass_name(steady) if recipe.get("motion") == "translational" else {}
        steady = ops.fix(steady, {("J" if mass and k == "M" else k): v for k, v in recipe["fixed"].items()})
    for name in recipe.get("without", ()):
        steady = ops.without(steady, name)
    if recipe.get("motion", "rotary") == "translational":
        steady = ops.translational(steady)
    return steady
