"""A CasADi conic exported to C, compiled and loaded (``casadi-c:qrqp``).

``Function.generate`` writes self-contained C for code-generatable
plugins (qrqp). The library is built once per problem size with the
system C compiler (`adcs_common.codegen`) in a private temporary folder,
loaded, and the folder removed. As with the called conic, a finite point
is "solved" and the allocators check it.
"""

from __future__ import annotations

import shutil
import tempfile
from typing import Any

import casadi as ca

from ...codegen import compile_c, find_compiler, generate_c
from .casadi_conic_ import Backend as ConicBackend
from .casadi_conic_ import wrapped_conic

#: Plugins whose generated C is self-contained.
PLUGINS = ("qrqp",)


def available() -> bool:
    """Tell whether a C compiler is on PATH."""
    try:
        find_compiler()
    except Exception:
        return False
    return True


class Backend(ConicBackend):
    """The conic as generated C, called through ``casadi.external``."""

    def __init__(self, plugin: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any]) -> None:
        self.name = f"casadi-c:{plugin}"
        self.plugin = plugin
        fn = wrapped_conic(plugin, n, k, options)
        folder = tempfile.mkdtemp(prefix="adcs_qp_")
        try:
            src = generate_c([fn], folder, "qp_c")
            lib = compile_c([src], f"{folder}/qp_c.so", opt="-O2")
            self._bind(ca.external("qp_c", str(lib)), n, k)
        finally:
            # the library is loaded (dlopen): the folder can go
            shutil.rmtree(folder, ignore_errors=True)
