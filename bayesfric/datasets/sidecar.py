"""Read and validate the TOML sidecar of a data file (keys and rules: :mod:`bayesfric.datasets.loader`).

Everything that can be checked without the CSV is checked here: the file is UTF-8 TOML, every key
is known and has the right type, roles, quantities, provenance and the encoding name are valid,
exactly one column is the response. Each problem raises :class:`DataError` with one line naming
the sidecar and the key.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from bayesfric.datasets.derive import check_derive
from bayesfric.datasets.errors import DataError, decode_position, decode_utf8, read_file
from bayesfric.quantities import QUANTITIES, RESPONSES

__all__ = ["PROVENANCES", "ROLES", "DATASET_KEYS", "COLUMN_KEYS", "REDUCTION_KEYS", "read_sidecar"]

PROVENANCES = ("measured", "reconstructed", "simulated")
#: ``se``: the standard error of the response in each row (a reduced data set's segment means,
#: :mod:`bayesfric.datasets.reduce`); the likelihood adds it to the noise model (:mod:`bayesfric.model`).
ROLES = ("input", "response", "group", "aux", "se")
#: Keys of ``[dataset]`` and their types (``provenance`` and ``source`` are required).
DATASET_KEYS: dict[str, type] = {
    "name": str, "title": str, "provenance": str, "source": str, "description": str,
    "trajectory": str, "encoding": str,
}
#: Keys of a ``[columns.<name>]`` table and their types (``role`` is required).
COLUMN_KEYS: dict[str, type] = {"role": str, "quantity": str, "unit": str, "group": bool}
#: Keys of the optional ``[reduction]`` table that ``bayesfric data reduce`` writes (what was reduced
#: and how); each value a string, number or true/false.
REDUCTION_KEYS = ("source_file", "source_sha256", "sidecar_sha256", "on", "rtol", "atol", "settle",
                  "min_samples", "keep_standstill", "se_method", "segments", "rows_used", "rows_total",
                  "bayesfric")


def read_sidecar(path: Path, *, response: bool = True) -> dict[str, Any]:
    """Parse and validate the sidecar at ``path``.

    Parameters
    ----------
    path : Path
        The TOML sidecar.
    response : bool
        Whether a response column is required; ``False`` lets a log without one through (a planned
        trajectory to predict on: ``bayesfric predict``), with at most one response column.

    Returns
    -------
    dict
        ``{"dataset": {...}, "columns": {name: {...}}}`` as written, validated.

    Raises
    ------
    DataError
        One line naming ``path`` and the offending key.
    """
    if not path.exists():
        raise DataError(f"{path}: metadata file not found (expected next to the CSV, same name, .toml)")
    data = read_file(path, "metadata file")
    try:
        text = decode_utf8(data)
    except UnicodeDecodeError as exc:
        raise DataError(
            f"{path}: not UTF-8 at {decode_position(data, exc)}; a TOML sidecar must be UTF-8, re-save it as UTF-8"
        ) from None
    try:
        meta = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DataError(f"{path}: invalid TOML: {exc}") from None
    except RecursionError:
        raise DataError(f"{path}: invalid TOML: arrays or tables nested too deeply") from None
    if not isinstance(meta.get("dataset"), dict) or not isinstance(meta.get("columns"), dict):
        raise DataError(f"{path}: needs a [dataset] table and [columns.<name>] tables")
    unknown = sorted(set(meta) - {"dataset", "columns", "reduction", "derive"})
    if unknown:
        raise DataError(f"{path}: unknown top-level key {unknown[0]!r}; a sidecar has [dataset], [columns.<name>], "
                        f"[derive.<quantity>] and (written by bayesfric data reduce) [reduction]")
    _check_dataset(path, meta["dataset"])
    _check_columns(path, meta["columns"], response)
    _check_reduction(path, meta.get("reduction", {}))
    check_derive(path, meta.get("derive", {}))
    return meta


def _check_reduction(path: Path, table: object) -> None:
    if not isinstance(table, dict):
        raise DataError(f"{path}: reduction must be a table ([reduction])")
    for key, value in table.items():
        if key not in REDUCTION_KEYS:
            raise DataError(f"{path}: [reduction]: unknown key {key!r}; known keys: {', '.join(REDUCTION_KEYS)}")
        if not isinstance(value, str | int | float | bool):
            raise DataError(f"{path}: [reduction] {key} must be a string, number or true/false, got {value!r}")


def _check_keys(where: str, table: dict, known: dict[str, type]) -> None:
    for key, value in table.items():
        if key not in known:
            raise DataError(f"{where}: unknown key {key!r}; known keys: {', '.join(known)}")
        if not isinstance(value, known[key]):
            kind = "true or false" if known[key] is bool else "a string"
            raise DataError(f"{where}: {key} must be {kind}, got {value!r}")


def _check_dataset(path: Path, ds: dict) -> None:
    _check_keys(f"{path}: [dataset]", ds, DATASET_KEYS)
    for key in ("provenance", "source"):
        if key not in ds:
            raise DataError(f"{path}: [dataset] is missing {key!r}")
    if ds["provenance"] not in PROVENANCES:
        raise DataError(f"{path}: [dataset] provenance {ds['provenance']!r} not one of {PROVENANCES}")
    if "encoding" in ds and not _is_text_encoding(ds["encoding"]):
        raise DataError(
            f"{path}: [dataset] encoding = {ds['encoding']!r} is not a text encoding Python knows "
            f"(e.g. \"utf-8\", \"latin-1\", \"cp1252\")"
        )


def _is_text_encoding(name: str) -> bool:
    """True if ``name`` is a codec Python knows that decodes bytes to text."""
    try:
        b"\n".decode(name)  # b"".decode() would not look the name up
    except UnicodeDecodeError:
        return True  # a text codec that needs more bytes (utf-16, utf-32)
    except (LookupError, ValueError):
        return False  # unknown name, or a bytes/str transform such as base64 or rot13
    return True


def _check_columns(path: Path, columns: dict, response: bool = True) -> None:
    n_response = n_se = 0
    for col, spec in columns.items():
        where = f"{path}: column {col!r}"
        if not col.strip():
            raise DataError(f"{path}: [columns.{col!r}]: a column name cannot be empty or only whitespace")
        if col != col.strip():
            raise DataError(f"{where}: the name has leading or trailing whitespace (header cells are read without it)")
        if not isinstance(spec, dict) or "role" not in spec:
            raise DataError(f"{where}: needs a 'role' ({', '.join(ROLES)})")
        _check_keys(where, spec, COLUMN_KEYS)
        role = spec["role"]
        if role not in ROLES:
            raise DataError(f"{where}: role {role!r} not one of {ROLES}")
        if spec.get("group") and role != "input":
            raise DataError(f"{where}: 'group = true' applies to inputs only (this column's role is {role!r})")
        if role in ("input", "response", "se") or "quantity" in spec:
            q = spec.get("quantity")
            if q not in QUANTITIES:
                raise DataError(f"{where}: quantity {q!r} unknown; known: {', '.join(QUANTITIES)}")
            if "unit" not in spec:
                raise DataError(f"{where}: needs a 'unit'")
        if role == "response":
            n_response += 1
            if spec["quantity"] not in RESPONSES:
                raise DataError(f"{where}: a response must be one of {RESPONSES}")
        n_se += role == "se"
    if n_response != 1 and (response or n_response > 1 or n_se):
        which = "exactly one column" if response or n_se else "at most one column"
        raise DataError(f"{path}: {which} must have role 'response' (found {n_response})")
    if n_se:
        _check_se(path, columns, n_se)


def _check_se(path: Path, columns: dict, n_se: int) -> None:
    """At most one ``se`` column, with a quantity and unit, of the response's quantity."""
    response = next(spec["quantity"] for spec in columns.values() if spec["role"] == "response")
    for col, spec in columns.items():
        if spec["role"] != "se":
            continue
        if n_se > 1:
            raise DataError(f"{path}: column {col!r}: more than one column has role 'se' ({n_se}); the "
                            f"response has one standard error per row")
        if spec.get("quantity") != response:
            raise DataError(f"{path}: column {col!r}: a standard error (role 'se') has the response's quantity "
                            f"{response!r}, got {spec.get('quantity')!r}")
