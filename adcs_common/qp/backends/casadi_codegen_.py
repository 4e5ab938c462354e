"""A CasADi conic exported to C, compiled and loaded (``casadi-c:qrqp``).

``Function.generate`` writes self-contained C for code-generatable
plugins (qrqp). The library is built once per problem size with the
system C compiler (`adcs_common.codegen`) in a private temporary folder,
loaded, and the folder removed. The generated code reports no status:
a point is "solved" when it is finite and keeps every constraint to 1e-6
(the allocators then check it their own way).
"""

from __future__ import annotations

import shutil
import tempfile
from typing import Any

import casadi as ca
import numpy as np

from ...codegen import compile_c, find_compiler, generate_c
from ..problem import QP, primal_residual
from ..solution import QPSolution
from .casadi_conic_ import dense_conic

#: Plugins whose generated C is self-contained.
PLUGINS = ("qrqp",)
#: Largest constraint violation of a "solved" point.
RESIDUAL_TOL = 1e-6


def available() -> bool:
    """Tell whether a C compiler is on PATH."""
    try:
        find_compiler()
    except Exception:
        return False
    return True


class Backend:
    """The conic as generated C, called through ``casadi.external``."""

    def __init__(self, plugin: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any]) -> None:
        self.name = f"casadi-c:{plugin}"
        conic = dense_conic("qp_conic", plugin, n, k, options)
        args = [ca.MX.sym(s, *shape) for s, shape in (
            ("h", (n, n)), ("g", (n, 1)), ("a", (k, n)), ("lba", (k, 1)),
            ("uba", (k, 1)), ("lbx", (n, 1)), ("ubx", (n, 1)))]
        x = conic(h=args[0], g=args[1], a=args[2], lba=args[3],
                  uba=args[4], lbx=args[5], ubx=args[6])["x"]
        fn = ca.Function("qp_c", args, [x])
        folder = tempfile.mkdtemp(prefix="adcs_qp_")
        try:
            src = generate_c([fn], folder, "qp_c")
            lib = compile_c([src], f"{folder}/qp_c.so", opt="-O2")
            self.function = ca.external("qp_c", str(lib))
        finally:
            # the library is loaded (dlopen): the folder can go
            shutil.rmtree(folder, ignore_errors=True)

    def solve(self, qp: QP) -> QPSolution:
        """Solve one QP with the compiled conic."""
        try:
            x = np.array(self.function(qp.P, qp.q, qp.C, qp.l, qp.u, qp.lb,
                                       qp.ub), dtype=float).ravel()
        except RuntimeError:   # the generated code returned an error code
            return QPSolution.failed(backend_status="evaluation failed")
        found = primal_residual(qp, x) <= RESIDUAL_TOL
        return QPSolution(x if found else None, found,
                          "solved" if found else "failed",
                          extras={"backend_status": "generated C"})
