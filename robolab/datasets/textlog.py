"""Lines of a plain or gzip-compressed text data file, every failure a clear error.

The readers of text data sets (CARMEN logs, Freiburg course data, UTIAS MRCLAM) share
what can go wrong before a line is parsed: the path is a folder or missing, the bytes
are not text (a binary file given by mistake), or a ``.gz`` is truncated or corrupt.
Each is raised as the reader's own error class, naming the file (and line).
"""

from __future__ import annotations

import gzip
import zlib
from collections.abc import Iterator
from pathlib import Path

__all__ = ["data_folder", "text_lines"]

_GZIP_MAGIC = b"\x1f\x8b"


def text_lines(path: Path, error: type[Exception], what: str) -> Iterator[tuple[int, str]]:
    """``(lineno, line)`` of ``path``, plain UTF-8 text or gzip-compressed.

    Parameters
    ----------
    path : Path
    error : type
        The reader's error class (a ValueError), raised for bad content.
    what : str
        What the file should hold, for messages (``"CARMEN log"``).

    Raises
    ------
    FileNotFoundError
        When ``path`` does not exist.
    error
        When ``path`` is a folder, holds bytes that are not UTF-8 text, or is a
        truncated or corrupt gzip file.
    """
    path = Path(path)
    if path.is_dir():
        raise error(f"{path} is a folder, not the {what} file")
    if not path.is_file():
        raise FileNotFoundError(f"{what} file not found: {path}")
    with open(path, "rb") as fh:
        gz = fh.read(2) == _GZIP_MAGIC
    lineno = 0
    try:
        opened = gzip.open(path, "rt", encoding="utf-8") if gz else open(path, encoding="utf-8")
        with opened as fh:
            for lineno, line in enumerate(fh, 1):  # noqa: B007 - lineno says where it stopped
                yield lineno, line
    except UnicodeDecodeError as exc:
        raise error(
            f"{path}:{lineno + 1}: not a {what} file: bytes that are not UTF-8 text ({exc.reason})"
        ) from None
    except (EOFError, OSError, zlib.error) as exc:
        if not gz:
            raise
        raise error(
            f"{path}: the gzip-compressed {what} is truncated or corrupt after line {lineno} "
            f"({type(exc).__name__}: {exc or 'unexpected end of data'})"
        ) from None


def data_folder(folder: Path, error: type[Exception], what: str) -> Path:
    """``folder`` when it is one; FileNotFoundError when missing, ``error`` when a file."""
    folder = Path(folder)
    if not folder.exists():
        raise FileNotFoundError(f"{what} folder not found: {folder}")
    if not folder.is_dir():
        raise error(f"{folder} is a file; give the {what} folder that holds it")
    return folder
