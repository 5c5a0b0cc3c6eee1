"""Built-in data sets shipped under ``data/<name>/<name>.csv`` (+ ``.toml`` sidecar)."""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from bayesfric.builtin import builtin_folder
from bayesfric.datasets.loader import DataError, load_dataset

__all__ = ["DATA_ROOT", "builtin_names", "load_builtin", "resolve", "describe"]

#: The built-in data sets: ``data/`` of the repository, shipped as package data (bayesfric.builtin).
DATA_ROOT = builtin_folder("bayesfric.builtin_data", "data")


def builtin_names() -> list[str]:
    """Names of the shipped data sets (folders of ``data/`` holding ``<name>.csv``)."""
    if not DATA_ROOT.is_dir():
        return []
    return sorted(p.name for p in DATA_ROOT.iterdir() if (p / f"{p.name}.csv").exists())


def resolve(ref: str | Path) -> Path:
    """A built-in name or a path to a CSV file -> the CSV path."""
    path = Path(ref)
    if path.suffix == ".csv" or path.exists():
        return path
    candidate = DATA_ROOT / str(ref) / f"{ref}.csv"
    if candidate.exists():
        return candidate
    raise DataError(f"{ref}: neither a CSV file nor a built-in data set ({', '.join(builtin_names())})")


def load_builtin(name: str) -> xr.Dataset:
    """Load a shipped data set by name."""
    return load_dataset(resolve(name))


def describe(ds: xr.Dataset) -> str:
    """Human-readable account of what the loader understood (used by ``bayesfric data check``)."""
    lines = [
        f"data set   {ds.attrs.get('name')}  ({ds.attrs.get('provenance')})",
        f"title      {ds.attrs.get('title') or '-'}",
        f"source     {ds.attrs.get('source')}",
        f"rows       {ds.sizes['obs']}",
        "columns:",
    ]
    for name, var in list(ds.coords.items()) + list(ds.data_vars.items()):
        a = var.attrs
        role = a.get("role", "?")
        if role == "group":
            groups = sorted(set(var.values.tolist()), key=str)
            shown = ", ".join(map(str, groups[:8])) + (" ..." if len(groups) > 8 else "")
            lines.append(f"  {a.get('column', name):<18} group     -> {name}: {len(groups)} groups ({shown})")
            continue
        conv = f"{a.get('original_unit')} -> {a.get('units')}"
        lo, hi = float(var.min()), float(var.max())
        lines.append(
            f"  {a.get('column', name):<18} {role:<9} -> {name} [{conv}]  range {lo:.4g} .. {hi:.4g}"
        )
    if ds.attrs.get("trajectory"):
        lines.append(f"trajectories delimited by group {ds.attrs['trajectory']!r}")
    return "\n".join(lines)
