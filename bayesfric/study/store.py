"""The run store: content-addressed results of a study's units of work, for resume and reuse.

Every unit of a study (a law's full fit, its PSIS-LOO, each cross-validation scheme, each
evidence estimate, the checks) is a pure function of its inputs. Its *key* is a SHA-256 over
everything it depends on (:func:`bayesfric.fingerprint.unit_key`): the law's name and the source of the module that
declares it, the source of the computing code (every module of :mod:`bayesfric` a unit can run:
:func:`bayesfric.fingerprint.computing_files`), the package version, the resolved priors, noise model and
constants, the content of the selected data, the scheme's masks, the sampler settings and the seed.
A unit whose key is in the store is read back instead of computed.

Layout: ``<root>/<key>.nc`` (a full fit, a NetCDF DataTree) or ``<root>/<key>.unit.nc`` (every
other unit: its scorer's ``xarray.Dataset``, :mod:`bayesfric.study.units`, whose attrs hold its key
and compute seconds). A fit's compute seconds lie beside it in ``<root>/<key>.nc.json``
(:meth:`RunStore.put_seconds`), outside the NetCDF file so a fit's file stays a function of its
inputs; a reused unit reports what it saved. The store holds results as objects in memory and as
NetCDF files on disk: :meth:`RunStore.put` writes a result and :meth:`RunStore.get` reads it, the
only places a result becomes bytes (a run's units hand each other the objects themselves).
``root`` is :func:`store_folder`: ``$BAYESFRIC_STORE_DIR/<study>``
if that variable is set, else ``<reports root>/.store/<study>``; below the reports root it is
reached through real folders only, never a symbolic link. Each entry is one file written
atomically (temporary file in the same folder, then ``os.replace``), so a run killed at any moment
leaves either the whole entry or none. An entry that cannot be read back (truncated by a full
disk, edited, another format) counts as a miss and is computed again. The store may be deleted at
any time; it only costs recomputation.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import secrets
import socket
from pathlib import Path

import xarray as xr

from bayesfric.fsutil import PathError, check_output_folder, lexically_inside, real_folders

__all__ = ["RunStore", "Result", "store_folder", "STORE_ENV"]

#: Environment variable that moves the store out of the reports folder.
STORE_ENV = "BAYESFRIC_STORE_DIR"


def store_folder(out_root: str | Path, study: str) -> Path:
    """The store folder of ``study``: ``$BAYESFRIC_STORE_DIR/<study>`` or ``<out_root>/.store/<study>``,
    checked before anything is written there.

    Below the reports root ``out_root`` (``.store`` and ``<study>``, or the path of
    ``$BAYESFRIC_STORE_DIR`` where it lies below the root) every existing component must be a real
    folder, as report folders must (:func:`bayesfric.fsutil.real_folders`): a link planted there
    would lead the store's writes out of the root. ``$BAYESFRIC_STORE_DIR`` itself is the folder the
    user named: it must be, or be creatable as, a writable folder, and ``<study>`` inside it a real
    folder.

    Raises
    ------
    bayesfric.fsutil.PathError
        One line starting with the path (or ``$BAYESFRIC_STORE_DIR=...``).
    """
    base = os.environ.get(STORE_ENV, "").strip()
    if not base:
        return real_folders(out_root, ".store", study)
    named = Path(base).expanduser()
    try:
        check_output_folder(named)
    except PathError as exc:
        raise PathError(f"${STORE_ENV}={base}: {exc}") from None
    below = lexically_inside(named, out_root)
    return real_folders(out_root, *below, study) if below is not None else real_folders(named, study)


def _tmp_name(path: Path) -> Path:
    """Temporary file of a write in progress: names its host and process (see :meth:`RunStore.clean`)."""
    return path.parent / f".{path.name}.{socket.gethostname()}.{os.getpid()}.{secrets.token_hex(4)}.tmp"


def _atomic_write(path: Path, payload: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        with open(tmp, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


#: A unit's result: the fit (a DataTree) or the unit's Dataset.
Result = xr.DataTree | xr.Dataset


class RunStore:
    """The store of one study (see the module docstring).

    Parameters
    ----------
    folder : Path
        Where entries live (created on the first write).
    read : bool
        False (``--fresh``): every lookup is a miss; results are still written for the next run.
    """

    def __init__(self, folder: Path, *, read: bool = True):
        self.folder = Path(folder)
        self.read = read

    def path(self, key: str, kind: str) -> Path:
        """File of the entry ``key``; ``kind`` is ``"nc"`` (a fit) or ``"unit.nc"``."""
        return self.folder / f"{key}.{kind}"

    def get(self, key: str, kind: str) -> Result | None:
        """The entry, read back (a fit fully loaded into memory), if present and readable, else
        None (a miss, never an error)."""
        if not self.read:
            return None
        path = self.path(key, kind)
        try:
            payload = path.read_bytes()
            if kind != "nc":
                result = load_unit_bytes(payload)
                return result if result.attrs.get("key") == key else None
            return load_fit_bytes(payload)
        except (OSError, ValueError, KeyError, EOFError):
            return None
        except Exception:  # noqa: BLE001 - h5py/netCDF raise their own types on a damaged file: a miss
            return None

    def clean(self) -> list[Path]:
        """Remove temporary files of writes killed part-way (their process on this host is gone)."""
        removed = []
        if not self.folder.is_dir():
            return removed
        host = socket.gethostname()
        for tmp in self.folder.glob(".*.tmp"):
            parts = tmp.name.rsplit(".", 4)  # .<entry>.<host>.<pid>.<token>.tmp
            if len(parts) != 5 or parts[1] != host or not parts[2].isdigit() or _pid_alive(int(parts[2])):
                continue
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
        return removed

    def put(self, key: str, kind: str, result: Result) -> Path:
        """Write an entry atomically (an existing one is replaced), as NetCDF."""
        path = self.path(key, kind)
        _atomic_write(path, fit_to_bytes(result))
        return path

    def put_seconds(self, key: str, kind: str, seconds: float) -> None:
        """Record beside the entry the wall seconds it took to compute (for a fit, whose NetCDF
        bytes hold no record of their own)."""
        _atomic_write(self.folder / f"{key}.{kind}.json", json.dumps({"compute_s": float(seconds)}).encode())

    def seconds(self, key: str, kind: str) -> float:
        """The seconds recorded by :meth:`put_seconds`; NaN if none (a store of an older run)."""
        try:
            return float(json.loads((self.folder / f"{key}.{kind}.json").read_text())["compute_s"])
        except (OSError, ValueError, KeyError, TypeError):
            return float("nan")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def fit_to_bytes(dt: xr.DataTree | xr.Dataset) -> bytes:
    """A fit (or a unit's Dataset) as NetCDF bytes (h5netcdf, as :func:`bayesfric.inference.save_fit`
    writes; no temporary file)."""
    buffer = io.BytesIO()
    with _local_locks():
        dt.to_netcdf(buffer, engine="h5netcdf")
    return buffer.getvalue()


def _local_locks():
    """Inside a Dask worker xarray would take a *distributed* lock named after the file, which a
    buffer cannot be; the synchronous scheduler makes it take a local lock (the write is local)."""
    try:
        import dask
    except ImportError:
        return contextlib.nullcontext()
    return dask.config.set(scheduler="synchronous")


def load_fit_bytes(payload: bytes) -> xr.DataTree:
    """Inverse of :func:`fit_to_bytes` (the fit fully loaded into memory)."""
    return xr.open_datatree(io.BytesIO(payload), engine="h5netcdf").load()


def load_unit_bytes(payload: bytes) -> xr.Dataset:
    """Inverse of :func:`fit_to_bytes` for a unit's Dataset (fully loaded into memory)."""
    with xr.open_dataset(io.BytesIO(payload), engine="h5netcdf") as ds:
        return ds.load()
