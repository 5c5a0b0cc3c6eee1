"""Content fingerprints: what a cached result or a cached compiled program depends on.

The run store (:mod:`bayesfric.study.store`) keys a study's units with them, and the exported
sampler programs (:mod:`bayesfric.exported`) key their files with them: the source of
the computing code and of every module a law's code reads (the module that declares it and the
modules of the package and of the user's law files it imports, transitively:
:mod:`bayesfric.codegraph`), a data set's content, and any
dataclass / array / mapping canonicalised to JSON (:func:`canonical`).
"""

from __future__ import annotations

import ast
import hashlib
import inspect
import json
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from bayesfric.codegraph import roots_of, source_files

__all__ = ["code_fingerprint", "computing_files", "COMPUTING_ROOTS", "package_fingerprint", "law_fingerprint",
           "data_fingerprint", "canonical", "unit_key", "program_parts", "PLACE_ATTRS"]

_PACKAGE = Path(__file__).resolve().parent
#: Where a unit's computation starts: :mod:`bayesfric.study.units` computes every unit (fits,
#: scores, the programs they trace), in a process that built its law from a
#: :mod:`bayesfric.study.spec` entry.
COMPUTING_ROOTS = ("study/units.py", "study/spec.py")
#: Reached from the roots, but run by no unit: the run store (the units import its type alias).
_NOT_COMPUTING = ("study/store.py",)


def _type_checking(test: ast.expr) -> bool:
    """``TYPE_CHECKING`` or ``typing.TYPE_CHECKING`` (without unparsing every ``if``: ~0.5 s)."""
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imported(path: Path, deep: bool) -> set[str]:
    """Dotted names of the bayesfric modules the file imports, at module level or, ``deep``, inside
    a function too (never ``if TYPE_CHECKING:``); ``from a import b`` names ``a`` and ``a.b``.
    Only statements are walked (an import is one), not expressions."""
    names: set[str] = set()

    def walk(body: list[ast.stmt]) -> None:
        for st in body:
            if isinstance(st, ast.Import):
                names.update(a.name for a in st.names)
            elif isinstance(st, ast.ImportFrom) and st.module:
                names.update([st.module, *(f"{st.module}.{a.name}" for a in st.names)])
            elif isinstance(st, ast.FunctionDef | ast.AsyncFunctionDef) and not deep:
                continue
            elif isinstance(st, ast.If) and _type_checking(st.test):
                walk(st.orelse)
                continue
            for field in ("body", "orelse", "finalbody"):
                walk(getattr(st, field, None) or [])
            for inner in (*getattr(st, "handlers", ()), *getattr(st, "cases", ())):
                walk(inner.body)

    walk(ast.parse(path.read_bytes(), str(path)).body)
    return {n for n in names if n == "bayesfric" or n.startswith("bayesfric.")}


def _files_of(name: str, root: Path) -> list[Path]:
    """The files importing module ``name`` runs: its own and its packages' ``__init__.py``."""
    parts = name.split(".")[1:]
    out = [root / "__init__.py"]
    for i in range(1, len(parts) + 1):
        base = root.joinpath(*parts[:i])
        out += [f for f in (base / "__init__.py", base.with_suffix(".py")) if f.is_file()]
    return out


def computing_files(root: Path = _PACKAGE) -> list[str]:
    """The package's files a unit's computation can run (paths relative to ``root``, sorted).

    Every module :data:`COMPUTING_ROOTS` import, transitively (imports inside functions too,
    ``if TYPE_CHECKING:`` ones not, nor those inside ``bayesfric/__init__.py``'s functions: its
    ``__getattr__`` loads the public API on first use, which no unit does), with the
    ``__init__.py`` of each package on the way, less
    :data:`_NOT_COMPUTING` and the law families: a law's own modules enter its units' keys
    through :func:`law_fingerprint` (``laws/base.py``, ``laws/__init__.py`` and
    ``laws/variants.py``, which every law runs through, stay). What no unit imports (the runner,
    a law's result Dataset, the result tree, the report, the API, the command line) is left out:
    editing it changes no unit's number and no traced program.
    """
    todo = [root / r for r in COMPUTING_ROOTS]
    found = set(todo)
    while todo:
        path = todo.pop()
        for name in _imported(path, deep=path != root / "__init__.py"):
            for f in _files_of(name, root):
                if f not in found:
                    found.add(f)
                    todo.append(f)
    rel = {f.relative_to(root).as_posix() for f in found}
    return sorted(r for r in rel if r not in _NOT_COMPUTING and (
        not r.startswith("laws/") or r in ("laws/base.py", "laws/__init__.py", "laws/variants.py")))


@lru_cache(maxsize=4)
def code_fingerprint(root: Path = _PACKAGE) -> str:
    """SHA-256 of the package version and the source of every computing module
    (:func:`computing_files`)."""
    from bayesfric._version import __version__

    digest = hashlib.sha256(str(__version__).encode())
    for rel in computing_files(root):
        digest.update(rel.encode() + b"\0" + (root / rel).read_bytes())
    return digest.hexdigest()


@lru_cache(maxsize=1)
def package_fingerprint() -> str:
    """SHA-256 of every source file and report template of the package (what a report renders with)."""
    from bayesfric._version import __version__

    digest = hashlib.sha256(str(__version__).encode())
    for path in sorted(p for p in _PACKAGE.rglob("*") if p.suffix in (".py", ".j2")):
        digest.update(path.relative_to(_PACKAGE).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def law_fingerprint(law) -> str:
    """SHA-256 of the law's recipe and of the source of every module its code reads.

    For the law and each part of a variant (:mod:`bayesfric.laws.variants`: its base and added
    laws), the module that declares it and every module of the package, of the user's law files
    or of a plug-in package that it imports, transitively (:func:`bayesfric.codegraph.source_files`:
    ``laws/bearing.py`` brings ``laws/ball_loads.py``; a user's law file brings the helper modules
    beside it that it imports). An edit to any of them invalidates the law's units and exported
    programs; modules of other installed packages do not count.
    """
    from bayesfric.laws import get_law
    from bayesfric.laws.variants import term_names

    recipe = dict(getattr(law, "recipe", None) or {})
    parts = [law] + [get_law(name) for name in [recipe.get("base"), *recipe.get("add", ())]
                     if isinstance(name, str) and name not in ("", *term_names())]
    digest = hashlib.sha256(json.dumps(recipe, sort_keys=True, default=str).encode())
    seen: list[Path] = []
    for part in parts:
        module = inspect.getmodule(part.fn) if getattr(part, "fn", None) is not None else None
        files = source_files(module) if module is not None else []
        if not files:
            digest.update((inspect.getsource(module) if module is not None else repr(part)).encode())
            continue
        roots = roots_of(module)
        for path in (f for f in files if f not in seen):
            seen.append(path)
            digest.update(_label(path, roots).encode() + b"\0" + _source(path))
    return digest.hexdigest()


def _source(path: Path) -> bytes:
    """The bytes of a source file that a key covers."""
    return path.read_bytes()


def _label(path: Path, roots: tuple[Path, ...]) -> str:
    """A source file's name relative to its root (a report folder or study may move: keys stay)."""
    for root in sorted(roots, key=lambda r: -len(r.parts)):
        if root == path:
            return path.name
        if root in path.parents:
            return path.relative_to(root).as_posix()
    return path.name


#: Data set attributes that name a place or a display text, not content: a project folder moved
#: or cloned with its reports keeps every unit key (the values and the file's bytes,
#: ``data_hash``, stay in the key).
PLACE_ATTRS = ("title", "csv_file")


def data_fingerprint(ds: xr.Dataset) -> str:
    """SHA-256 of a data set's content: every variable and coordinate (values, dtype, units) and
    the attributes but :data:`PLACE_ATTRS` (where the file lies is no input of a result)."""
    digest = hashlib.sha256()
    for name in sorted(map(str, list(ds.coords) + list(ds.data_vars))):
        var = ds[name]
        values = np.ascontiguousarray(var.values)
        digest.update(json.dumps([name, str(values.dtype), list(values.shape), list(var.dims),
                                  {k: str(v) for k, v in sorted(var.attrs.items())}]).encode())
        digest.update(values.tobytes() if values.dtype != object else repr(values.tolist()).encode())
    digest.update(json.dumps({k: str(v) for k, v in sorted(ds.attrs.items()) if k not in PLACE_ATTRS}).encode())
    return digest.hexdigest()


def canonical(value: Any) -> Any:
    """JSON-able, order-independent form of a key part (dataclasses, arrays, mappings)."""
    if isinstance(value, np.ndarray):
        return {"array": hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest(),
                "shape": list(value.shape), "dtype": str(value.dtype)}
    if isinstance(value, Mapping):
        return {str(k): canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, list | tuple):
        return [canonical(v) for v in value]
    if hasattr(value, "__dataclass_fields__"):
        return {"type": type(value).__name__,
                **{f: canonical(getattr(value, f)) for f in value.__dataclass_fields__}}
    if isinstance(value, float | int | str | bool) or value is None:
        return value
    if isinstance(value, np.generic):
        return value.item()
    return repr(value)


def unit_key(**parts: Any) -> str:
    """Key of a unit: SHA-256 (hex, 32 characters) over its canonicalised ``parts`` and the code."""
    text = json.dumps({"code": code_fingerprint(), **canonical(parts)}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def program_parts(program: Any, response: bool = True) -> dict[str, Any]:
    """What a program's traced functions depend on besides the package source.

    ``program`` is a :class:`bayesfric.model.Program`: its law as declared (every field but the
    functions, whose source :func:`law_fingerprint` covers), the resolved priors, noise model,
    constants, data scale and the data arrays, which are constants of the compiled code.
    ``response=False`` leaves the response values out (keeping their shape) for functions that
    take the response as an argument.
    """
    law = program.law
    declared = {f: getattr(law, f) for f in law.__dataclass_fields__ if f not in ("fn", "derived")}
    return dict(law=declared, law_code=law_fingerprint(law), derived=sorted(law.derived), noise=program.noise,
                resolved=program.resolved, constants=program.constants, scale=program.scale,
                inputs=program.inputs, group_index=program.group_index,
                response=program.response if response else list(np.shape(program.response)),
                chain_start=program.chain_start,
                # a reduced data set's standard errors (constants of the likelihood); absent otherwise,
                # so the keys of programs without them stay as they were
                **({} if getattr(program, "response_se", None) is None else {"response_se": program.response_se}),
                # each vary_by column's levels per row (absent without group terms: other keys unchanged)
                **({"groupings": {c: [list(g.labels), g.index, g.centred] for c, g in program.groupings.items()}}
                   if getattr(program, "groupings", None) else {}))
