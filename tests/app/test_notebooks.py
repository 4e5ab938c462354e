"""Every notebook executes with small settings (ADCS_NOTEBOOK_SMALL=1)."""

from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

NOTEBOOKS = sorted((Path(__file__).resolve().parents[2] / "notebooks")
                   .glob("*.ipynb"))


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 3


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes(path, monkeypatch, tmp_path):
    if "basilisk" in path.stem:
        pytest.importorskip("Basilisk", reason="Basilisk is an optional "
                            'extra: pip install -e ".[basilisk]"')
    monkeypatch.setenv("ADCS_NOTEBOOK_SMALL", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    book = nbformat.read(path, as_version=4)
    assert all(not c.get("outputs") for c in book.cells
               if c.cell_type == "code"), "commit notebooks without outputs"
    nbclient.NotebookClient(book, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}
                            ).execute()
    errors = [o for c in book.cells if c.cell_type == "code"
              for o in c.outputs if o.output_type == "error"]
    assert not errors
