"""The data loader's error type and helpers for its one-line messages.

:class:`DataError` is declared in :mod:`bayesfric.errors` (the laws raise it too) and re-exported
here, so that the sidecar reader and the loader can both raise it; import it from
:mod:`bayesfric.datasets.loader` or :mod:`bayesfric.datasets` (both re-export it).
"""

import codecs
from pathlib import Path

from bayesfric.errors import DataError

__all__ = ["DataError", "read_file", "decode_utf8", "decode_position", "shorten"]


def read_file(path: Path, what: str = "file") -> bytes:
    """The bytes of an existing regular file; a folder, a pipe or an unreadable file is a DataError.

    A pipe or device is refused before reading: reading it could block forever or never end.
    """
    if path.is_dir():
        raise DataError(f"{path}: is a folder, not a {what}")
    if not path.is_file():
        raise DataError(f"{path}: not a regular file (a pipe or device?); the {what} must be a plain file")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise DataError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None


def decode_utf8(data: bytes) -> str:
    """Decode UTF-8 with or without a byte-order mark (the BOM is dropped).

    Raises
    ------
    UnicodeDecodeError
        With ``start`` counted from the start of ``data`` (BOM included), unlike the
        ``utf-8-sig`` codec, which counts from after the BOM.
    """
    bom = len(codecs.BOM_UTF8) if data.startswith(codecs.BOM_UTF8) else 0
    try:
        return data[bom:].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UnicodeDecodeError(exc.encoding, data, exc.start + bom, exc.end + bom, exc.reason) from None


def decode_position(data: bytes, exc: UnicodeDecodeError) -> str:
    """Where ``data`` failed to decode, for a one-line message: ``"line 3, byte 41 (0xb0)"``.

    ``line`` counts every line of the file from 1; ``byte`` is the 0-based offset in the file.
    """
    line = data.count(b"\n", 0, exc.start) + 1
    value = f" (0x{data[exc.start]:02x})" if exc.start < len(data) else ""
    return f"line {line}, byte {exc.start}{value}"


def shorten(text: str, limit: int = 40) -> str:
    """``repr`` of a cell or name for a message, cut to about ``limit`` characters."""
    return repr(text) if len(text) <= limit else repr(text[:limit]) + "..."
