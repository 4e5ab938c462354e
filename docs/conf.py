"""Sphinx configuration: the API reference from the docstrings."""

from adcs.provenance import version as _version

project = "adcs-toolbox"
author = "The adcs-toolbox developers"
release = _version()
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "myst_parser"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build"]
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
# toolbox's own, documented once (adcs_common.exceptions)
suppress_warnings = ["myst.xref_missing", "ref.python"]
html_theme = "alabaster"
