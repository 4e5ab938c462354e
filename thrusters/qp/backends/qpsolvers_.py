"""Any installed qpsolvers backend, by name."""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from ..problem import DutyCycleQP

#: Backends that take sparse matrices (dense ones would be converted with
#: a warning on every call).
SPARSE = ("clarabel", "osqp", "scs", "highs", "piqp")

#: Tolerances set per qpsolvers backend (interior-point and ADMM solvers
#: must be tightened: at their defaults OSQP and ProxQP return duties off
#: by up to 0.1-0.2, SOLVER_NOTES). Active-set solvers (daqp, quadprog)
#: are exact at their defaults.
DEFAULTS = {
    "osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True,
             "max_iter": 200000},
    "proxqp": {"eps_abs": 1e-10, "eps_rel": 0.0},
    "piqp": {"eps_abs": 1e-12, "eps_rel": 1e-12},
    "clarabel": {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12,
                 "tol_feas": 1e-12},
    "cvxopt": {"abstol": 1e-11, "reltol": 1e-11, "feastol": 1e-11},
    "highs": {"primal_feasibility_tolerance": 1e-10,
              "dual_feasibility_tolerance": 1e-10},
    "scs": {"eps_abs": 1e-10, "eps_rel": 1e-10},
    "ecos": {"abstol": 1e-11, "reltol": 1e-11, "feastol": 1e-11},
}


class Backend:
    """qpsolvers ``solve_problem`` with the QP split into G, h, A, b."""

    def __init__(self, qp: DutyCycleQP, plugin: str, options: dict) -> None:
        import qpsolvers

        self._qpsolvers = qpsolvers
        self.qp = qp
        self.name = plugin
        self.settings = {**DEFAULTS.get(plugin, {}), **options}
        eq = np.arange(qp.A.shape[0]) < qp.n_eq
        self._up = qp.upper_rows & ~eq
        self._lo = qp.lower_rows & ~eq
        self._eq = eq
        self._G = np.vstack([qp.A[self._up], -qp.A[self._lo]])
        self._A = qp.A[eq]
        self._P = qp.P
        if plugin in SPARSE:
            self._P = sp.csc_matrix(qp.P)
            self._G = sp.csc_matrix(self._G)
            self._A = sp.csc_matrix(self._A)
        # the slack's upper bound is dropped: ProxQP fails on this QP with
        # any finite bound on it (measured), the others do not care
        self._ub = qp.ub.copy()
        self._ub[-1] = np.inf

    def set_upper(self, ub: np.ndarray) -> None:
        """Change the duties' upper bounds (the slack stays unbounded)."""
        self._ub[:-1] = ub[:-1]

    def solve(self, theta: np.ndarray):
        """Return ``(x, status, None)``; qpsolvers reports no infeasibility."""
        q, l, u = self.qp.vectors(theta)
        h = np.concatenate([u[self._up], -l[self._lo]])
        problem = self._qpsolvers.Problem(
            self._P, q, self._G, h, self._A, l[self._eq], self.qp.lb,
            self._ub)
        with warnings.catch_warnings():
            # failures are reported through the status, not warnings
            warnings.simplefilter("ignore")
            sol = self._qpsolvers.solve_problem(problem, solver=self.name,
                                                **self.settings)
        if sol.x is None or not sol.found:
            return None, "failed", None
        return np.asarray(sol.x, dtype=float), "solved", None
