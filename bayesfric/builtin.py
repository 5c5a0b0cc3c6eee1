"""Where the built-in data sets and seed studies are, installed or in a source checkout.

They live at the repository's top level (``data/``, ``studies/``) and ship inside the package
as ``bayesfric.builtin_data`` and ``bayesfric.builtin_studies`` (``pyproject.toml`` maps the
folders), so ``pip install bayesfric`` carries them. Running from a source tree without an
install, the top-level folders are used directly.
"""

from __future__ import annotations

import importlib
from pathlib import Path

__all__ = ["builtin_folder"]


def builtin_folder(package: str, source_folder: str) -> Path:
    """The folder of data package ``package``, or ``<repository>/<source_folder>`` when not installed."""
    try:
        return Path(next(iter(importlib.import_module(package).__path__)))
    except (ImportError, StopIteration):
        return Path(__file__).resolve().parents[1] / source_folder
