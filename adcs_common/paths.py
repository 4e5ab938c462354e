"""Output folders: created when missing, refused with a clear error."""

from __future__ import annotations

import os
from pathlib import Path

from .exceptions import InvalidValueError

__all__ = ["output_folder"]


def output_folder(path, name: str = "out") -> Path:
    """Create (if needed) and return a writable folder ``path``.

    Raises
    ------
    InvalidValueError
        ``path`` is not a path, names an existing file, cannot be created
        or is not writable (the message names ``name``).
    """
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise InvalidValueError(
            f"{name} must be a folder path, got {path!r}")
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise InvalidValueError(f"{name}: {p} is a file, not a folder")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidValueError(
            f"{name}: cannot create folder {p} ({exc.strerror})") from None
    if not os.access(p, os.W_OK | os.X_OK):
        raise InvalidValueError(f"{name}: folder {p} is not writable")
    return p
