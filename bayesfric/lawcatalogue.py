"""A stored description of the law registry, so ``bayesfric laws`` answers without JAX.

Declaring the laws imports ``jax.numpy`` (every law module computes with it) and numpyro (every
prior is a numpyro distribution): seconds on a small machine, for a listing that never computes.
``bayesfric/lawcatalogue.json`` therefore holds what ``bayesfric laws`` prints, rendered by the
one renderer (:func:`bayesfric.listing.laws_listing`) once per family and format, with the
laws' names in registry order, and the SHA-256 of every source file the listing depends on (the
module-level import closure of :mod:`bayesfric.laws`, ``listing.py`` and every ``laws/*.py``).
:func:`listing` uses it only while those files hash the same and no installed package declares
laws through the ``bayesfric.laws`` entry points; otherwise the command imports the registry as
before (same text, slower). Regenerate after editing a law::

    python -m bayesfric.lawcatalogue

``tests/test_cli_start.py`` checks that the stored file is current and renders what the
registry renders. Importing this module imports only the standard library.
"""

from __future__ import annotations

import hashlib
import json
import sys
from importlib import metadata
from pathlib import Path

__all__ = ["CATALOGUE", "ENTRY_POINT_GROUP", "listing", "build", "write", "sources_digest"]

_PACKAGE = Path(__file__).resolve().parent
#: The stored catalogue (package data).
CATALOGUE = _PACKAGE / "lawcatalogue.json"
#: Entry-point group of law plug-ins (:data:`bayesfric.laws.plugins.ENTRY_POINT_GROUP`; the same
#: text, kept here so that checking for plug-ins imports no law).
ENTRY_POINT_GROUP = "bayesfric.laws"


def sources_digest(sources: list[str], root: Path = _PACKAGE) -> str | None:
    """SHA-256 over ``sources`` (paths relative to ``root``) and every ``laws/*.py``, each as its
    relative path and bytes; None when a listed file is missing."""
    names = sorted(set(sources) | {p.relative_to(root).as_posix() for p in (root / "laws").glob("*.py")})
    digest = hashlib.sha256()
    for rel in names:
        try:
            digest.update(rel.encode() + b"\0" + (root / rel).read_bytes() + b"\0")
        except OSError:
            return None
    return digest.hexdigest()


def _listing_sources(root: Path = _PACKAGE) -> list[str]:
    """The package files the listing depends on: every module :mod:`bayesfric.laws` imports at
    module level, transitively (with each package's ``__init__.py``), and the renderer
    ``listing.py``."""
    from bayesfric.fingerprint import _files_of, _imported

    todo = [root / "laws" / "__init__.py"]
    found = set(todo)
    while todo:
        for name in _imported(todo.pop(), deep=False):
            for f in _files_of(name, root):
                if f not in found:
                    found.add(f)
                    todo.append(f)
    return sorted({f.relative_to(root).as_posix() for f in found} | {"listing.py"})


def build() -> dict:
    """The catalogue of the registry as this process declares it (imports JAX: slow)."""
    from bayesfric.laws import REGISTRY, all_laws
    from bayesfric.listing import laws_listing

    laws = sorted(REGISTRY.values(), key=lambda w: (w.family, w.name))  # built-in laws only, no plug-ins
    if len(laws) != len(all_laws()):
        raise RuntimeError("entry-point laws are installed: the stored catalogue describes the built-in laws only")
    families = {}
    for family in sorted({w.family for w in laws}):
        members = [w for w in laws if w.family == family]
        families[family] = {"plain": laws_listing(members), "markdown": laws_listing(members, markdown=True)}
    sources = _listing_sources()
    return {"sources": sources, "sources_sha256": sources_digest(sources),
            "names": [[w.name, w.family] for w in laws], "families": families}


def write(path: Path = CATALOGUE) -> Path:
    """Write :func:`build`'s catalogue to ``path`` (JSON, sorted keys, one trailing newline)."""
    path.write_text(json.dumps(build(), indent=1, sort_keys=True, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


def _current(path: Path | None = None) -> dict | None:
    """The stored catalogue (``path``, default :data:`CATALOGUE`) when it still describes this
    package and no plug-in adds laws."""
    try:
        data = json.loads((path or CATALOGUE).read_text(encoding="utf-8"))
        fresh = sources_digest(list(data["sources"])) == data["sources_sha256"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not fresh or any(True for _ in metadata.entry_points(group=ENTRY_POINT_GROUP)):
        return None
    return data


def listing(family: str | None, *, markdown: bool = False, names: bool = False) -> str | None:
    """What ``bayesfric laws`` prints, from the stored catalogue; None when it cannot answer
    (stale, absent, plug-ins installed) and the registry must be imported.

    Raises
    ------
    KeyError
        ``family`` names no family of the catalogue.
    """
    data = _current()
    if data is None:
        return None
    if family is not None and family not in data["families"]:
        raise KeyError(family)
    if names:
        return "\n".join(name for name, fam in data["names"] if family in (None, fam))
    chosen = sorted(data["families"]) if family is None else [family]
    return "\n".join(data["families"][f]["markdown" if markdown else "plain"] for f in chosen)


if __name__ == "__main__":
    print(f"written {write(Path(sys.argv[1]) if len(sys.argv) > 1 else CATALOGUE)}")
