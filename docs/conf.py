"""Sphinx configuration: the pages, the notebooks and the API reference."""

import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from adcs.provenance import version as _version

os.environ.setdefault("ADCS_NOTEBOOK_SMALL", "1")
# the kernels draw inline so that the pages carry the figures (CI exports
# MPLBACKEND=Agg, which would draw nothing)
os.environ["MPLBACKEND"] = "module://matplotlib_inline.backend_inline"
# a quiet build log: each notebook's kernel would warn that its local TCP
# transport is not encrypted (the build's own kernels, on this machine);
# a private IPython directory (outside the tree) sets their log level
_ipython = Path(tempfile.mkdtemp(prefix="adcs-docs-ipython-"))
(_ipython / "profile_default").mkdir()
(_ipython / "profile_default" / "ipython_kernel_config.json").write_text(
    json.dumps({"IPKernelApp": {"log_level": "ERROR"}}))
os.environ["IPYTHONDIR"] = str(_ipython)
# the notebooks live at the top of the repository: copy them in. Their
# links to the pages are written for the repository (notebooks/ ->
# ../docs/x.md); in the copy, docs/notebooks/, the page is ../x.md
_here = Path(__file__).resolve().parent
shutil.copytree(_here.parent / "notebooks", _here / "notebooks",
                dirs_exist_ok=True,
                ignore=shutil.ignore_patterns(".ipynb_checkpoints"))
for _nb in (_here / "notebooks").glob("*.ipynb"):
    _text = _nb.read_text(encoding="utf-8")
    if "](../docs/" in _text:
        _nb.write_text(_text.replace("](../docs/", "](../"),
                       encoding="utf-8")

project = "adcs-toolbox"
author = "The adcs-toolbox developers"
release = _version()
# the API page's generator (docs/_ext/public_api.py)
sys.path.insert(0, str(_here / "_ext"))
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "myst_nb",
              "public_api"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb",
                 ".ipynb": "myst-nb"}
# the notebooks are executed by the build (small settings, as in the
# tests), so the site shows their plots; the repository keeps them
# without outputs
nb_execution_mode = "force"
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_output_stderr = "remove"
exclude_patterns = ["_build", "notebooks/.ipynb_checkpoints"]
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"
default_role = "literal"
myst_heading_anchors = 3
# every package re-exports the shared error types and several classes have
# a field named like another's (``n``): Sphinx then finds more than one
# target for a short name in a docstring and warns; the names are the
# toolbox's own, documented once (adcs_common.exceptions). Links between
# pages are not suppressed: a missing one fails the -W build
suppress_warnings = ["ref.python"]
html_theme = "alabaster"
