"""Variants of declared laws: motion kind, added terms, direction asymmetry, fixed parameters.

A law is declared once (:mod:`bayesfric.laws.base`); everything a study or the data asks of it
beyond that declaration is a *variant*, built here from a small recipe and validated by the same
:func:`bayesfric.laws.base.declare` as a registered law:

``add``
    Additive parts: a term of :data:`TERMS` (``"offset"``: a constant response offset with a
    data-scaled prior; ``"viscous"``: ``c_v · q̇``; the drive terms ``"inertia"``: ``J · q̈``,
    ``M · ẍ`` on force data, and ``"gravity"`` of :mod:`bayesfric.laws.terms`) or any registered
    law with the same response.
    A part's parameter whose name the law already uses is renamed ``<name>_<part>``.
``offset``
    Shorthand for ``add = ["offset"]``.
``asymmetric``
    Direction-dependent coefficients of a steady law that reads ``velocity``: each named
    parameter ``p`` becomes ``p_pos`` (used where velocity ≥ 0) and ``p_neg`` (velocity < 0),
    both with the declared prior. The law is evaluated once with each set and the value of the
    sample's direction is kept, so a derived quantity that reads ``p`` is reported per side too
    (``T_s_pos``, ``T_s_neg``). Trajectory (stateful) laws are refused: their state would mix the
    two parameter sets along a loop.
``fixed``
    Parameters conditioned at a value (SI, in the unit the law shows for the data's motion kind)
    instead of sampled: each becomes a constant of the variant; a constant named here is simply
    overridden. ``fixed`` generalises the study's ``constants``.
``without``
    Optional inputs (:class:`bayesfric.laws.base.OptionalInput`) the data lack: the input is held
    at the declared reference constant and the parameters that then have no effect are fixed at 0.
``vary_by``
    Group terms: ``{column: [parameters]}``. Each named parameter varies between the levels of
    the data column (runs, series, units) with partial pooling (:mod:`bayesfric.hierarchy`); a
    parameter varies by one column; a trajectory (stateful) law, or one with vector parameters,
    by one column at most (it is evaluated once per level). Applied
    last, so it names the parameters as the variant has them (``T_C_pos``, ``offset``).
``trend``, ``trend_form``
    Trends over a service coordinate: ``{column: [parameters]}`` with the column holding one
    number per test campaign (operating hours, cycles); each campaign is a level that scatters
    about a ``linear`` (default), ``loglinear`` or ``walk`` trend (:mod:`bayesfric.trend`). A
    column is a group or a trend column, not both; the one-column rule of ``vary_by`` counts both.
``motion``
    ``"translational"``: the law declared on rotary quantities runs on force data. Inputs map
    ``velocity → linear_velocity``, ``angle → displacement``, the response ``torque → force``;
    parameter units map N·m → N and rad → m (so N·m·s/rad → N·s/m, rad/s → m/s) and a moment of
    inertia ``J`` in kg·m² becomes the mass ``M`` in kg (``fixed`` and ``priors`` may name either),
    and the priors' data scaling follows the renamed inputs. Quantities that do not depend on the motion kind
    (time, preload, temperature) are unchanged. A law that cannot run translationally says why
    (:func:`translation_problem`).

The order of application is fixed: add, asymmetric, fixed, without, motion, vary_by and trend. :func:`for_data`
adds the data-dependent steps (motion, missing optional inputs) to a law's recipe; the recipe is
stored with every fit so the variant can be rebuilt (:func:`law_of_fit`).

The transformations themselves, on law objects, are in :mod:`bayesfric.laws.transforms`; this
module names them in recipes, resolves the parts by name (terms, registered laws), registers
aliases and installs :func:`vary` as the builder of :meth:`Law.fix <bayesfric.laws.base.Law.fix>`,
``.asymmetric`` and ``+``. :class:`VariantError` is declared in :mod:`bayesfric.laws.base`.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from typing import Any

from bayesfric.errors import DataError
from bayesfric.laws import transforms as ops
from bayesfric.laws.base import REGISTRY, Law, LawDeclarationError, VariantError, get_law, set_variant_builder
from bayesfric.laws.plugins import load_recorded
from bayesfric.laws.terms import all_terms
from bayesfric.laws.transforms import TRANSLATIONAL, translation_problem, translational_unit

__all__ = [
    "VariantError", "TERMS", "TRANSLATIONAL", "vary", "build", "for_data", "translation_problem",
    "translational_unit", "law_of_fit", "describe", "alias", "term_names", "variant_name",
]


# -- terms that only make sense as parts (bayesfric.laws.terms) ---------------------------------
#: Additive terms a law entry may ``add`` besides registered laws (built on first use).
TERMS: dict[str, Law] = {}


def term_names() -> tuple[str, ...]:
    """Names of the additive terms (:data:`TERMS`), which are parts of variants, not registered laws."""
    if not TERMS:
        TERMS.update(all_terms())
    return tuple(TERMS)


def _part(name: str) -> Law:
    if name in term_names():
        return TERMS[name]
    try:
        return get_law(name)
    except KeyError:
        raise VariantError(f"{name!r} is not a term ({', '.join(TERMS)}) or a registered law", "add") from None


# -- recipes -------------------------------------------------------------------------------------
_KEYS = ("base", "add", "asymmetric", "fixed", "without", "motion", "vary_by", "trend", "trend_form")
TREND_FORMS = ("linear", "loglinear", "walk")


def build(recipe: Mapping[str, Any], name: str | None = None) -> Law:
    """The law a recipe describes (keys: base, add, asymmetric, fixed, without, motion, vary_by,
    trend, trend_form).

    Raises
    ------
    VariantError
        An unknown part, parameter or input, or a variant the law cannot take.
    KeyError
        The base is not a registered law.
    """
    unknown = set(recipe) - set(_KEYS)
    if unknown:
        raise VariantError(f"unknown variant key(s) {sorted(unknown)}")
    law = get_law(recipe["base"])
    if law.recipe:  # an alias: build from its own recipe, then apply this one on top
        return build(_merge(law.recipe, {k: v for k, v in recipe.items() if k != "base"}), name or law.name)
    for part in recipe.get("add", ()):
        law = ops.add(law, _part(part))
    if recipe.get("asymmetric"):
        law = ops.asymmetric(law, list(recipe["asymmetric"]))
    if recipe.get("fixed"):
        mass = ops.mass_name(law) if recipe.get("motion") == "translational" else {}
        law = ops.fix(law, {("J" if mass and k == "M" else k): v for k, v in recipe["fixed"].items()})
    for input_name in recipe.get("without", ()):
        if input_name not in law.optional:
            raise VariantError(f"law {law.name!r} cannot do without input {input_name!r}")
        law = ops.without(law, input_name)
    if recipe.get("motion", "rotary") == "translational":
        law = ops.translational(law)
    elif recipe.get("motion", "rotary") != "rotary":
        raise VariantError(f"motion {recipe['motion']!r}: not 'rotary' or 'translational'")
    if recipe.get("vary_by") or recipe.get("trend"):
        _check_vary_by(law, recipe.get("vary_by", {}), recipe.get("trend", {}))
    if recipe.get("trend_form", "linear") not in TREND_FORMS or (recipe.get("trend_form") and not recipe.get("trend")):
        raise VariantError(f"trend_form {recipe.get('trend_form')!r}: not one of {', '.join(TREND_FORMS)}, or no "
                           "trend to shape", "trend_form")
    clean = {k: recipe[k] for k in _KEYS if recipe.get(k)}
    return dataclasses.replace(law, name=name or str(recipe["base"]), recipe=clean)


def _check_vary_by(law: Law, vary_by: Mapping[str, Sequence[str]], trend: Mapping[str, Sequence[str]]) -> None:
    """Every group term and trend names scalar, sampled parameters of ``law``, each under one column."""
    seen: dict[str, str] = {}
    for key, table in (("vary_by", vary_by), ("trend", trend)):
        if not isinstance(table, Mapping):
            raise VariantError(f"{key} must map a data column to a list of parameters", key)
        for column, names in table.items():
            _check_group_entry(law, key, column, names, seen)
    columns = set(vary_by) | set(trend)
    if set(vary_by) & set(trend):
        raise VariantError(f"column(s) {sorted(set(vary_by) & set(trend))} both a group and a trend column", "trend")
    per_level = law.trajectory or any(p.shape for p in law.params.values())  # bayesfric.hierarchy.elementwise
    if per_level and len(columns) > 1:
        raise VariantError(f"law {law.name!r} (a trajectory law or one with vector parameters) can vary by one "
                           f"group column, not {len(columns)}", "trend" if trend else "vary_by")


def _check_group_entry(law: Law, key: str, column: Any, names: Any, seen: dict[str, str]) -> None:
    what = "group" if key == "vary_by" else "service-coordinate"
    if not isinstance(column, str) or not column.isidentifier():
        raise VariantError(f"{what} column {column!r} is not a plain name", key)
    if isinstance(names, str) or not names:
        raise VariantError(f"{key}.{column} must be a non-empty list of parameter names", f"{key}.{column}")
    for name in names:
        if name not in law.params:
            raise VariantError(f"law {law.name!r} has no sampled parameter {name!r} to vary by {column!r}; "
                               f"parameters: {', '.join(law.params)}", f"{key}.{column}")
        if law.params[name].shape:
            raise VariantError(f"parameter {name!r} of law {law.name!r} is a vector; only scalar parameters "
                               "can vary between groups", f"{key}.{column}")
        if name in seen:
            raise VariantError(f"parameter {name!r} varies by both {seen[name]!r} and {column!r}",
                               f"{key}.{column}")
        seen[name] = column


def _merge(first: Mapping[str, Any], then: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(first)
    for key in ("add", "asymmetric", "without"):
        out[key] = list(first.get(key, ())) + [v for v in then.get(key, ()) if v not in first.get(key, ())]
    out["fixed"] = dict(first.get("fixed", {})) | dict(then.get("fixed", {}))
    for key in ("vary_by", "trend"):
        groups = {c: list(v) for c, v in first.get(key, {}).items()}
        for column, names in then.get(key, {}).items():
            groups[column] = groups.get(column, []) + [n for n in names if n not in groups.get(column, [])]
        out[key] = groups
    for key in ("motion", "trend_form"):
        if key in then:
            out[key] = then[key]
    return {k: v for k, v in out.items() if v}


def vary(law: Law, *, name: str | None = None, add: Sequence[str] = (), offset: bool = False,
         asymmetric: Sequence[str] = (), fixed: Mapping[str, float] | None = None,
         without: Sequence[str] = (), motion: str | None = None,
         vary_by: Mapping[str, Sequence[str]] | None = None, trend: Mapping[str, Sequence[str]] | None = None,
         trend_form: str | None = None) -> Law:
    """A variant of ``law`` (see the module docstring); ``law`` itself if nothing is asked.

    Parameters
    ----------
    law : Law
        A registered law or a variant (its recipe is extended).
    name : str, optional
        The variant's name (the label of a study entry); default the law's name with every
        modification asked (:func:`variant_name`), so no two different variants share a name.
    add, offset, asymmetric, fixed, without, motion, vary_by, trend, trend_form
        As in the module docstring.
    """
    asked = {"add": list(add) + (["offset"] if offset and "offset" not in add else []),
             "asymmetric": list(asymmetric), "fixed": dict(fixed or {}), "without": list(without),
             "vary_by": {str(c): list(v) for c, v in (vary_by or {}).items()},
             "trend": {str(c): list(v) for c, v in (trend or {}).items()}}
    if motion is not None:
        asked["motion"] = motion
    if trend_form is not None:
        asked["trend_form"] = trend_form
    asked = {k: v for k, v in asked.items() if v}
    if not asked and (name is None or name == law.name):
        return law
    return build(_merge(law.recipe or {"base": law.name}, asked) | {"base": law.recipe.get("base", law.name)},
                 name or variant_name(law.name, asked))


def variant_name(name: str, asked: Mapping[str, Any]) -> str:
    """The default name of the variant of law ``name`` with the modifications ``asked`` (a recipe's
    keys): each one written out, parts added last, so a name shows everything that was changed
    (``.asymmetric("c_v") + "offset"`` is not just ``<law>+offset``).

    ``_asym_<p>...`` direction-dependent parameters, ``_<p>_eq_<value>`` fixed values,
    ``_by_<column>`` group terms, ``_trend_<column>`` trends, ``_without_<input>...``, ``_<motion>``,
    ``+<part>`` each added part. A name that already ends with a group or trend suffix keeps it once.

    Examples
    --------
    >>> variant_name("armstrong_helouvry", {"asymmetric": ["dT_s", "c_v"], "add": ["offset"]})
    'armstrong_helouvry_asym_dT_s_c_v+offset'
    >>> variant_name("stribeck", {"fixed": {"delta": 1.0}})
    'stribeck_delta_eq_1'
    """
    out = name
    if asked.get("asymmetric"):
        out += "_asym_" + "_".join(asked["asymmetric"])
    for key, value in asked.get("fixed", {}).items():
        out += f"_{key}_eq_{format(float(value), 'g').replace('+', '')}"
    for prefix, table in (("_by_", asked.get("vary_by", {})), ("_trend_", asked.get("trend", {}))):
        out += "".join(prefix + str(c) for c in table if not out.endswith(prefix + str(c)))
    if asked.get("without"):
        out += "_without_" + "_".join(asked["without"])
    if asked.get("motion"):
        out += f"_{asked['motion']}"
    return out + "".join(f"+{part}" for part in asked.get("add", ()))


def for_data(law: Law, ds) -> Law:
    """``law`` as it runs on ``ds``: translational for force data, without optional inputs the
    data lack. A law that cannot run on the data's motion kind raises :class:`VariantError`."""
    response = ds.attrs.get("response")
    inputs = {k for k, v in ds.coords.items() if v.attrs.get("role") == "input"}
    motion = None
    if response == "force" and law.response == "torque":
        if problem := translation_problem(law):
            raise DataError(f"law {law.name!r} runs on rotary (torque) data only ({problem}); data set "
                            f"{ds.attrs.get('name', '?')!r} has a force response")
        motion = "translational"
    without = [i for i in law.optional if i not in inputs]
    if motion is None and not without:
        return law
    return vary(law, name=law.name, without=without, motion=motion)  # the same law, run on these data


def alias(name: str, recipe: Mapping[str, Any], notes: str = "") -> Law:
    """Register ``name`` as a thin alias: the variant ``recipe`` of a registered law.

    ``notes`` (e.g. how the alias's source names the parameters) precede the base law's notes.

    Raises
    ------
    LawDeclarationError
        The name is taken, or the recipe is not a valid variant.
    """
    if name in REGISTRY:
        raise LawDeclarationError(f"alias {name!r}: a law named {name!r} is already registered")
    law = build(recipe, name)
    REGISTRY[name] = dataclasses.replace(law, notes=" ".join(filter(None, (notes, law.notes))))
    return REGISTRY[name]


def law_of_fit(attrs: Mapping[str, Any]) -> Law:
    """The law of a stored fit: its recipe if it was a variant, else the registered name. The
    user's law files the fit records are loaded first (:func:`bayesfric.laws.plugins.load_recorded`)."""
    load_recorded(attrs)
    recipe = attrs.get("law_recipe")
    if recipe:
        recipe = json.loads(recipe)
        registered = REGISTRY.get(str(attrs["law"]))
        if registered is not None and registered.recipe == recipe:  # an alias, with its own notes
            return registered
        return build(recipe, str(attrs["law"]))
    return get_law(str(attrs["law"]))


def describe(law: Law) -> str:
    """One line naming how a variant differs from its base law ('' for a registered law)."""
    r = law.recipe
    if not r:
        return ""
    parts = [f"base {r['base']}"]
    if r.get("add"):
        parts.append("+ " + " + ".join(r["add"]))
    if r.get("asymmetric"):
        parts.append("direction-dependent " + ", ".join(r["asymmetric"]) + " (_pos: velocity ≥ 0, _neg: < 0)")
    if r.get("fixed"):
        parts.append("fixed " + ", ".join(f"{k} = {v:g}" for k, v in r["fixed"].items()))
    if r.get("without"):
        parts.append("without input " + ", ".join(r["without"]))
    if r.get("motion") == "translational":
        parts.append("translational")
    for column, names in r.get("vary_by", {}).items():
        parts.append(f"{', '.join(names)} vary by {column} (partial pooling)")
    for column, names in r.get("trend", {}).items():
        parts.append(f"{', '.join(names)} follow a {r.get('trend_form', 'linear')} trend over {column} "
                     "(campaigns partially pooled about it)")
    return "; ".join(parts)


set_variant_builder(vary)  # Law.fix, .asymmetric and + build variants through vary (laws.base cannot import it)
