"""The documentation site builds without a warning (Sphinx, -W).

The build executes the notebooks (small settings), so the site shows
their figures while the repository keeps them without outputs.
"""

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx", reason='the docs extra: pip install -e '
                    '".[docs]"')
pytest.importorskip("myst_nb", reason="the docs extra")

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.mark.slow
def test_docs_build_without_warnings(tmp_path):
    run = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html",
         "-q", str(DOCS), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    api = (tmp_path / "html" / "api.html").read_text()
    for name in ("QPAllocator", "DutyCycleAllocator", "AttitudeMPC",
                 "export_c", "run_bench"):
        assert name in api
    # the notebooks are executed by the build: their pages carry figures
    pages = sorted((tmp_path / "html" / "notebooks").glob("*.html"))
    assert len(pages) >= 12
    assert len(list((tmp_path / "html" / "_images").glob("*.png"))) >= 10
