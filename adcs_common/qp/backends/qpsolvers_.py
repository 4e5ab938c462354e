"""Any `qpsolvers` backend by name (the problem set up on every call).

Interior-point and ADMM solvers must be tightened to be exact on the
allocation QPs; the defaults here are those tolerances (active-set
solvers, daqp and quadprog, get none). An allocator may override them.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..problem import QP
from ..solution import QPSolution

DEFAULTS: dict[str, dict[str, Any]] = {
    "osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True,
             "max_iter": 20000},
    "proxqp": {"eps_abs": 1e-9, "eps_rel": 0.0},
    "piqp": {"eps_abs": 1e-9, "eps_rel": 0.0},
    "clarabel": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10,
                 "tol_feas": 1e-10},
    "cvxopt": {"abstol": 1e-11, "reltol": 1e-11, "feastol": 1e-11},
    "highs": {"primal_feasibility_tolerance": 1e-10,
              "dual_feasibility_tolerance": 1e-10},
    "scs": {"eps_abs": 1e-10, "eps_rel": 1e-10},
    "ecos": {"abstol": 1e-11, "reltol": 1e-11, "feastol": 1e-11},
}


def installed() -> tuple[str, ...]:
    """List the qpsolvers backends installed here."""
    try:
        import qpsolvers
    except ImportError:
        return ()
    return tuple(qpsolvers.available_solvers)


class Backend:
    """``qpsolvers.solve_problem`` with the rows split into G, h, A, b."""

    def __init__(self, plugin: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any]) -> None:
        import qpsolvers

        self._qpsolvers = qpsolvers
        self.name = f"qpsolvers:{plugin}"
        self.plugin = plugin
        self.settings = {**DEFAULTS.get(plugin, {}), **options}
        self.sparse = (plugin in qpsolvers.sparse_solvers
                       and plugin not in qpsolvers.dense_solvers)
        self._key: tuple[int, int, bytes, bytes] | None = None

    def _matrices(self, qp: QP, up: np.ndarray, lo: np.ndarray):
        """(P, A, G), rebuilt only when P, C or the one-sided rows change."""
        key = (id(qp.P), id(qp.C), up.tobytes(), lo.tobytes())
        if key != self._key:
            e = qp.n_eq
            C = qp.C[e:]
            P, A, G = qp.P, qp.C[:e], np.vstack([C[up], -C[lo]])
            if self.sparse:
                P, A, G = (sp.csc_matrix(P), sp.csc_matrix(A),
                           sp.csc_matrix(G))
            self._key, self._mats = key, (P, A, G)
            self._keep = (qp.P, qp.C)  # the ids stay theirs while kept
        return self._mats

    def solve(self, qp: QP) -> QPSolution:
        """Solve one QP."""
        e = qp.n_eq
        l, u = qp.l[e:], qp.u[e:]
        up, lo = np.isfinite(u), np.isfinite(l)
        h = np.concatenate([u[up], -l[lo]])
        P, A, G = self._matrices(qp, up, lo)
        problem = self._qpsolvers.Problem(
            P, qp.q, G if h.size else None, h if h.size else None,
            A if e else None, qp.l[:e] if e else None, qp.lb, qp.ub)
        with warnings.catch_warnings():
            # failures are reported through the status, not warnings
            warnings.simplefilter("ignore")
            sol = self._qpsolvers.solve_problem(problem, solver=self.plugin,
                                                **self.settings)
        found = (bool(sol.found) and sol.x is not None
                 and bool(np.all(np.isfinite(sol.x))))
        return QPSolution(np.array(sol.x, dtype=float) if found else None,
                          found, "solved" if found else "failed",
                          extras={"backend_status": "found" if found
                                  else "not found"})
