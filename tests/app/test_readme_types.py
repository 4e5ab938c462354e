"""The README's Python tour type-checks: mypy finds the toolbox typed
(``py.typed`` in every top-level package, shipped as package data) and
reports zero errors on the tour's calls (e.g. ``time_optimal_slew(sc,
...)`` with a `Spacecraft`)."""

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("adcs", "adcs_common", "allocation", "thrusters", "ocp")


def test_every_package_is_marked_typed_and_ships_the_marker():
    for name in PACKAGES:
        assert (ROOT / name / "py.typed").is_file(), name
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    package_data = data["tool"]["setuptools"]["package-data"]
    for name in PACKAGES:
        assert "py.typed" in package_data.get(name, []) + package_data.get(
            "*", []), name


def _tour() -> str:
    blocks = re.findall(r"```python\n(.*?)```",
                        (ROOT / "README.md").read_text(), re.S)
    assert blocks, "the README has no Python tour"
    return "\n".join(blocks)


def test_mypy_finds_no_error_in_the_readme_tour(tmp_path):
    pytest.importorskip("mypy")
    tour = tmp_path / "tour.py"
    tour.write_text(_tour())
    # the packages' own bodies are checked elsewhere: only the tour's
    # errors count here (as for a user of an installed, typed package)
    run = subprocess.run(
        [sys.executable, "-m", "mypy", "--follow-imports=silent",
         "--no-error-summary", "--cache-dir", str(tmp_path / "cache"),
         str(tour)],
        capture_output=True, text=True, timeout=600, cwd=tmp_path,
        env={"MYPYPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "error:" not in run.stdout, run.stdout
