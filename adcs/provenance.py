"""How a report (or a benchmark) was made: date, versions, commit, machine."""

from __future__ import annotations

import datetime as _dt
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

from adcs_common.version import version as _version

__all__ = ["provenance", "version"]

#: Packages whose versions a report records.
PACKAGES = ("adcs-toolbox", "casadi", "numpy", "scipy", "daqp", "osqp",
            "qpsolvers")


def version() -> str:
    """Return the toolbox's version (`adcs_common.version.version`)."""
    return _version()


def _git_commit() -> str | None:
    root = Path(__file__).resolve().parents[1]
    if not (root / ".git").exists():
        return None
    try:
        out = subprocess.run(["git", "-C", str(root), "rev-parse",
                              "--short", "HEAD"], capture_output=True,
                             text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip() or None


def provenance(seconds: float | None = None) -> list[tuple[str, str]]:
    """Rows ``(item, value)``: date, versions, git commit, machine, time."""
    rows = [("date (UTC)", _dt.datetime.now(_dt.timezone.utc)
             .strftime("%Y-%m-%d %H:%M:%S"))]
    for name in PACKAGES:
        try:
            rows.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            rows.append((name, "not installed"))
    rows.append(("python", platform.python_version()))
    rows.append(("git commit", _git_commit() or "not a git checkout"))
    rows.append(("machine", f"{platform.system()} {platform.machine()}, "
                 f"{os.cpu_count()} cores"))
    if seconds is not None:
        rows.append(("run time", f"{seconds:.1f} s"))
    return rows
