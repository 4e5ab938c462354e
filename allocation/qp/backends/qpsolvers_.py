"""Any `qpsolvers` backend by name (set up again on every call).

Tolerances set unless the user overrides them in ``solver_options``:
OSQP ``eps_abs = eps_rel = 1e-9`` with polishing; ProxQP and PIQP
``eps_abs = 1e-9``, ``eps_rel = 0``; Clarabel gap and feasibility 1e-10.
Active-set solvers (daqp, quadprog) are exact and get nothing.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import qpsolvers
import scipy.sparse as sp

from . import BackendResult
from ..problem import QPData

TOLERANCES: dict[str, dict[str, Any]] = {
    "osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polish": True,
             "max_iter": 20000},
    "proxqp": {"eps_abs": 1e-9, "eps_rel": 0.0},
    "piqp": {"eps_abs": 1e-9, "eps_rel": 0.0},
    "clarabel": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10,
                 "tol_feas": 1e-10},
}


class QpsolversBackend:
    """Calls ``qpsolvers.solve_problem`` with this backend's tolerances."""

    def __init__(self, solver: str, n_eq: int,
                 options: dict[str, Any]) -> None:
        self.name = solver
        self.n_eq = n_eq
        self.options = {**TOLERANCES.get(solver, {}), **options}
        self.sparse = solver in qpsolvers.sparse_solvers and \
            solver not in qpsolvers.dense_solvers

    def solve(self, data: QPData) -> BackendResult:
        """Solve one QP."""
        e = self.n_eq
        G = data.C[e:] if data.C.shape[0] > e else None
        h = data.u[e:] if G is not None else None
        P, A_eq = data.P, data.C[:e]
        if self.sparse:
            P, A_eq = sp.csc_matrix(P), sp.csc_matrix(A_eq)
            G = None if G is None else sp.csc_matrix(G)
        problem = qpsolvers.Problem(
            P, data.q, G, h, A_eq, data.l[:e], data.lb, data.ub)
        sol = qpsolvers.solve_problem(problem, solver=self.name,
                                      **self.options)
        found = bool(sol.found) and sol.x is not None and bool(
            np.all(np.isfinite(sol.x)))
        return BackendResult(np.array(sol.x) if found else None, found,
                             "found" if found else "not found")


def make(solver: str, n: int, k: int, n_eq: int,
         options: dict[str, Any]) -> QpsolversBackend:
    """Build the qpsolvers backend ``solver``."""
    return QpsolversBackend(solver, n_eq, options)
