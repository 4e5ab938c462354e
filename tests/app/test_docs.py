"""The documentation site builds without a warning (Sphinx, -W), and its
API reference documents every public name.

The build executes the notebooks (small settings), so the site shows
their figures while the repository keeps them without outputs. The API
page alone builds in seconds: every name of every package's ``__all__``
has its anchor there (its object documented, or a module's section).
"""

import importlib
import os
import pkgutil
import re
import subprocess
import sys
import types
from pathlib import Path

import pytest

pytest.importorskip("sphinx", reason='the docs extra: pip install -e '
                    '".[docs]"')
pytest.importorskip("myst_nb", reason="the docs extra")

DOCS = Path(__file__).resolve().parents[2] / "docs"
TOP_LEVEL = ("adcs_common", "allocation", "thrusters", "ocp", "adcs")


def _public_names() -> list[tuple[str, str]]:
    """(package, name) of every package's ``__all__``, subpackages too."""
    found = []
    for top in TOP_LEVEL:
        root = importlib.import_module(top)
        for name in [top] + [i.name for i in pkgutil.walk_packages(
                root.__path__, top + ".") if i.ispkg]:
            package = importlib.import_module(name)
            found += [(name, n) for n in getattr(package, "__all__", [])]
    return found


def _resolve(path: str):
    """The object an anchor ``a.b.C.m`` names (attributes before
    submodules: ``allocation.envelope`` is the function)."""
    parts = path.split(".")
    obj = importlib.import_module(parts[0])
    for i, part in enumerate(parts[1:], 1):
        if hasattr(obj, part):
            obj = getattr(obj, part)
            continue
        try:
            obj = importlib.import_module(".".join(parts[:i + 1]))
        except ImportError:
            return None
    return obj


def _undocumented(html: str) -> list[str]:
    """``package.name`` of every public name without an anchor in
    ``html`` (its object's description, or its module's section)."""
    anchors = set(re.findall(r'<dt class="sig sig-object py" id="([^"]+)"',
                             html))
    documented = {id(_resolve(a)) for a in anchors}
    modules = set(re.findall(r'id="module-([^"]+)"', html))
    missing = []
    for package, name in _public_names():
        obj = getattr(importlib.import_module(package), name)
        if isinstance(obj, types.ModuleType):
            ok = obj.__name__ in modules
        else:
            ok = id(obj) in documented
        if not ok:
            missing.append(f"{package}.{name}")
    return missing


def _dead_links(site: Path) -> list[str]:
    """Links of the built pages that name no file or no anchor of theirs
    (``href="#../docs/references.md"`` was one: a page link the build
    could not resolve)."""
    dead = []
    ids: dict[Path, set[str]] = {}
    for page in sorted(site.rglob("*.html")):
        for href in re.findall(r'href="([^"]+)"', page.read_text()):
            if re.match(r"^[a-z][a-z0-9+.-]*:", href) or href.startswith(
                    ("//", "?")):
                continue
            file, _, anchor = href.split("?")[0].partition("#")
            target = (page.parent / file).resolve() if file else page
            if not target.exists():
                dead.append(f"{page.name}: {href}")
            elif anchor and target.suffix == ".html":
                if target not in ids:
                    ids[target] = set(re.findall(r'id="([^"]+)"',
                                                 target.read_text()))
                if anchor not in ids[target]:
                    dead.append(f"{page.name}: {href}")
    return dead


def test_the_public_names_are_all_there_to_check():
    names = _public_names()
    assert len(names) > 300
    for entry in (("ocp.spacecraft", "Spacecraft"),
                  ("ocp.spacecraft", "load_spacecraft"),
                  ("ocp.spacecraft", "SpacecraftFileError"),
                  ("adcs", "__version__"), ("allocation", "methods")):
        assert entry in names


def test_api_page_documents_every_public_name(tmp_path):
    """The API page alone (no notebooks), with -W: every public name,
    Spacecraft and load_spacecraft among them."""
    src = tmp_path / "src"
    src.mkdir()
    text = (DOCS / "api.rst").read_text()
    try:
        importlib.import_module("adcs.basilisk.modules")
    except Exception:        # Basilisk not installed: its modules aside
        text = re.sub(r"\.\. automodule:: adcs\.basilisk\..*?\n\n", "",
                      text + "\n", flags=re.S)
    (src / "api.rst").write_text(text)
    (src / "conf.py").write_text(
        "import sys\n"
        f"sys.path.insert(0, {str(DOCS / '_ext')!r})\n"
        "root_doc = 'api'\n"
        "extensions = ['sphinx.ext.autodoc', 'sphinx.ext.napoleon', "
        "'public_api']\n"
        "napoleon_numpy_docstring = True\n"
        "napoleon_google_docstring = False\n"
        "napoleon_use_rtype = False\n"
        "autodoc_member_order = 'bysource'\n"
        "autodoc_typehints = 'none'\n"
        "default_role = 'literal'\n"
        "suppress_warnings = ['ref.python']\n")
    run = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html",
         "-q", str(src), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    html = (tmp_path / "html" / "api.html").read_text()
    assert _undocumented(html) == []
    for anchor in ("ocp.spacecraft.Spacecraft",
                   "ocp.spacecraft.load_spacecraft",
                   "ocp.spacecraft.SpacecraftFileError"):
        assert f'id="{anchor}"' in html


@pytest.mark.slow
def test_docs_build_without_warnings(tmp_path):
    # the notebooks run with their small settings (the tests' executions
    # of the notebooks are these: test_notebooks.py)
    env = {**os.environ, "ADCS_NOTEBOOK_SMALL": "1", "MPLBACKEND": "Agg"}
    run = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html",
         "-q", str(DOCS), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=900, env=env)
    assert run.returncode == 0, run.stderr[-3000:]
    # a quiet log: no kernel's transport warning, no warning at all
    assert "WARNING" not in run.stderr, run.stderr[-3000:]
    # the executed notebooks land beside the output folder: with the
    # README's command that is docs/_build/, not the tracked tree
    assert (tmp_path / "jupyter_execute").is_dir()
    readme = (DOCS.parent / "README.md").read_text()
    assert "python -m sphinx docs\n  docs/_build/html`" in readme
    api = (tmp_path / "html" / "api.html").read_text()
    for name in ("QPAllocator", "DutyCycleAllocator", "AttitudeMPC",
                 "export_c", "run_bench"):
        assert name in api
    assert _undocumented(api) == []
    assert _dead_links(tmp_path / "html") == []
    # the notebooks are executed by the build: their pages carry figures
    pages = sorted((tmp_path / "html" / "notebooks").glob("*.html"))
    assert {p.stem for p in pages} >= {p.stem for p in (
        DOCS.parent / "notebooks").glob("*.ipynb")}
    assert len(pages) >= 12
    assert len(list((tmp_path / "html" / "_images").glob("*.png"))) >= 10
