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


def _notebook_sources(folder: Path) -> list[Path]:
    """Each notebook's code cells as one module (magics and shell lines
    dropped), written into ``folder``."""
    import json

    out = []
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(nb.read_text())["cells"]
        code = ["\n".join(line for line in "".join(c["source"]).splitlines()
                          if not line.lstrip().startswith(("%", "!")))
                for c in cells if c["cell_type"] == "code"]
        path = folder / f"nb_{nb.stem.replace('-', '_')}.py"
        path.write_text("\n\n".join(code) + "\n")
        out.append(path)
    return out


def test_the_notebooks_code_type_checks(tmp_path):
    files = _notebook_sources(tmp_path)
    assert len(files) >= 10
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", *map(str, files), "--cache-dir",
         str(tmp_path / "cache")],
        cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:]
