"""A CasADi ``conic`` plugin (the solvers CasADi can generate C for).

The conic is built once per problem size with dense sparsity; each call
passes the numeric data. ``qrqp`` can report success on a point that
violates constraints (seen on a few random allocations, by up to 0.01):
the allocators check every point they get.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ..problem import QP
from ..solution import QPSolution

#: Options set per plugin unless the caller overrides them.
DEFAULTS: dict[str, dict[str, Any]] = {
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False,
             "error_on_fail": False},
    # DAQP's default primal_tol (1e-6) leaves equality rows off by up to
    # ~3e-5; 1e-10 is exact to the references
    "daqp": {"daqp": {"primal_tol": 1e-10}, "error_on_fail": False},
    "osqp": {"osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True,
                      "verbose": False, "max_iter": 20000},
             "error_on_fail": False},
}


def plugin_options(plugin: str, options: dict[str, Any]) -> dict[str, Any]:
    """``DEFAULTS[plugin]`` with ``options`` merged over it."""
    from ...options import merge_options

    return merge_options(DEFAULTS.get(plugin, {"error_on_fail": False}),
                         options)


def dense_conic(name: str, plugin: str, n: int, k: int,
                options: dict[str, Any]) -> ca.Function:
    """``casadi.conic`` of ``plugin`` for dense (n, n) H and (k, n) A."""
    return ca.conic(name, plugin, {"h": ca.Sparsity.dense(n, n),
                                   "a": ca.Sparsity.dense(k, n)},
                    plugin_options(plugin, options))


class Backend:
    """A ``casadi.conic`` solver called with numpy data."""

    def __init__(self, plugin: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any]) -> None:
        self.name = f"casadi:{plugin}"
        self.solver = dense_conic("qp", plugin, n, k, options)

    def solve(self, qp: QP) -> QPSolution:
        """Solve one QP."""
        sol = self.solver(h=qp.P, g=qp.q, a=qp.C, lba=qp.l, uba=qp.u,
                          lbx=qp.lb, ubx=qp.ub)
        stats = self.solver.stats()
        found = bool(stats.get("success", False))
        x = np.array(sol["x"], dtype=float).ravel()
        found = found and bool(np.all(np.isfinite(x)))
        return QPSolution(x if found else None, found,
                          "solved" if found else "failed",
                          int(stats.get("iter_count", -1) or -1),
                          extras={"backend_status":
                                  str(stats.get("return_status", ""))})
