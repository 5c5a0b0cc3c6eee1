"""Traced programs kept on disk, so a repeated fit neither traces nor compiles its sampler.

JAX's persistent compilation cache (:mod:`bayesfric.runtime`) keeps the *compiled* code, but a
new process must still *trace* the Python function to find the cache entry: for a law's NUTS
engine that is the whole sampler (warm-up, tree building, the law, the pointwise likelihood) and
took 2.3 s of a 3.7 s warm first call on the stribeck law, more on stateful laws. Here the
traced program is exported once with :func:`jax.export.export` (StableHLO, JAX's public,
versioned serialisation) into ``<cache>/exported/<key>.jaxexport``; a later process deserialises
it in milliseconds and calls it through ``jax.jit(exported.call)``, whose compilation the
persistent cache then answers.

The key is a SHA-256 over everything the traced program depends on: the package's computing
source (:func:`bayesfric.fingerprint.code_fingerprint`), the source of the module declaring the
law and its parts (:func:`~bayesfric.fingerprint.law_fingerprint`), the caller's parts (resolved
priors, noise model, constants, the data arrays that are constants of the program, sampler
settings), the argument shapes and dtypes, the JAX and jaxlib versions, the backend and the x64
flag. A law defined outside the package is covered by the source of its own module; a law whose
numbers come from a module it *imports* (not its own) is not, and needs the cache cleared
(``BAYESFRIC_NO_CACHE=1`` for one run, or delete the folder) after such an edit.

With the cache switched off (``BAYESFRIC_NO_CACHE``) this is plain ``jax.jit``. A file that
cannot be read back (truncated, another JAX) is traced again and replaced; writes are atomic;
the folder keeps at most :data:`EXPORTED_MAX_BYTES`, the least recently used files leaving first.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jaxlib
import numpy as np

from bayesfric.fingerprint import canonical, code_fingerprint
from bayesfric.runtime import cache_dir

__all__ = ["exported_jit", "program_jit", "EXPORTED_MAX_BYTES", "SUFFIX"]

#: Upper bound of the exported programs kept on disk (oldest read first to go).
EXPORTED_MAX_BYTES = 512 * 1024**2
SUFFIX = ".jaxexport"


def _folder() -> Path | None:
    base = cache_dir()
    return None if base is None else base / "exported"


def _key(parts: dict[str, Any], args: Sequence[Any]) -> str:
    shapes = [[list(a.shape), str(a.dtype)] for a in jax.tree.leaves(args)]
    text = json.dumps({"code": code_fingerprint(), "jax": jax.__version__, "jaxlib": jaxlib.__version__,
                       "backend": jax.default_backend(), "x64": bool(jax.config.jax_enable_x64),
                       "args": shapes, "parts": canonical(parts)}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:40]


def _load(path: Path) -> jax.export.Exported | None:
    try:
        exported = jax.export.deserialize(bytearray(path.read_bytes()))
    except FileNotFoundError:
        return None
    except Exception:  # noqa: BLE001 -- any unreadable entry (truncated, other JAX) is a miss
        return None
    os.utime(path)  # least recently *used* leaves first
    return exported


def _save(path: Path, exported: jax.export.Exported) -> None:
    try:
        payload = exported.serialize()
    except (ImportError, ValueError, NotImplementedError):  # not serialisable here: keep it in memory
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    try:
        tmp.write_bytes(payload)
        os.replace(tmp, path)
    except OSError:  # a full or read-only disk costs the next run a trace, nothing else
        return
    finally:
        tmp.unlink(missing_ok=True)
    _evict(path.parent, keep=path)


def _evict(folder: Path, keep: Path) -> None:
    files = sorted(folder.glob(f"*{SUFFIX}"), key=lambda p: p.stat().st_mtime)
    total = sum(p.stat().st_size for p in files)
    for old in files:
        if total <= EXPORTED_MAX_BYTES:
            break
        if old != keep:
            total -= old.stat().st_size
            old.unlink(missing_ok=True)


def exported_jit(fn: Callable, parts: dict[str, Any], example_args: Sequence[Any]) -> tuple[Callable, bool]:
    """``jax.jit(fn)``, traced at most once per key across processes.

    Parameters
    ----------
    fn : callable
        The function to compile. Everything it closes over must be determined by ``parts``
        and by the package's source.
    parts : dict
        What, besides the package source and the argument shapes, the traced program depends
        on (canonicalised with :func:`bayesfric.fingerprint.canonical`).
    example_args : sequence
        Arrays (or ``jax.ShapeDtypeStruct``) with the shapes and dtypes of the later calls.

    Returns
    -------
    (callable, bool)
        The compiled function, and whether its program was read from disk (``False``: traced
        in this process).
    """
    folder = _folder()
    if folder is None:
        return jax.jit(fn), False
    path = folder / f"{_key(parts, example_args)}{SUFFIX}"
    exported = _load(path)
    if exported is not None:
        return jax.jit(exported.call), True
    exported = jax.export.export(jax.jit(fn))(*example_args)
    _save(path, exported)
    return jax.jit(exported.call), False


def program_jit(program: Any, what: str, fn: Callable) -> Callable:
    """A drop-in ``jax.jit(fn)`` for a function of ``program``, its traces kept on disk.

    ``program`` is a :class:`bayesfric.model.Program`; ``what`` names the function and any
    setting it closes over besides the program (e.g. ``"draw_tables n_prior=500"``). The key's
    program part is :func:`bayesfric.fingerprint.program_parts`; each new combination of
    argument shapes is exported (or read back) on its first call, as ``jax.jit`` traces it.
    """
    return _ProgramJit(program, what, fn)


class _ProgramJit:
    def __init__(self, program: Any, what: str, fn: Callable):
        self._program, self._what, self._fn = program, what, fn
        self._parts: dict[str, Any] | None = None
        self._compiled: dict[Any, Callable] = {}

    def __call__(self, *args: Any) -> Any:
        leaves, treedef = jax.tree.flatten(args)
        if any(isinstance(a, jax.core.Tracer) for a in leaves):
            # called inside another transformation (a vmapped or jitted caller, e.g. tempered
            # SMC): inline the function into the caller's trace; an exported program has no
            # batching rule, and the caller's own compilation covers it
            return self._fn(*args)
        # host arrays: a device-committed argument would be another signature of the exported
        # program to compile (measured: a second compilation of the NUTS engine per warm start)
        args = jax.tree.unflatten(treedef, [np.asarray(a) if isinstance(a, jax.Array) else a for a in leaves])
        signature = (treedef, tuple((tuple(jax.numpy.shape(a)), str(jax.numpy.result_type(a))) for a in leaves))
        if signature not in self._compiled:
            if self._parts is None:
                from bayesfric.fingerprint import program_parts

                self._parts = dict(program=program_parts(self._program), what=self._what)
            self._compiled[signature] = exported_jit(self._fn, self._parts, args)[0]
        return self._compiled[signature](*args)
