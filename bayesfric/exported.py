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

**Compiling ahead.** ``exported_jit(..., ahead=True)`` and :meth:`_ProgramJit.ahead` lower the
program in the calling thread and hand its XLA compilation to :data:`COMPILE_THREADS` background
threads (created on first use), so the caller can trace the next program, or sample, while this
one compiles: on the 2-core machine a law's sampler, its starting points and its DataTree tables
used to compile one after the other. Tracing stays in the calling thread because numpyro's
effect-handler stack is a module-level list, not thread-local. The first call waits for the
compilation to finish. XLA compiles, and reads a compiled program back from the persistent cache,
without holding the GIL (a pure-Python thread kept running throughout), so two programs load
side by side while the caller waits for both: a warm ``joint_tribological`` fit took 1.64 s
in-process with two threads against 1.72 s with one (8 interleaved pairs, 7 in favour), a cold
``stribeck`` fit 5.06 against 5.44 s (3 pairs).

**Two optimisation levels.** A program run once per fit over its draws (the DataTree tables, the
pointwise likelihood, the checks' curves) is compiled at XLA's CPU backend optimisation level 0
(:data:`ONE_SHOT`) when its data set has at most :data:`ONE_SHOT_ROWS` rows. A program run in a
loop (the sampler, an optimiser, emcee's batched density) or steering the sampler (chain starts:
another level changes their last bits, and a trajectory follows them) is compiled at XLA's
default level 2 (:data:`LOOPED`), so the draws are those of the default level. On the
robot_joint study the once-run programs were about two thirds of a cold run's compilation; at
level 0 they compile in about half the time and run 3-4x slower, on milliseconds (a fit's tables:
0.011 -> 0.047 s on coulomb_viscous; ``benchmarks/bench_xla_level.py``). Level 0 everywhere made the sampler slower
than the compilation it saved. A run at level 0 grows with the rows (pitch_bearing's Rothe Erde
tables, 300 rows: 0.17 -> 0.75 s, against 2.5 s of compilation saved), so above ``ONE_SHOT_ROWS``
rows every program is compiled at the default level.

With the cache switched off (``BAYESFRIC_NO_CACHE``) this is plain ``jax.jit``. A file that
cannot be read back (truncated, another JAX) is traced again and replaced; writes are atomic;
the folder keeps at most :data:`EXPORTED_MAX_BYTES`, the least recently used files leaving first.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import secrets
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import jax
import jaxlib
import numpy as np

from bayesfric.errors import UserError
from bayesfric.fingerprint import canonical, code_fingerprint
from bayesfric.runtime import cache_dir

__all__ = ["exported_jit", "program_jit", "forget_compiled", "finish_compilations", "set_compile_threads",
           "AheadCompiled", "EXPORTED_MAX_BYTES", "SUFFIX", "COMPILE_THREADS", "ONE_SHOT", "LOOPED", "ONE_SHOT_ROWS",
           "program_options"]

#: XLA options of a program run once per fit (see the module notes).
ONE_SHOT: dict[str, Any] = {"xla_backend_optimization_level": 0}
#: XLA options of a program run in a loop: XLA's CPU default, stated so that no flag lowers it.
LOOPED: dict[str, Any] = {"xla_backend_optimization_level": 2}
#: Largest data set whose once-run programs are compiled with :data:`ONE_SHOT`.
ONE_SHOT_ROWS = 2000

#: Upper bound of the exported programs kept on disk (oldest read first to go).
EXPORTED_MAX_BYTES = 512 * 1024**2
SUFFIX = ".jaxexport"


#: Background compilation threads by default: two, so the starting points and the sampler (the
#: programs a fit waits for) load side by side; more would only compete with the chains for the
#: cores. A process that shares the cores with others takes fewer (:func:`set_compile_threads`).
COMPILE_THREADS = 2
_COMPILER: ThreadPoolExecutor | None = None  # the background compilation threads, made on first use
_THREADS = COMPILE_THREADS  # how many _COMPILER gets
_KEPT: dict[str, Callable] = {}  # compiled functions of this process by key (see exported_jit)


def forget_compiled() -> None:
    """Drop the compiled functions :func:`exported_jit` keeps for reuse in this process
    (:func:`bayesfric.inference.release_compiled_code` calls it between laws)."""
    _KEPT.clear()


def finish_compilations() -> None:
    """Wait for the background compilations started ahead (their results go to the persistent
    cache) and stop the compilation threads; a later :func:`exported_jit` starts new ones."""
    global _COMPILER
    if _COMPILER is not None:
        _COMPILER.shutdown(wait=True)
        _COMPILER = None


def set_compile_threads(threads: int) -> None:
    """Use ``threads`` (≥ 1) background compilation threads in this process from now on.

    The main job gives each study process its share of the cores: two study processes on two
    cores, each with two compilation threads, slowed the one-thread parts of a study (the
    importance estimator's L-BFGS loop of small compiled calls) while the other process loaded
    or compiled: unwinder's thermal_poly_surface evidence pair took 1.01× its fit in a cold main
    job against 0.43× with one thread per process, and the job itself 292 against 286 s (one
    pair). Compilations already started finish first.
    """
    global _THREADS
    if threads < 1:
        raise UserError(f"compilation threads must be at least 1 (got {threads})", "threads")
    finish_compilations()
    _THREADS = int(threads)


def _compiler() -> ThreadPoolExecutor:
    global _COMPILER
    if _COMPILER is None:
        _COMPILER = ThreadPoolExecutor(max_workers=_THREADS, thread_name_prefix="bayesfric-compile")
    return _COMPILER


class AheadCompiled:
    """A jitted function lowered for one signature, its XLA compilation running in the background.

    Parameters
    ----------
    jitted : callable
        A ``jax.jit`` function.
    example_args : sequence
        Arrays or ``jax.ShapeDtypeStruct`` of the later calls (lowered here, in the caller's thread).

    Attributes
    ----------
    out_shapes
        Pytree of ``jax.ShapeDtypeStruct``: the outputs' shapes, known before compiling ends.
    fallbacks : int
        Calls whose arguments did not match the lowered signature (each ran through plain
        ``jax.jit``, which compiles once per new signature): 0 when every call was as planned.
    """

    def __init__(self, jitted: Callable, example_args: Sequence[Any]):
        self._jitted = jitted
        self.fallbacks = 0
        lowered = jitted.lower(*example_args)
        self.out_shapes = lowered.out_info
        self._future: Future = _compiler().submit(lowered.compile)

    def __call__(self, *args: Any) -> Any:
        compiled = self._future.result()  # waits for the compilation; re-raises its error
        try:
            return compiled(*args)
        except TypeError:  # arguments of another signature than the lowered one: plain jit
            self.fallbacks += 1
            return self._jitted(*args)

    def lower(self, *args: Any) -> Any:
        """``jax.jit(...).lower`` of the function, e.g. to inspect its arguments."""
        return self._jitted.lower(*args)


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
    with contextlib.suppress(FileNotFoundError):  # another process may have evicted it since
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
    """Remove the least recently used files of ``folder`` beyond :data:`EXPORTED_MAX_BYTES`.
    Other processes evict from the same folder: a file gone in between is skipped."""
    files = []
    for p in folder.glob(f"*{SUFFIX}"):
        try:
            files.append((p.stat(), p))
        except FileNotFoundError:
            continue
    files.sort(key=lambda f: f[0].st_mtime)
    total = sum(st.st_size for st, _ in files)
    for st, old in files:
        if total <= EXPORTED_MAX_BYTES:
            break
        if old != keep:
            total -= st.st_size
            old.unlink(missing_ok=True)


def exported_jit(fn: Callable, parts: dict[str, Any], example_args: Sequence[Any],
                 ahead: bool = False, options: dict[str, Any] | None = None) -> tuple[Callable, bool]:
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
    ahead : bool
        Return an :class:`AheadCompiled` whose compilation for ``example_args`` has started in
        the background (see the module notes) instead of a function compiled on first call.
    options : dict, optional
        XLA compiler options (:data:`ONE_SHOT`, :data:`LOOPED`); ``None`` is XLA's defaults.

    Returns
    -------
    (callable, bool)
        The compiled function, and whether its program was read from disk or was already
        compiled in this process (``False``: traced here).

    Notes
    -----
    A key met again in the same process returns the function compiled (or compiling) for it
    the first time, until :func:`forget_compiled`: a law's units rebuild its program from the
    stored fit, and its chain starts, say, were compiled twice per law (once for the engine,
    once for the evidence estimators' optimisers), 1-1.5 s each on the 2-core machine.
    """
    key = _key(parts if options is None else parts | {"xla options": options}, example_args)
    if key in _KEPT:
        kept = _KEPT[key]
        if ahead and not isinstance(kept, AheadCompiled):
            kept = _KEPT[key] = AheadCompiled(kept, example_args)
        return kept, True
    folder = _folder()
    loaded = False
    if folder is None:
        jitted = jax.jit(fn, compiler_options=options)
    else:
        path = folder / f"{key}{SUFFIX}"
        exported = _load(path)
        loaded = exported is not None
        if not loaded:
            exported = jax.export.export(jax.jit(fn))(*example_args)
            _save(path, exported)
        jitted = jax.jit(_named(exported.call, parts.get("what")), compiler_options=options)
    _KEPT[key] = AheadCompiled(jitted, example_args) if ahead else jitted
    return _KEPT[key], loaded


def _named(call: Callable, what: Any) -> Callable:
    """``call`` under a name saying what it computes, so that JAX's compilation log
    (``JAX_LOG_COMPILES=1``) and profiles name ``jit(draw_tables_n_prior_500)``, not ``jit(call)``."""
    name = re.sub(r"\W+", "_", str(what or "call")).strip("_")[:60] or "call"

    def named(*args: Any) -> Any:
        return call(*args)

    named.__name__ = named.__qualname__ = name
    return named


def program_jit(program: Any, what: str, fn: Callable, optimised: bool = False) -> Callable:
    """A drop-in ``jax.jit(fn)`` for a function of ``program``, its traces kept on disk.

    ``program`` is a :class:`bayesfric.model.Program`; ``what`` names the function and any
    setting it closes over besides the program (e.g. ``"draw_tables n_prior=500"``). The key's
    program part is :func:`bayesfric.fingerprint.program_parts`; each new combination of
    argument shapes is exported (or read back) on its first call, as ``jax.jit`` traces it.
    ``optimised``: the function is called many times (an optimiser's step, emcee's density), or
    its output steers the sampler (chain starts, warm starts), so it is compiled with
    :data:`LOOPED` options: another level changes results in their last bits, and a chain's
    trajectory follows them. Otherwise it is compiled with :data:`ONE_SHOT` on small data sets.
    """
    return _ProgramJit(program, what, fn, optimised)


def program_options(n_obs: int, optimised: bool) -> dict[str, Any]:
    """XLA options of a program over ``n_obs`` rows (see the module notes).

    >>> program_options(111, optimised=False)["xla_backend_optimization_level"]
    0
    >>> program_options(111, optimised=True)["xla_backend_optimization_level"]
    2
    """
    return ONE_SHOT if not optimised and n_obs <= ONE_SHOT_ROWS else LOOPED


class _ProgramJit:
    def __init__(self, program: Any, what: str, fn: Callable, optimised: bool = False):
        self._program, self._what, self._fn = program, what, fn
        self._options = program_options(program.n_obs, optimised)
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
        signature = _signature(treedef, leaves)
        if signature not in self._compiled:
            self._compiled[signature] = exported_jit(self._fn, self._key_parts(), args, options=self._options)[0]
        return self._compiled[signature](*args)

    def ahead(self, *example_args: Any) -> Any:
        """Start compiling for the signature of ``example_args`` (arrays or ``ShapeDtypeStruct``)
        in the background; return the outputs' shapes. A later call of that signature waits
        for it instead of compiling."""
        leaves, treedef = jax.tree.flatten(example_args)
        signature = _signature(treedef, leaves)
        if signature not in self._compiled:
            self._compiled[signature] = exported_jit(self._fn, self._key_parts(), example_args, ahead=True,
                                                     options=self._options)[0]
        compiled = self._compiled[signature]
        return compiled.out_shapes if isinstance(compiled, AheadCompiled) else None

    def _key_parts(self) -> dict[str, Any]:
        if self._parts is None:
            from bayesfric.fingerprint import program_parts

            self._parts = dict(program=program_parts(self._program), what=self._what)
        return self._parts


def _signature(treedef: Any, leaves: list[Any]) -> tuple:
    """Argument structure, shapes and dtypes (arrays, scalars or ``ShapeDtypeStruct``)."""
    def one(a: Any) -> tuple:
        if isinstance(a, jax.ShapeDtypeStruct):
            return tuple(a.shape), str(np.dtype(a.dtype))
        return tuple(jax.numpy.shape(a)), str(jax.numpy.result_type(a))

    return treedef, tuple(one(a) for a in leaves)
