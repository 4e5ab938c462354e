"""The API reference of every public name, generated from the ``__all__``s.

`api_rst` walks every package of the toolbox (the top-level ones, then
their subpackages) and writes, for each name of its ``__all__``, the
directive that documents it: ``autoclass``, ``autoexception``,
``autofunction``, or ``py:data`` with the ``#:`` comment of the module
that defines it. An object exported by several packages is documented
once, under the first in `PACKAGES` order; the others link to it. The
Sphinx extension (`setup`) puts the text where ``api.rst`` has the line
``.. public-api::``; ``tests/app/test_docs.py`` checks every name's
anchor in the built page.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import sys
import types

#: The top-level packages, in the page's order.
TOP_LEVEL = ("adcs_common", "allocation", "thrusters", "ocp", "adcs")

#: The line of ``api.rst`` the generated text replaces.
MARKER = ".. public-api::"


def packages() -> list[str]:
    """Every package with an ``__all__``: each top-level one, then its
    subpackages (importable ones: ``adcs.basilisk``'s modules need
    Basilisk, its package does not)."""
    found = []
    for top in TOP_LEVEL:
        module = importlib.import_module(top)
        names = [top] + sorted(
            info.name for info in pkgutil.walk_packages(
                module.__path__, top + ".") if info.ispkg)
        for name in names:
            if hasattr(importlib.import_module(name), "__all__"):
                found.append(name)
    return found


def public_names() -> list[tuple[str, str]]:
    """``(package, name)`` for every name of every package's ``__all__``."""
    return [(p, n) for p in packages()
            for n in importlib.import_module(p).__all__]


def _doc_comment(obj: object, name: str, top: str) -> list[str]:
    """The ``#:`` comment above ``name``'s assignment, in the module of
    ``top`` that defines it (Sphinx's analyzer), or []."""
    from sphinx.pycode import ModuleAnalyzer

    for modname, module in sorted(sys.modules.items()):
        if not (modname == top or modname.startswith(top + ".")) or (
                getattr(module, name, None) is not obj):
            continue
        try:
            docs = ModuleAnalyzer.for_module(modname).find_attr_docs()
        except Exception:           # no source (a compiled module)
            continue
        if ("", name) in docs:
            return [line for line in docs["", name] if line.strip()]
    return []


def _directive(package: str, name: str, obj: object) -> list[str]:
    """The reST that documents ``package.name``."""
    path = f"{package}.{name}"
    if inspect.isclass(obj):
        kind = ("autoexception" if issubclass(obj, BaseException)
                else "autoclass")
        lines = [f".. {kind}:: {path}", "   :members:"]
        # named-tuple and dataclass fields: their docstring's Attributes
        # section documents them (autodoc would describe them again)
        fields = list(getattr(obj, "_fields", ())) or (
            [f.name for f in dataclasses.fields(obj)]
            if dataclasses.is_dataclass(obj) else [])
        if fields:
            lines.append(f"   :exclude-members: {', '.join(fields)}")
        return lines + [""]
    if inspect.isroutine(obj):
        return [f".. autofunction:: {path}", ""]
    lines = [f".. py:data:: {name}"]         # in the package's py:module
    value = repr(obj)
    if isinstance(obj, (bool, int, float, str, tuple)) and len(value) < 70:
        lines.append(f"   :value: {value}")
    doc = _doc_comment(obj, name, package.split(".")[0])
    return lines + [""] + [f"   {line}" for line in doc] + [""]


def api_rst() -> str:
    """The reST of every package's public names (`PACKAGES` order)."""
    home: dict[int, str] = {}
    out: list[str] = []
    for package in packages():
        module = importlib.import_module(package)
        title = f"``{package}``"
        out += [title, "-" * len(title), "", f".. py:module:: {package}",
                ""]
        summary = (inspect.getdoc(module) or "").split("\n\n")[0]
        out += [summary, ""] if summary else []
        also = []
        for name in module.__all__:
            obj = getattr(module, name)
            if isinstance(obj, types.ModuleType):
                also.append(f"``{name}``: the package :py:mod:`{obj.__name__}`")
            elif id(obj) in home:
                also.append(f"``{name}``: :py:obj:`{home[id(obj)]}`")
            else:
                home[id(obj)] = f"{package}.{name}"
                out += _directive(package, name, obj)
        if also:
            out += ["Also exported here:", ""] + [f"* {a}" for a in also]
            out.append("")
    return "\n".join(out)


def _source_read(app, docname: str, source: list[str]) -> None:
    if docname == "api" and MARKER in source[0]:
        source[0] = source[0].replace(MARKER, api_rst())


def setup(app):
    """Register the ``api`` page's generation."""
    app.connect("source-read", _source_read)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
