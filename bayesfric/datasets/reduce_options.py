"""The settings of ``bayesfric data reduce`` (:class:`ReduceOptions`) and its command-line options.

Apart from :mod:`bayesfric.datasets.reduce` (which re-exports both names) because the command
line builds every command's options at start-up: this module imports only the standard library,
so ``bayesfric --help`` pays for no numpy, xarray or pint.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

__all__ = ["ReduceOptions", "add_arguments"]


@dataclass(frozen=True)
class ReduceOptions:
    """Settings of a reduction (:mod:`bayesfric.datasets.reduce`, *Algorithm*).

    Parameters
    ----------
    on : str
        Input quantity (or its column name) that is constant within a segment.
    rtol : float
        Relative tolerance on ``on``.
    atol : str, optional
        Absolute tolerance with its unit (``"0.005 rad/s"``); default from the noise of ``on``.
    settle : str
        Transient dropped at each segment start: ``"10%"``, ``"25"`` (rows) or ``"0.5 s"``.
    min_samples : int
        Fewest rows a kept segment averages (after settling).
    keep_standstill : bool
        Keep velocity segments at rest.
    """

    on: str = "velocity"
    rtol: float = 0.02
    atol: str | None = None
    settle: str = "10%"
    min_samples: int = 20
    keep_standstill: bool = False


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``bayesfric data reduce`` (defaults: :class:`ReduceOptions`)."""
    d = ReduceOptions()
    parser.add_argument("file", help="raw log CSV (sidecar FILE.toml next to it)")
    parser.add_argument("--meta", help="metadata TOML of the log (default: FILE with .toml suffix)")
    parser.add_argument("--out", help="reduced CSV to write, its sidecar beside it (default: FILE_reduced.csv)")
    parser.add_argument("--on", default=d.on, help=f"input held constant in a segment: quantity or column (default "
                                                   f"{d.on})")
    parser.add_argument("--rtol", type=float, default=d.rtol, help=f"relative tolerance (default {d.rtol})")
    parser.add_argument("--atol", help="absolute tolerance with unit, e.g. '0.005 rad/s' (default: 5 noise sds)")
    parser.add_argument("--settle", default=d.settle, help="dropped at each segment start: '10%%' of it (default), "
                                                           "'25' rows or '0.5 s' (needs a time input)")
    parser.add_argument("--min-samples", type=int, default=d.min_samples,
                        help=f"fewest rows a kept segment averages (default {d.min_samples})")
    parser.add_argument("--keep-standstill", action="store_true", help="keep velocity segments at rest")
    parser.add_argument("--strict", action="store_true",
                        help="refuse (exit 2, nothing written) a log whose segments are too short to be plateaus")
