"""The bad-input harness: run the CLI in-process on a hostile case and check the contract.

The contract (README, DESIGN.md): a user error ends with exit status 2 and exactly one line on
stderr, ``bayesfric: error: <message>``, that names the file and the column, row or key; no
traceback; and nothing is created, changed or removed anywhere in the case's directory tree.
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from bayesfric.cli import main

__all__ = ["snapshot", "run_cli", "assert_user_error"]


def snapshot(root: Path) -> dict[str, tuple[int, int, int]]:
    """Every path under ``root`` (folders included) with its size, mtime (ns) and mode."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            st = p.lstat()
            out[str(p.relative_to(root))] = (st.st_size, st.st_mtime_ns, st.st_mode)
    return out


def run_cli(argv: Sequence[str], cwd: Path) -> tuple[int, str, str]:
    """Run ``bayesfric argv`` in-process with ``cwd`` as the working directory.

    Returns (exit status, stdout, stderr). Exceptions other than ``SystemExit`` propagate: an
    uncaught exception *is* a traceback for the user, so the calling test fails on it.
    """
    out, err = io.StringIO(), io.StringIO()
    old = Path.cwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(argv))
            except SystemExit as exc:  # argparse
                code = exc.code if isinstance(exc.code, int) else 1
    finally:
        os.chdir(old)
    return int(code), out.getvalue(), err.getvalue()


def assert_user_error(argv: Sequence[str], root: Path, mentions: Iterable[str], cwd: Path | None = None) -> str:
    """Run a hostile case and assert the bad-input contract; return the error line.

    Parameters
    ----------
    argv : sequence of str
        CLI arguments.
    root : Path
        The case's whole directory tree: nothing under it may be created, changed or removed.
    mentions : iterable of str
        Fragments the one-line message must contain (file name, column, row, key ...).
    cwd : Path, optional
        Working directory of the run (default ``root``).
    """
    before = snapshot(root)
    code, _, err = run_cli(argv, cwd or root)
    lines = err.strip().splitlines()
    assert code == 2, f"exit status {code}, expected 2; stderr: {err!r}"
    assert "Traceback" not in err, err
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}: {err!r}"
    line = lines[0]
    assert line.startswith("bayesfric: error: "), line
    for fragment in mentions:
        assert fragment in line, f"{fragment!r} missing from: {line}"
    after = snapshot(root)
    assert after == before, f"the tree changed: added {sorted(set(after) - set(before))}, " \
        f"removed {sorted(set(before) - set(after))}, " \
        f"changed {sorted(k for k in before.keys() & after.keys() if before[k] != after[k])}"
    return line
