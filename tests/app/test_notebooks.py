"""Every notebook is committed without outputs and executes with small
settings (ADCS_NOTEBOOK_SMALL=1).

The execution is the documentation build's (`test_docs.py`,
``test_docs_build_without_warnings``): Sphinx runs every notebook with
the small settings and fails on a cell's error (myst-nb,
``nb_execution_raise_on_error``), and each notebook gets its page with
its figures. Executing them here as well ran each twice in one CI run.
"""

from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")

NOTEBOOKS = sorted((Path(__file__).resolve().parents[2] / "notebooks")
                   .glob("*.ipynb"))
CONF = Path(__file__).resolve().parents[2] / "docs" / "conf.py"


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 3


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_committed_without_outputs(path):
    book = nbformat.read(path, as_version=4)
    assert all(not c.get("outputs") for c in book.cells
               if c.cell_type == "code"), "commit notebooks without outputs"


def test_the_docs_build_executes_the_notebooks_and_fails_on_an_error():
    """What this file leaves to the documentation build: every notebook
    executed (not from a cache), a cell's error failing the build."""
    text = CONF.read_text()
    assert 'nb_execution_mode = "force"' in text
    assert "nb_execution_raise_on_error = True" in text
