"""Laws from outside the package: a user's law files and installed packages' entry points.

Two ways in, both loading code only when asked (importing :mod:`bayesfric` loads neither):

**Law files** (:func:`load_module`, :func:`load_modules`). A study names them with
``[study] modules = ["my_laws.py"]`` (paths relative to the study file); the file is executed as
a module of its own, whose declarations (:func:`bayesfric.laws.law`,
:func:`bayesfric.laws.simple_law`) register its laws. The file's folder is on ``sys.path`` while
it runs, so it may import helper modules beside it. No bytecode is written next to them.
A file is loaded once per process (by its resolved path); every process that builds a study's
laws -- ``main --jobs`` study processes, Dask workers -- loads the files named in the law's
:class:`~bayesfric.study.config.LawSpec` itself before resolving its name, so nothing depends on
what the parent process imported.

**Entry points** (:func:`load_entry_points`). An installed package registers laws under the group
:data:`ENTRY_POINT_GROUP`, in its ``pyproject.toml``::

    [project.entry-points."bayesfric.laws"]
    my_laws = "my_package.laws"          # a module whose import registers its laws

An entry point may also name a :class:`~bayesfric.laws.base.Law` or a list of them (registered
if they are not yet). Entry points are loaded the first time a law name is not found in the
registry (:func:`bayesfric.laws.base.get_law`) or every law is listed
(:func:`bayesfric.laws.all_laws`), in any process.

Every problem -- a missing file, a file that fails to import, a law name defined twice -- is a
:class:`LawModuleError`: one line naming the file (or entry point), and the registry is left as
it was before the failed file.

**Unregistered laws** (:func:`unregistered_law`, a resolver of
:func:`~bayesfric.laws.base.get_law`). A law declared without registering it
(``bayesfric.law(fn, units=...)``, ``simple_law(..., register=False)``) is still found by its
name: one that a loaded law file defines at its top level, else the latest declared in this
process (:func:`remember`). It is not listed with the registered laws, and a registered law of
the same name takes precedence. A fit records the files its law's code comes from
(:func:`law_files`: a law file, or the file of a module imported by name); :func:`load_recorded`
loads them again wherever the fit is read, so a fit of a user's law rebuilds in a fresh process.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import sys
import types
from collections.abc import Iterable, Mapping, Sequence
from importlib import metadata
from pathlib import Path

from bayesfric.errors import UserError
from bayesfric.laws.base import REGISTRY, Law, LawDeclarationError, declared_in, get_law, register_resolver

__all__ = ["LawModuleError", "ENTRY_POINT_GROUP", "load_module", "load_modules", "load_entry_points",
           "module_files", "user_roots", "entry_point_law", "remember", "unregistered_law", "law_file",
           "law_files", "load_recorded"]

#: Entry-point group under which installed packages register laws.
ENTRY_POINT_GROUP = "bayesfric.laws"

#: Law files loaded in this process: resolved path -> module.
_LOADED: dict[Path, types.ModuleType] = {}
#: Laws declared in this process without registering them: name -> the latest (:func:`remember`).
_DECLARED: dict[str, Law] = {}
#: Whether this process has loaded the entry points (once; see :func:`load_entry_points`).
_ENTRY_POINTS: dict[str, bool] = {"loaded": False}


class LawModuleError(UserError):
    """A law file or entry point that cannot be loaded (one line naming it)."""


def _module_name(path: Path) -> str:
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:10]
    stem = "".join(c if c.isalnum() else "_" for c in path.stem)
    return f"_bayesfric_law_file_{stem}_{digest}"


def load_module(path: str | Path, label: str | None = None) -> types.ModuleType:
    """Execute a user's law file once in this process and return its module.

    Parameters
    ----------
    path : str or Path
        A ``.py`` file (absolute, or relative to the working directory).
    label : str, optional
        How errors name the file (default: ``path`` as given), e.g. as a study file writes it.

    Returns
    -------
    module
        The loaded module (the same object on every later call with the same file).

    Raises
    ------
    LawModuleError
        No such file, not a ``.py`` file, an error while executing it, or a law it declares
        whose name is already registered (by the package, an entry point or another file).
    """
    given = label if label is not None else str(path)
    resolved = Path(path).resolve()
    if resolved in _LOADED:
        return _LOADED[resolved]
    if (imported := _imported(resolved)) is not None:  # imported by name already: that module, not a copy
        _LOADED[resolved] = imported
        return imported
    if not resolved.is_file():
        problem = "no such file" if not resolved.exists() else "not a file"
        raise LawModuleError(f"{given}: law module: {problem} (looked for {resolved})")
    if resolved.suffix != ".py":
        raise LawModuleError(f"{given}: law module: not a Python file (.py)")
    try:
        source = resolved.read_text(encoding="utf-8")
        code = compile(source, str(resolved), "exec")
    except (OSError, UnicodeDecodeError, SyntaxError, ValueError) as exc:
        raise LawModuleError(f"{given}: law module does not load: {_one_line(exc)}") from None
    name = _module_name(resolved)
    module = types.ModuleType(name)
    module.__file__ = str(resolved)
    module.__package__ = ""
    before = set(REGISTRY)
    sys.modules[name] = module
    sys.path.insert(0, str(resolved.parent))
    bytecode, sys.dont_write_bytecode = sys.dont_write_bytecode, True  # helpers it imports too
    try:
        exec(code, module.__dict__)  # noqa: S102 - the user's own law file, named by their study
    except Exception as exc:  # noqa: BLE001 - any error of the user's code is reported in one line
        for added in set(REGISTRY) - before:
            del REGISTRY[added]
        del sys.modules[name]
        raise LawModuleError(f"{given}: law module does not load: {_one_line(exc)}{_where(exc, resolved)}") from None
    finally:
        sys.dont_write_bytecode = bytecode
        if str(resolved.parent) in sys.path:
            sys.path.remove(str(resolved.parent))
    _LOADED[resolved] = module
    return module


def _imported(path: Path) -> types.ModuleType | None:
    """The module of this process imported (by name) from the file ``path``, if any (this
    module's own copies of law files are not: they are what :data:`_LOADED` holds)."""
    for name, module in list(sys.modules.items()):
        found = getattr(module, "__file__", None)
        if name.startswith("_bayesfric_law_file_"):
            continue
        if isinstance(found, str) and found.endswith(".py") and Path(found).resolve() == path:
            return module
    return None


def load_modules(paths: Sequence[str | Path]) -> list[types.ModuleType]:
    """:func:`load_module` of every path, in order (each at most once per process)."""
    return [load_module(p) for p in paths]


def user_roots() -> tuple[Path, ...]:
    """Folders of the law files loaded in this process: their modules' imports there are the
    user's code (:mod:`bayesfric.fingerprint` hashes them with the law)."""
    return tuple(sorted({p.parent for p in _LOADED}))


def module_files() -> tuple[Path, ...]:
    """The law files loaded in this process, in the order they were loaded."""
    return tuple(_LOADED)


def remember(law: Law) -> Law:
    """Make an unregistered ``law`` findable by its name in this process (:func:`unregistered_law`);
    a later law of the same name replaces it. Returns ``law``."""
    _DECLARED[law.name] = law
    return law


def unregistered_law(name: str) -> Law | None:
    """The resolver of laws that are declared but not registered (module docstring): a
    :class:`~bayesfric.laws.base.Law` named ``name`` at the top level of a loaded law file (the
    latest file first), else the latest one :func:`remember` was given; None if neither."""
    for module in reversed(list(_LOADED.values())):
        for value in vars(module).values():
            if isinstance(value, Law) and value.name == name:
                return value
    return _DECLARED.get(name)


def law_file(law: Law) -> Path | None:
    """The file that declares ``law``'s own function, if loading it again elsewhere declares the
    law: a law file (:func:`load_module`) or a module imported by name (not ``__main__``, not this
    package) that registers the law or holds it at its top level. None for the package's laws,
    variants' composed functions, laws of a notebook or script and laws declared inside a function."""
    module = sys.modules.get(getattr(law.fn, "__module__", "") or "")
    if module is None or module.__name__ == "__main__" or module.__name__.split(".")[0] == "bayesfric":
        return None
    if REGISTRY.get(law.name) is not law and not any(v is law for v in vars(module).values()):
        return None  # loading the file again would not declare it (declared inside a function, say)
    for path, loaded in _LOADED.items():
        if loaded is module:
            return path
    found = getattr(module, "__file__", None)
    return Path(found).resolve() if found and found.endswith(".py") else None


def law_files(law: Law) -> tuple[str, ...]:
    """Absolute paths of the files ``law``'s code comes from (:func:`law_file` of the law, of its
    base law and of every law it adds), in that order, each once; what a fit records."""
    names = (law.base_name, *law.recipe.get("add", ()))
    parts = [law, *(w for n in names if (w := REGISTRY.get(n) or unregistered_law(n)) is not None)]
    files: list[str] = []
    for part in parts:
        if (path := law_file(part)) is not None and str(path) not in files:
            files.append(str(path))
    return tuple(files)


def load_recorded(attrs: Mapping[str, object]) -> None:
    """Load the law files a fit records (``attrs["law_files"]``, :func:`law_files`) that this
    process has neither loaded nor imported, so its law can be rebuilt by name.

    A recorded file of another place that this process has loaded from here (:func:`_loaded_twin`:
    the project folder was moved or copied with its reports) is not loaded again.

    Raises
    ------
    LawModuleError
        A recorded file that is gone or no longer loads (the fit's law cannot be rebuilt).
    """
    for path in json.loads(str(attrs.get("law_files") or "[]")):
        if Path(path) not in _LOADED and _loaded_twin(Path(path)) is None:  # an imported one is taken as it is
            load_module(path, label=f"law file of the fit ({path})")


def _loaded_twin(path: Path) -> Path | None:
    """The law file loaded in this process that stands for ``path``, recorded elsewhere: the same
    file name and, where ``path`` still exists (a copied project), the same bytes; where it is
    gone (a moved project), the loaded file of that name. A study's reused fits need no more: a
    unit's key holds its law file's bytes, so a fit reused under it was computed from the file
    loaded here."""
    for loaded in _LOADED:
        if loaded.name != path.name:
            continue
        try:
            if not path.exists() or path.read_bytes() == loaded.read_bytes():
                return loaded
        except OSError:
            continue
    return None


def load_entry_points() -> bool:
    """Load every entry point of :data:`ENTRY_POINT_GROUP` (once per process).

    Returns
    -------
    bool
        True if this call loaded them (so a name lookup may be tried again), False if they were
        loaded before.

    Raises
    ------
    LawModuleError
        An entry point that fails to load, names something other than a module or laws, or
        declares a law whose name is already registered.
    """
    if _ENTRY_POINTS["loaded"]:
        return False
    _ENTRY_POINTS["loaded"] = True
    for point in sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda p: p.name):
        where = f"entry point {point.name} = {point.value!r} (group {ENTRY_POINT_GROUP}{_dist(point)})"
        try:
            target = point.load()
        except Exception as exc:  # noqa: BLE001 - a broken plug-in is reported in one line
            raise LawModuleError(f"{where}: does not load: {_one_line(exc)}") from None
        _register(where, target)
    return True


def entry_point_law(name: str) -> Law | None:
    """The resolver (:func:`bayesfric.laws.base.register_resolver`) of installed packages' laws:
    on the first name no law or resolver knows, load the entry points and look ``name`` up again;
    None after that. :mod:`bayesfric.laws` registers it after every family's resolver."""
    return get_law(name) if load_entry_points() else None


def _register(where: str, target: object) -> None:
    if inspect.ismodule(target):
        return  # its import registered its laws
    laws = [target] if isinstance(target, Law) else list(target) if isinstance(target, Iterable) else None
    if laws is None or not all(isinstance(w, Law) for w in laws):
        raise LawModuleError(f"{where}: names {type(target).__name__}, not a module, a Law or a list of Laws")
    for w in laws:
        if REGISTRY.get(w.name) is w:
            continue
        if w.name in REGISTRY:
            other = declared_in(REGISTRY[w.name].fn)
            raise LawModuleError(f"{where}: law {w.name!r} is defined twice (also in {other})")
        REGISTRY[w.name] = w


def _dist(point: metadata.EntryPoint) -> str:
    dist = getattr(point, "dist", None)
    return f", distribution {dist.name} {dist.version}" if dist is not None else ""


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if isinstance(exc, LawDeclarationError | LawModuleError):
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _where(exc: BaseException, path: Path) -> str:
    """`` (line N)`` of the deepest frame of ``exc`` in the file at ``path``, if any."""
    line = None
    tb = exc.__traceback__
    while tb is not None:
        if Path(tb.tb_frame.f_code.co_filename) == path:
            line = tb.tb_lineno
        tb = tb.tb_next
    return f" (line {line})" if line is not None else ""


register_resolver(unregistered_law)  # laws declared but not registered, found by name (module docstring)
