"""Which source files a law's code reads: its module and, transitively, the modules it imports.

:func:`source_files` walks the ``import`` statements (read with :mod:`ast`, nothing imported)
from the module that declares a law and keeps every module that is *ours*: a module of the
bayesfric package, or of the user's code, i.e. the folder of a law file loaded by path (or of a
script), or the top-level package of an installed plug-in. Modules of other installed packages
(site-packages) and the standard library are left out: their versions are not part of a key.

Within the bayesfric package only module-level imports are followed (imports inside functions
there break import cycles or defer the registry and the CLI, and are not law code: following
``bayesfric.laws.base.get_law``'s import of the whole registry would tie every law to every
family module); in the user's and plug-ins' files every import is followed, those inside
functions too. ``if TYPE_CHECKING:`` imports are never followed. ``from package import name``
follows the module that defines ``name`` (a re-export in ``__init__`` leads to its source).

Example: ``bayesfric/laws/bearing.py`` imports ``bayesfric.laws.ball_loads``, so
:func:`bayesfric.fingerprint.law_fingerprint` of the pitch-bearing laws covers ``ball_loads.py``.
"""

from __future__ import annotations

import ast
import importlib.util
import sys
import sysconfig
import types
from functools import lru_cache
from pathlib import Path

__all__ = ["source_files", "roots_of"]

PACKAGE = Path(__file__).resolve().parent
#: Folders whose modules are never the user's: the standard library and site-packages.
_FOREIGN = tuple(Path(p).resolve() for key in ("stdlib", "platstdlib", "purelib", "platlib")
                 if (p := sysconfig.get_paths().get(key)))


def source_files(module: types.ModuleType) -> list[Path]:
    """The source file of ``module`` and of every module of ours it imports, transitively.

    Parameters
    ----------
    module : module
        The module that declares a law (``inspect.getmodule(law.fn)``).

    Returns
    -------
    list of Path
        Resolved paths, the module's own first, then in the order they were found.
    """
    start = _file_of(module)
    if start is None:
        return []
    roots = roots_of(module)
    found, todo = [start], [start]
    while todo:
        path = todo.pop(0)
        for name, level, attrs in _imports(path, *_stat(path), deep=not _inside(path, (PACKAGE,))):
            for target in _targets(path, name, level, attrs):
                if target not in found and _inside(target, roots):
                    found.append(target)
                    todo.append(target)
    return found


def roots_of(module: types.ModuleType) -> tuple[Path, ...]:
    """Folders whose modules count as ours for a law declared in ``module`` (module docstring)."""
    path = _file_of(module)
    if path is None or _inside(path, (PACKAGE,)):
        return (PACKAGE,)
    top = sys.modules.get(module.__name__.split(".")[0])
    top_file = _file_of(top) if top is not None else None
    if top is not None and hasattr(top, "__path__") and top_file is not None:
        return PACKAGE, top_file.parent  # an installed or local package: all of it
    if _inside(path, _FOREIGN):
        return PACKAGE, path  # a lone module in site-packages: itself only
    return PACKAGE, path.parent  # a law file or script: its folder


def _file_of(module: types.ModuleType | None) -> Path | None:
    name = getattr(module, "__file__", None)
    return Path(name).resolve() if name and name.endswith(".py") else None


def _inside(path: Path, roots: tuple[Path, ...]) -> bool:
    return any(path == r or r in path.parents for r in roots)


def _stat(path: Path) -> tuple[int, int]:
    st = path.stat()
    return st.st_mtime_ns, st.st_size


@lru_cache(maxsize=1024)
def _imports(path: Path, mtime: int, size: int, deep: bool) -> tuple[tuple[str, int, tuple[str, ...]], ...]:
    """(module, relative level, imported names) of every import of the file; ``deep``: also
    those inside functions. Cached by the file's modification time and size."""
    try:
        tree = ast.parse(path.read_bytes(), str(path))
    except (OSError, SyntaxError, ValueError):
        return ()
    out: list[tuple[str, int, tuple[str, ...]]] = []

    def walk(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) and not deep:
                continue
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                walk(ast.Module(body=child.orelse, type_ignores=[]))
                continue
            if isinstance(child, ast.Import):
                out.extend((a.name, 0, ()) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                out.append((child.module or "", child.level, tuple(a.name for a in child.names)))
            walk(child)

    walk(tree)
    return tuple(out)


def _targets(path: Path, name: str, level: int, attrs: tuple[str, ...]) -> list[Path]:
    """Files an import statement of ``path`` reads (see the module docstring)."""
    if level:
        package = _module_name(path)
        if package is None:
            return []
        if path.name != "__init__.py":
            package = package.rpartition(".")[0]
        try:
            name = importlib.util.resolve_name("." * level + name, package)
        except ImportError:
            return []
    if not attrs:
        return [f] if (f := _resolve(path, name)) is not None else []
    out = []
    for attr in attrs:
        found = _resolve(path, f"{name}.{attr}")  # a submodule
        if found is None:  # an object: the module that defines it, else the package itself
            obj = getattr(sys.modules.get(name), attr, None)
            owner = getattr(obj, "__module__", None) if not isinstance(obj, types.ModuleType) else None
            found = _resolve(path, owner) if isinstance(owner, str) else None
            found = found or _resolve(path, name)
        if found is not None and found not in out:
            out.append(found)
    return out


def _resolve(path: Path, name: str) -> Path | None:
    """The file of module ``name``: loaded already, else beside ``path`` or in the package."""
    found = _file_of(sys.modules.get(name))
    if found is not None:
        return found
    rel = Path(*name.split("."))
    for base in (path.parent, PACKAGE.parent):
        for candidate in (base / rel.with_suffix(".py"), base / rel / "__init__.py"):
            if candidate.is_file():
                return candidate.resolve()
    return None


def _module_name(path: Path) -> str | None:
    """The dotted name under which ``path`` is imported, if it is (for relative imports)."""
    for name, module in list(sys.modules.items()):
        if _file_of(module) == path and getattr(module, "__spec__", None) is not None:
            return name
    return None
