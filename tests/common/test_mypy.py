"""The public packages type-check: mypy (settings in pyproject.toml) finds
no error in adcs_common, allocation, thrusters, ocp and adcs."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(
    shutil.which("mypy") is None and not (
        Path(sys.executable).parent / "mypy").exists(),
    reason="mypy is not installed (pip install -e '.[test]')")


def test_the_packages_type_check_at_zero_errors(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "adcs_common", "allocation",
         "thrusters", "ocp", "adcs", "--cache-dir", str(tmp_path / "cache")],
        cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert "Success: no issues found" in proc.stdout
