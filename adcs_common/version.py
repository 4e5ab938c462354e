"""The toolbox's version, one source for every package's ``__version__``.

The installed distribution's (``adcs-toolbox``, `importlib.metadata`);
in a source tree that is not installed, the ``version`` of the
``pyproject.toml`` beside the packages; else ``"unknown"``.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

__all__ = ["DISTRIBUTION", "version"]

#: The distribution the packages ship in.
DISTRIBUTION = "adcs-toolbox"


def _source_version() -> str | None:
    """``project.version`` of the source tree's pyproject.toml, or None."""
    try:
        import tomllib
    except ImportError:          # Python 3.10: no TOML reader to hand
        return None
    path = Path(__file__).resolve().parents[1] / "pyproject.toml"
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    found = data.get("project", {}).get("version")
    return found if isinstance(found, str) else None


def version() -> str:
    """Return the toolbox's version (``"unknown"`` if nothing says)."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return _source_version() or "unknown"
