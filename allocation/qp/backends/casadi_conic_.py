"""CasADi ``conic`` backend (the form that code generation uses).

The conic is built once per problem size with dense sparsity; every call
passes the numeric data. ``qrqp`` can report success on a point that
violates constraints (seen on 4 of 1,500 random 4-7 wheel allocations with
momentum bounds, bound violations up to 0.01 N·m); the allocator checks
every returned point and raises `SolverError` for those.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from . import BackendResult
from ..problem import QPData

DEFAULTS: dict[str, dict[str, Any]] = {
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False,
             "error_on_fail": False},
    "daqp": {"error_on_fail": False},
    "osqp": {"osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polish": True,
                      "verbose": False, "max_iter": 20000},
             "error_on_fail": False},
}


class ConicBackend:
    """A ``casadi.conic`` solver with dense H and A."""

    def __init__(self, plugin: str, n: int, k: int,
                 options: dict[str, Any]) -> None:
        self.name = f"casadi:{plugin}"
        opts = {**DEFAULTS.get(plugin, {}), **options}
        self.solver = ca.conic("alloc_qp", plugin,
                               {"h": ca.Sparsity.dense(n, n),
                                "a": ca.Sparsity.dense(k, n)}, opts)

    def solve(self, data: QPData) -> BackendResult:
        """Solve one QP."""
        sol = self.solver(h=data.P, g=data.q, a=data.C, lba=data.l,
                          uba=data.u, lbx=data.lb, ubx=data.ub)
        stats = self.solver.stats()
        found = bool(stats.get("success", False))
        x = np.array(sol["x"]).ravel()
        return BackendResult(x if found else None, found,
                             str(stats.get("return_status", "")),
                             int(stats.get("iter_count", -1) or -1))


def make(plugin: str, n: int, k: int, n_eq: int,
         options: dict[str, Any]) -> ConicBackend:
    """Build the conic backend for ``plugin``."""
    return ConicBackend(plugin, n, k, options)
