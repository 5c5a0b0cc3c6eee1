"""Process-wide JAX settings bayesfric needs, applied on first use — never at import.

:func:`configure` switches on 64-bit floats (friction coefficients span many decades: N·m and
N·m·s/rad on MN·m loads) and JAX's persistent compilation cache, so a repeated fit or study
loads its compiled programs from disk instead of compiling them again. It runs when a program
is built (:func:`bayesfric.model.build_program`, which every fit, refit, evidence estimate and
check goes through) and when the CLI starts; importing bayesfric changes nothing.

The cache lives in ``$BAYESFRIC_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/bayesfric/jax`` (default
``~/.cache/bayesfric/jax``). ``BAYESFRIC_NO_CACHE=1`` switches it off. It may be deleted at any
time; it is bounded to :data:`CACHE_MAX_BYTES` (JAX evicts the least recently used entries).
A user who set ``jax_compilation_cache_dir`` already keeps their choice.

:func:`without_dask` keeps dask out of a light command's process (``bayesfric data``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["configure", "cache_dir", "CACHE_MAX_BYTES", "without_dask"]

#: Upper bound of the on-disk compilation cache (JAX evicts least recently used entries).
CACHE_MAX_BYTES = 2 * 1024**3

_configured = False


def cache_dir() -> Path | None:
    """The persistent compilation cache folder, or ``None`` when switched off."""
    if os.environ.get("BAYESFRIC_NO_CACHE", "").strip() not in ("", "0"):
        return None
    explicit = os.environ.get("BAYESFRIC_CACHE_DIR", "").strip()
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME", "").strip() or Path.home() / ".cache"
    return Path(base) / "bayesfric" / "jax"


def configure() -> None:
    """Enable x64 and the persistent compilation cache for this process (idempotent)."""
    global _configured
    if _configured:
        return
    import jax  # here: cache_dir() serves light commands (pint's cache) that import no JAX
    from jax.experimental.compilation_cache import compilation_cache

    jax.config.update("jax_enable_x64", True)
    folder = cache_dir()
    if folder is not None and jax.config.jax_compilation_cache_dir is None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:  # read-only home, say: run without the cache rather than fail
            folder = None
        if folder is not None:
            jax.config.update("jax_compilation_cache_dir", str(folder))
            # every program, however quick to compile: a fit is hundreds of small executables
            jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
            jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
            jax.config.update("jax_compilation_cache_max_size", CACHE_MAX_BYTES)
            # A library may have compiled at import (blackjax does), which initialised the cache
            # without a folder; make the next compilation initialise it again with ours.
            compilation_cache.reset_cache()
    _configured = True


def without_dask() -> bool:
    """Mark dask absent for the rest of this process, unless it is imported already; True if marked.

    Installed with the ``dask`` extra, dask is imported by xarray the first time it wraps an array
    (every ``Variable`` is checked against ``dask.array.Array``) and by pint's ``compat``: about
    half a second of what ``bayesfric data list|check|reduce`` took, for data never chunked. The
    light data commands call this first: ``sys.modules["dask"] = None`` makes ``import dask`` fail
    as if it were not installed, so xarray and pint take it as absent. Only for a process that
    will not use dask afterwards (a study with ``--workers`` needs it).

    Examples
    --------
    >>> import subprocess, sys
    >>> code = ("from bayesfric.runtime import without_dask; without_dask(); import xarray as xr, sys; "
    ...         "xr.Dataset({'a': ('x', [1.0])}); print('dask' in sys.modules and sys.modules['dask'] is not None)")
    >>> subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip()
    'False'
    """
    if "dask" in sys.modules:
        return False
    sys.modules["dask"] = None  # type: ignore[assignment]  # import dask -> ModuleNotFoundError
    return True
