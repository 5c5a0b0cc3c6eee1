"""Declarative schemas for settings tables: a table of :class:`Field` s drives validation, defaults
and error messages.

A :class:`Schema` lists the keys a table may hold. Each :class:`Field` declares its key, its
*kind* (:data:`KINDS`), its default (a value, :data:`REQUIRED`, or a function of the fields
parsed before it), ranges (``min``/``max`` inclusive, ``gt``/``lt`` exclusive), ``choices``, the
condition under which it applies (``only``: another key and its allowed values, e.g. settings
of one sampler), a sub-schema for nested tables, and an optional extra ``rule``. :func:`parse`
checks a raw table against it and returns the table with defaults filled; every problem is a
:class:`SchemaError` carrying the key's location and a one-line problem, which callers format as
``path: [section] key: problem`` (study files) or ``--option: problem`` (the CLI).

>>> parse(Schema((Field("draws", "int", 1000, min=1),)), {"draws": 0})   # doctest: +SKIP
SchemaError: [draws]: must be an integer ≥ 1, got integer 0
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from bayesfric.errors import InternalError, UserError
from bayesfric.fsutil import name_problem
from bayesfric.inference.config import described

__all__ = ["REQUIRED", "KINDS", "Field", "Schema", "SchemaError", "parse", "location"]


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


#: Default of a field that must be given.
REQUIRED: Any = _Required()

#: Kinds of values and how messages describe them.
KINDS = {
    "int": "an integer",
    "number": "a number",
    "bool": "true or false",
    "str": "a non-empty string",
    "text": "a string",
    "name": "a plain name",
    "value": "a string, number or boolean, or a list of them",
    "table": "a table",
    "tables": "an array of tables",
}


class SchemaError(UserError):
    """A value that does not fit its schema: ``where`` (a key path) and a one-line ``problem``."""

    def __init__(self, where: tuple[str | int, ...], problem: str):
        super().__init__(problem, location(where) if where else "")
        self.where = where


@dataclass(frozen=True)
class Field:
    """One key of a table (see the module docstring).

    Parameters
    ----------
    key : str
        The key.
    kind : str
        One of :data:`KINDS`.
    default
        Value when the key is absent: a value (copied), :data:`REQUIRED`, or a callable that
        receives the fields parsed so far (for defaults that depend on another key).
    min, max, gt, lt : float, optional
        Inclusive / exclusive bounds of a number; ``min`` of a ``tables`` field is the least
        number of entries.
    choices : tuple, optional
        Allowed values.
    only : (str, tuple), optional
        The field applies only when the key ``only[0]`` (parsed before it) has one of the values
        ``only[1]``; given otherwise, it is an error.
    items : str, optional
        Kind of every value of a ``table`` field without a schema (free keys).
    schema : Schema, optional
        Schema of a ``table`` field, or of every entry of a ``tables`` field.
    rule : callable, optional
        Extra check of the parsed value; returns the problem or None.
    doc : str
        What the key means (for documentation).
    """

    key: str
    kind: str
    default: Any = None
    min: float | None = None
    max: float | None = None
    gt: float | None = None
    lt: float | None = None
    choices: tuple | None = None
    only: tuple[str, tuple] | None = None
    items: str | None = None
    schema: Schema | None = None
    rule: Callable[[Any], str | None] | None = None
    doc: str = ""

    def __post_init__(self):
        if self.kind not in KINDS or (self.items is not None and self.items not in KINDS):
            raise InternalError(f"field {self.key!r}: unknown kind")

    def describe(self) -> str:
        """What a valid value is, e.g. ``an integer ≥ 1`` or ``one of 'nuts', 'emcee'``."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        text = KINDS[self.kind]
        if self.kind == "tables":
            return text + (f" with at least {_num(self.min)} entry" if self.min else "")
        low = f"≥ {_num(self.min)}" if self.min is not None else f"> {_num(self.gt)}" if self.gt is not None else ""
        high = f"≤ {_num(self.max)}" if self.max is not None else f"< {_num(self.lt)}" if self.lt is not None else ""
        return " ".join(p for p in (text, low, "and" if low and high else "", high) if p)


@dataclass(frozen=True)
class Schema:
    """The keys of a table; ``exactly_one``: groups of keys of which exactly one must be given;
    ``only_label``: how messages name the key that ``Field.only`` refers to (e.g. ``sampler``)."""

    fields: tuple[Field, ...]
    exactly_one: tuple[tuple[str, ...], ...] = ()
    only_label: str = ""

    def keys(self) -> list[str]:
        return [f.key for f in self.fields]


def location(where: tuple[str | int, ...]) -> str:
    """``[section] key`` for keys of tables, ``section.list[i].key`` inside arrays of tables."""
    if not where:
        return ""
    if any(isinstance(p, int) for p in where):
        text = ""
        for p in where:
            text += f"[{p}]" if isinstance(p, int) else (f".{p}" if text else p)
        return text
    head, *rest = where
    return f"[{head}]" + (f" {'.'.join(map(str, rest))}" if rest else "")


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


def _kind_ok(kind: str, value: Any) -> bool:
    scalar = isinstance(value, str | int | float) and not (isinstance(value, float) and not math.isfinite(value))
    return {
        "int": isinstance(value, int) and not isinstance(value, bool),
        "number": isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value),
        "bool": isinstance(value, bool),
        "str": isinstance(value, str) and value.strip() != "",
        "text": isinstance(value, str),
        "name": isinstance(value, str),
        "value": scalar or (isinstance(value, list) and bool(value) and all(
            isinstance(v, str | int | float) and not isinstance(v, dict) for v in value)),
        "table": isinstance(value, Mapping),
        "tables": isinstance(value, list) and all(isinstance(v, Mapping) for v in value),
    }[kind]


def _check(f: Field, value: Any, where: tuple) -> Any:
    """Check one value against its field; return it parsed (defaults of sub-tables filled)."""
    if not _kind_ok(f.kind, value):
        raise SchemaError(where, f"must be {f.describe()}, got {described(value)}")
    if f.kind == "name" and (problem := name_problem(value)):
        raise SchemaError(where, problem)
    if f.kind == "number":
        value = float(value)
    if f.kind in ("int", "number"):
        bad = ((f.min is not None and value < f.min) or (f.max is not None and value > f.max)
               or (f.gt is not None and value <= f.gt) or (f.lt is not None and value >= f.lt))
        if bad:
            raise SchemaError(where, f"must be {f.describe()}, got {described(value)}")
    if f.kind == "tables" and f.min is not None and len(value) < f.min:
        raise SchemaError(where, f"must be {f.describe()}, got {len(value)}")
    if f.choices is not None and value not in f.choices:
        raise SchemaError(where, f"must be {f.describe()}, got {described(value)}")
    if f.kind == "table" and f.schema is not None:
        value = parse(f.schema, value, where)
    elif f.kind == "table" and f.items is not None:
        item = Field("item", f.items)
        value = {k: _check(item, v, where + (k,)) for k, v in value.items()}
    elif f.kind == "tables" and f.schema is not None:
        value = [parse(f.schema, v, where + (i,)) for i, v in enumerate(value)]
    if f.rule is not None and (problem := f.rule(value)):
        raise SchemaError(where, problem)
    return value


def parse(schema: Schema, raw: Mapping[str, Any], where: tuple[str | int, ...] = ()) -> dict[str, Any]:
    """Validate ``raw`` against ``schema``; return it with defaults filled.

    Raises
    ------
    SchemaError
        The first problem found: an unknown key, a key that does not apply, a missing required
        key, a value of the wrong kind or out of range, or a broken ``exactly_one`` group.
    """
    if not isinstance(raw, Mapping):
        raise SchemaError(where, f"must be a table, got {described(raw)}")
    allowed = schema.keys()
    for key in raw:
        if key not in allowed:
            raise SchemaError(where, f"unknown key {key!r} (allowed: {', '.join(allowed)})")
    out: dict[str, Any] = {}
    for f in sorted(schema.fields, key=lambda f: f.only is not None):  # conditions first
        here = where + (f.key,)
        if f.only is not None:
            other, values = f.only
            if out.get(other) not in values:
                if f.key in raw:
                    label = schema.only_label or other
                    raise SchemaError(here, f"applies only to {label} {' or '.join(map(str, values))} "
                                            f"(here {out.get(other)!r})")
                continue
        if f.key in raw:
            out[f.key] = _check(f, raw[f.key], here)
        elif f.default is REQUIRED:
            raise SchemaError(here, f"is required ({f.describe()})")
        elif callable(f.default):
            out[f.key] = f.default(out)
        elif f.kind == "table" and f.schema is not None:
            out[f.key] = parse(f.schema, copy.deepcopy(f.default or {}), here)
        else:
            out[f.key] = copy.deepcopy(f.default)
    for group in schema.exactly_one:
        given = [k for k in group if k in raw]
        if len(given) != 1:
            raise SchemaError(where, f"give exactly one of {' or '.join(map(repr, group))}"
                                     + (f" (got {', '.join(map(repr, given))})" if given else ""))
    return {k: out[k] for k in allowed if k in out}
