"""Safe file-system helpers: validated names, checked output paths, marked report folders.

Every path bayesfric writes goes through this module:

* a study name becomes a folder name only if it is a plain *slug* (:func:`name_problem`);
* an output file (``fit --out``) or output root (``study --out``) is checked before any work
  (:func:`check_output_file`, :func:`check_output_folder`), so a bad path costs no sampling time;
  the user names these paths, so links on them are followed as on any path a user gives, but a
  file written there replaces a link at the final name instead of writing through it;
* below a reports root every folder bayesfric writes into is a real folder, never a symbolic link
  (:func:`real_folders`): a link planted there (``reports/.store`` pointing elsewhere) could lead
  writes out of the root, so the report folder and the run store refuse one;
* a report folder is built in a hidden *work folder* ``<root>/.<name>.<token>`` that carries a
  marker file (:data:`MARKER`: tool, study, PID, host, start time) and is then swapped in
  atomically (:func:`install_folder`: the old report is renamed aside, the new one renamed in,
  the old one removed). An existing ``<root>/<name>`` is replaced only when it carries the marker
  of the same study: bayesfric never removes a folder it did not create;
* a run stopped by SIGINT or SIGTERM removes its own work folder before it exits: the command
  line turns both signals into :class:`Interrupted` (:func:`handle_stop_signals`), which unwinds
  through the runner's clean-up, and the few steps that must not be cut in two (creating and
  marking a work folder, the swap of :func:`install_folder`) hold a signal back until they are
  done (:func:`signals_deferred`);
* work folders left behind by killed runs (SIGKILL, a power cut) are removed by the next run of
  the same study (:func:`clean_stale_work`) when their marker names a dead process (or, for
  another host, is older than :data:`STALE_AGE_S`); work folders of live concurrent runs are left
  alone;
* files and folders get the permissions an ordinary ``open``/``mkdir`` gives them: ``0o666`` and
  ``0o777`` less the process umask (:func:`apply_umask`), never ``tempfile``'s private ``0o600``.

Problems are :class:`PathError` (a :class:`~bayesfric.errors.UserError`) with a one-line message
that starts with the path; callers prefix the option or study key.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import shutil
import signal
import socket
import stat
import threading
import time
from pathlib import Path

from bayesfric.errors import UserError

__all__ = [
    "PathError", "MARKER", "NAME_MAX", "STALE_AGE_S", "name_problem", "current_umask", "apply_umask",
    "check_output_file", "check_output_folder", "report_folder", "create_work_folder", "install_folder",
    "remove_work_folder", "clean_stale_work", "is_marked", "real_folders", "lexically_inside",
    "Interrupted", "handle_stop_signals", "signals_deferred",
]

#: Marker file of every folder bayesfric creates under a reports root.
MARKER = ".bayesfric-report"
#: Longest allowed study name (a folder name on every common file system).
NAME_MAX = 64
#: Work folders of another host's runs count as stale after this many seconds (a week).
STALE_AGE_S = 7 * 24 * 3600
_SLUG = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]*")


class PathError(UserError):
    """An unusable output path: one line starting with the path."""


class Interrupted(KeyboardInterrupt):
    """The process received SIGINT or SIGTERM (``signum``).

    A :class:`KeyboardInterrupt`, so every clean-up written for Ctrl-C (a work folder removed, a
    temporary file unlinked, a Dask cluster closed) runs for SIGTERM too.
    """

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


#: Signals held back by :func:`signals_deferred` (depth of nesting, the first signal received).
_DEFERRED: dict = {"depth": 0, "pending": None}


def _stop(signum: int, frame) -> None:
    """The handler of SIGINT and SIGTERM: raise :class:`Interrupted`, or hold it back."""
    if _DEFERRED["depth"]:
        _DEFERRED["pending"] = _DEFERRED["pending"] or signum
        return
    raise Interrupted(signum)


def handle_stop_signals() -> None:
    """Turn SIGINT and SIGTERM into :class:`Interrupted` in this process (the command line's main
    thread only), so a stopped run unwinds and removes what it created instead of dying with its
    work folder left behind. A handler someone else installed is kept."""
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(signum) in (signal.SIG_DFL, signal.default_int_handler):
            signal.signal(signum, _stop)


@contextlib.contextmanager
def signals_deferred():
    """Hold SIGINT and SIGTERM back inside the block and raise :class:`Interrupted` after it, so
    a step that must not be cut in two (a folder created and marked, two renames) completes.
    Without :func:`handle_stop_signals` (a library caller) nothing is held back."""
    _DEFERRED["depth"] += 1
    try:
        yield
    finally:
        _DEFERRED["depth"] -= 1
        if _DEFERRED["depth"] == 0 and _DEFERRED["pending"] is not None:
            signum, _DEFERRED["pending"] = _DEFERRED["pending"], None
            raise Interrupted(signum)


def name_problem(name: object) -> str | None:
    """Why ``name`` cannot be used as a folder name (None if it can).

    A name is a slug: letters, digits, ``-``, ``_`` and ``.`` (not leading), at most
    :data:`NAME_MAX` characters; so never empty, ``.``, ``..``, absolute, with a separator, a
    space or a control character.
    """
    if not isinstance(name, str):
        return f"must be a string, got {type(name).__name__}"
    if not name:
        return "must not be empty"
    if len(name) > NAME_MAX:
        return f"must be at most {NAME_MAX} characters, got {len(name)}"
    if not _SLUG.fullmatch(name):
        return (f"{name!r} is not a plain name: use letters, digits, '-', '_' and '.' (not first), "
                "no spaces or path separators")
    return None


def current_umask() -> int:
    """The process umask (read from ``/proc`` where possible, so nothing is changed)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def apply_umask(folder: Path) -> None:
    """Give ``folder`` and everything below it the modes of ordinary files and folders.

    Folders get ``0o777 & ~umask``, files ``0o666 & ~umask`` (``0o777`` for executables);
    symbolic links are not followed.
    """
    mask = current_umask()
    for path in [folder, *folder.rglob("*")]:
        st = path.lstat()
        if stat.S_ISLNK(st.st_mode):
            continue
        full = 0o777 if stat.S_ISDIR(st.st_mode) or st.st_mode & 0o111 else 0o666
        os.chmod(path, full & ~mask)


def _probe(path: Path) -> tuple[bool, bool]:
    """(exists, is a folder) without following a final symbolic link into an error."""
    try:
        return path.exists(), path.is_dir()
    except (OSError, ValueError) as exc:  # name too long, embedded NUL ...
        raise PathError(f"{path}: unusable path ({exc})") from None


def _check_creatable(path: Path, target: str) -> None:
    """The nearest existing ancestor of ``path`` must be a writable folder."""
    for ancestor in path.absolute().parents:
        exists, is_dir = _probe(ancestor)
        if not exists:
            continue
        if not is_dir:
            raise PathError(f"{target}: {ancestor} is not a folder")
        if not os.access(ancestor, os.W_OK | os.X_OK):
            raise PathError(f"{target}: folder {ancestor} is not writable")
        return


def check_output_file(path: str | Path) -> Path:
    """Check that a file can be written at ``path`` (before any expensive work).

    The path must not be a folder or another non-regular file; an existing file must be
    writable; otherwise its nearest existing ancestor must be a writable folder (missing
    parent folders are created when the file is written).
    """
    text = str(path)
    path = Path(path)
    exists, is_dir = _probe(path)
    if not text or text.endswith(os.sep) or is_dir:
        raise PathError(f"{text or '.'}: is a folder; give a file path such as {path / 'fit.nc'}")
    if exists:
        if not path.is_file():
            raise PathError(f"{path}: exists and is not a regular file")
        if not os.access(path, os.W_OK) or not os.access(path.parent, os.W_OK | os.X_OK):
            raise PathError(f"{path}: is not writable")
        return path
    _check_creatable(path, str(path))
    return path


def check_output_folder(path: str | Path) -> Path:
    """Check that ``path`` is, or can be created as, a writable folder."""
    path = Path(path)
    exists, is_dir = _probe(path)
    if exists and not is_dir:
        raise PathError(f"{path}: exists and is not a folder")
    if exists and not os.access(path, os.W_OK | os.X_OK):
        raise PathError(f"{path}: folder is not writable")
    if not exists:
        _check_creatable(path, str(path))
    return path


def real_folders(root: str | Path, *parts: str) -> Path:
    """``root/parts...``, checked before anything is written there: every component below ``root``
    that exists is a real folder, not a symbolic link (which could lead writes out of ``root``) nor
    a file. ``root`` itself is the user's to name (a link there is followed).

    Raises
    ------
    PathError
        A component is a symbolic link or not a folder.
    """
    path = Path(root)
    for part in parts:
        path = path / part
        if path.is_symlink():
            raise PathError(f"{path}: is a symbolic link; below {root} bayesfric writes only into real folders "
                            "(links there could lead its files elsewhere): remove the link")
        if path.exists() and not path.is_dir():
            raise PathError(f"{path}: exists and is not a folder")
    return path


def lexically_inside(path: str | Path, root: str | Path) -> tuple[str, ...] | None:
    """The components of ``path`` below ``root``, compared as written (both made absolute and
    normalised without following links), or None when ``path`` does not lie below ``root``."""
    rel = os.path.relpath(os.path.abspath(path), os.path.abspath(root))
    if rel == os.pardir or rel.startswith(os.pardir + os.sep):
        return None
    return () if rel == os.curdir else Path(rel).parts


def _read_marker(folder: Path) -> dict | None:
    try:
        data = json.loads((folder / MARKER).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("tool") == "bayesfric" else None


def is_marked(folder: Path, name: str) -> bool:
    """Whether ``folder`` is a real folder that bayesfric created for the study ``name``."""
    return folder.is_dir() and not folder.is_symlink() and (_read_marker(folder) or {}).get("study") == name


def _proc_start(pid: int) -> int | None:
    """Start time of process ``pid`` in clock ticks since boot (Linux; None elsewhere)."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
        return int(text.rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def _alive(marker: dict) -> bool:
    """Whether the run that wrote ``marker`` may still be running."""
    if marker.get("host") != socket.gethostname():
        return time.time() - float(marker.get("created", 0)) < STALE_AGE_S
    pid = marker.get("pid")
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    started = marker.get("proc_start")
    return started is None or _proc_start(pid) in (None, started)  # a reused PID has another start


def report_folder(root: str | Path, name: str) -> Path:
    """The report folder ``<root>/<name>``, checked before anything is written.

    Raises
    ------
    PathError
        ``name`` is not a slug, the folder would lie outside ``root`` (resolved and compared), or
        it exists and is not a folder bayesfric created for this study (no marker).
    """
    problem = name_problem(name)
    if problem:
        raise PathError(f"{name!r}: {problem}")
    root = check_output_folder(root).resolve()
    final = root / name
    if final.resolve().parent != root:
        raise PathError(f"{final}: lies outside the reports folder {root}")
    if final.is_symlink() or (final.exists() and not is_marked(final, name)):
        raise PathError(f"{final}: exists and was not written by bayesfric for this study (no {MARKER} "
                        "marker); move it away or choose another study name")
    return final


def create_work_folder(root: Path, name: str) -> Path:
    """Create the marked hidden work folder ``<root>/.<name>.<token>`` (``root`` is created too).

    Created and marked with SIGINT/SIGTERM held back (:func:`signals_deferred`): a folder
    without its marker is one that nobody may remove. A signal that arrived meanwhile removes
    the new folder and is raised here, so the caller never holds a folder it does not know of.
    """
    root.mkdir(parents=True, exist_ok=True)
    work = None
    try:
        with signals_deferred():
            while work is None:
                candidate = root / f".{name}.{secrets.token_hex(4)}"
                with contextlib.suppress(FileExistsError):
                    candidate.mkdir()
                    work = candidate
            marker = {"tool": "bayesfric", "study": name, "pid": os.getpid(), "host": socket.gethostname(),
                      "created": time.time(), "proc_start": _proc_start(os.getpid())}
            (work / MARKER).write_text(json.dumps(marker) + "\n")
    except BaseException:
        if work is not None:  # created here: removed, marked or not (only its marker can be inside)
            (work / MARKER).unlink(missing_ok=True)
            work.rmdir()
        raise
    return work


def remove_work_folder(work: Path, name: str) -> None:
    """Remove a work folder this process created (only if it carries the study's marker)."""
    if is_marked(work, name):
        shutil.rmtree(work, ignore_errors=True)


def install_folder(work: Path, final: Path, name: str) -> None:
    """Atomically replace ``final`` by ``work``: old aside, new in, old removed.

    ``final`` must be absent or a folder marked for the same study (checked again here, since
    time has passed since :func:`report_folder`). Modes follow the umask (:func:`apply_umask`).
    """
    if final.is_symlink() or (final.exists() and not is_marked(final, name)):
        raise PathError(f"{final}: exists and was not written by bayesfric for this study (no {MARKER} marker)")
    apply_umask(work)
    aside = None
    if final.exists():
        aside = final.with_name(f".{name}.{secrets.token_hex(4)}")
        os.rename(final, aside)
    try:
        os.rename(work, final)
    except BaseException:
        if aside is not None:
            os.rename(aside, final)
        raise
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)


def clean_stale_work(root: Path, name: str) -> list[Path]:
    """Remove work folders ``<root>/.<name>.*`` of this study whose run is dead; return them.

    Only real folders whose marker names this study are considered; a folder of a run that may
    still be alive (:func:`_alive`) is left alone.
    """
    removed = []
    if not root.is_dir():
        return removed
    for path in sorted(root.glob(f".{_glob_escape(name)}.*")):
        if path.is_symlink() or not path.is_dir():
            continue
        marker = _read_marker(path)
        if marker is None or marker.get("study") != name or _alive(marker):
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path)
    return removed


def _glob_escape(text: str) -> str:
    """``text`` with glob metacharacters escaped (slugs have none, but stay safe)."""
    return re.sub(r"([*?\[])", r"[\1]", text)
