"""Content fingerprints: what a cached result or a cached compiled program depends on.

The run store (:mod:`bayesfric.study.store`) keys a study's units with them, and the exported
sampler programs (:mod:`bayesfric.exported`) key their files with them: the source of
the computing code and of every module a law's code reads (the module that declares it and the
modules of the package and of the user's law files it imports, transitively:
:mod:`bayesfric.codegraph`), a data set's content, and any
dataclass / array / mapping canonicalised to JSON (:func:`canonical`).
"""

from __future__ import annotations

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

__all__ = ["code_fingerprint", "package_fingerprint", "law_fingerprint", "data_fingerprint", "canonical",
           "unit_key", "program_parts"]

_PACKAGE = Path(__file__).resolve().parent
#: Parts of the package that only render, parse options or assemble the units' results into the
#: result tree (``study/tree.py``): their edits do not change any unit's number or compiled program.
_NOT_COMPUTING = ("report", "cli.py", "__main__.py", "study/executor.py", "study/store.py", "study/mainjob.py",
                  "study/tree.py")


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 of the package version and the source of every computing module (not laws/)."""
    from bayesfric._version import __version__

    digest = hashlib.sha256(str(__version__).encode())
    for path in sorted(_PACKAGE.rglob("*.py")):
        rel = path.relative_to(_PACKAGE).as_posix()
        if rel.startswith(_NOT_COMPUTING) or (rel.startswith("laws/") and rel not in (
                "laws/base.py", "laws/__init__.py", "laws/variants.py")):
            continue
        digest.update(rel.encode() + b"\0" + path.read_bytes())
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


def data_fingerprint(ds: xr.Dataset) -> str:
    """SHA-256 of a data set's content: every variable and coordinate (values, dtype, units)."""
    digest = hashlib.sha256()
    for name in sorted(map(str, list(ds.coords) + list(ds.data_vars))):
        var = ds[name]
        values = np.ascontiguousarray(var.values)
        digest.update(json.dumps([name, str(values.dtype), list(values.shape), list(var.dims),
                                  {k: str(v) for k, v in sorted(var.attrs.items())}]).encode())
        digest.update(values.tobytes() if values.dtype != object else repr(values.tolist()).encode())
    digest.update(json.dumps({k: str(v) for k, v in sorted(ds.attrs.items()) if k != "title"}).encode())
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
                **({} if getattr(program, "response_se", None) is None else {"response_se": program.response_se}))
