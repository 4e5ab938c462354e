"""Built-in spacecraft, each a TOML file shipped inside the package."""

from __future__ import annotations

import os
import stat
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from .definition import Spacecraft, SpacecraftFileError
from .toml_io import MAX_FILE_BYTES, spacecraft_from_toml

if TYPE_CHECKING:
    from importlib.resources.abc import Traversable

__all__ = ["list_spacecraft", "load_spacecraft", "spacecraft_toml"]

_PACKAGE = "ocp.spacecraft.catalogue"


def _catalogue() -> dict[str, Traversable]:
    files = resources.files(_PACKAGE)
    return {f.name[:-5]: f for f in files.iterdir()
            if f.name.endswith(".toml")}


def list_spacecraft() -> dict[str, str]:
    """Names of the built-in spacecraft and their one-line summaries."""
    return {name: load_spacecraft(name).description
            for name in sorted(_catalogue())}


def spacecraft_toml(name_or_path) -> str:
    """Return the TOML text of a built-in (by name) or of a file (path).

    Raises
    ------
    SpacecraftFileError
        Neither a built-in name nor a readable file: not a regular file
        (a FIFO or device) or over `MAX_FILE_BYTES` (1 MiB) is refused.
    """
    if isinstance(name_or_path, Spacecraft):
        return name_or_path.to_toml()
    if not isinstance(name_or_path, (str, Path)):
        raise SpacecraftFileError(repr(name_or_path), "", (
            "a spacecraft is a catalogue name or a TOML file path"))
    entry = _catalogue().get(str(name_or_path).lower())
    if entry is not None:
        return entry.read_text(encoding="utf-8")
    p = Path(name_or_path)
    if p.suffix != ".toml" and not p.exists():
        raise SpacecraftFileError(str(name_or_path), "", (
            "no built-in spacecraft of that name and no such file; "
            f"built-ins: {', '.join(sorted(_catalogue()))}"))
    try:
        return _read_regular(p).decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SpacecraftFileError(str(p), "", f"cannot be read ({exc})") \
            from None


def _read_regular(p: Path) -> bytes:
    """The bytes of ``p``: a regular file of at most `MAX_FILE_BYTES`.

    Opened without blocking (a FIFO would wait for a writer) and checked
    on the open descriptor, so a file swapped after a check is caught; a
    device (``/dev/zero``) or FIFO is refused, and never more than the
    cap plus one byte is read.
    """
    fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
                 | getattr(os, "O_NOCTTY", 0))
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise SpacecraftFileError(str(p), "", (
                "is not a regular file (a FIFO, device or socket); a "
                "spacecraft is read from a regular TOML file"))
        if st.st_size > MAX_FILE_BYTES:
            raise SpacecraftFileError(str(p), "", (
                f"is {st.st_size} bytes; a spacecraft file holds at most "
                f"{MAX_FILE_BYTES} bytes"))
        data = fh.read(MAX_FILE_BYTES + 1)
    if len(data) > MAX_FILE_BYTES:
        raise SpacecraftFileError(str(p), "", (
            f"holds more than {MAX_FILE_BYTES} bytes (the limit of a "
            "spacecraft file)"))
    return data


def load_spacecraft(name_or_path: str | os.PathLike[str] | Spacecraft
                    ) -> Spacecraft:
    """Load a built-in spacecraft by name, or one from a TOML file.

    Parameters
    ----------
    name_or_path : str, pathlib.Path or Spacecraft
        A catalogue name (`list_spacecraft`, case-insensitive), a path to
        a TOML file (schema in ``docs/spacecraft.md``), or a `Spacecraft`
        (returned as it is).

    Raises
    ------
    SpacecraftFileError
        Unknown name, unreadable file, or a file that breaks the schema
        (the message names the key).
    """
    if isinstance(name_or_path, Spacecraft):
        return name_or_path
    text = spacecraft_toml(name_or_path)
    known = str(name_or_path).lower() in _catalogue()
    source = f"built-in {name_or_path!s}" if known else str(name_or_path)
    return spacecraft_from_toml(text, source)
