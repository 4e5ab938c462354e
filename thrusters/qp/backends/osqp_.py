"""Persistent OSQP backend: set up once, update q, l, u, warm start."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..problem import DutyCycleQP

#: Tolerances set by default (SOLVER_NOTES: OSQP at its default
#: tolerances fires both engines of an opposed pair). eps 1e-6 with
#: polishing is exact to the reference (polishing solves the KKT system of
#: the detected active set; measured on 150 random cycles: error < 1e-11,
#: while 1e-4 misses 12 of them); 1e-9 sometimes runs to max_iter after a
#: warm start from a very different cycle (hence the cold restart).
DEFAULTS = {"eps_abs": 1e-6, "eps_rel": 1e-6, "polishing": True,
            "max_iter": 20000, "warm_starting": True, "verbose": False}


class Backend:
    """OSQP object kept across cycles (OSQP form: ``l <= [A; I] x <= u``)."""

    def __init__(self, qp: DutyCycleQP, plugin: str, options: dict) -> None:
        import osqp

        self.qp = qp
        settings = {**DEFAULTS, **options}
        A_full = np.vstack([qp.A, np.eye(qp.nx)])
        self._solver = osqp.OSQP()
        q, l, u = qp.vectors(np.zeros(qp.Lm.shape[1]))
        self._solver.setup(sp.csc_matrix(np.triu(qp.P)), q,
                           sp.csc_matrix(A_full), *self._full(l, u),
                           **settings)
        self._solved = {int(osqp.SolverStatus.OSQP_SOLVED),
                        int(osqp.SolverStatus.OSQP_SOLVED_INACCURATE)}
        self._infeasible = {
            int(osqp.SolverStatus.OSQP_PRIMAL_INFEASIBLE),
            int(osqp.SolverStatus.OSQP_PRIMAL_INFEASIBLE_INACCURATE)}
        self.settings = settings

    def set_upper(self, ub: np.ndarray) -> None:
        """Change the variables' upper bounds (n+1,) for the next solves."""
        self._ub = np.array(ub, dtype=float)

    def _full(self, l, u):
        ub = getattr(self, "_ub", self.qp.ub)
        return (np.concatenate([l, self.qp.lb]), np.concatenate([u, ub]))

    def solve(self, theta: np.ndarray):
        """Return ``(x, status, None)``, status solved/infeasible/failed."""
        q, l, u = self.qp.vectors(theta)
        lf, uf = self._full(l, u)
        self._solver.update(q=q, l=lf, u=uf)
        res = self._solver.solve(raise_error=False)
        code = int(res.info.status_val)
        if code not in self._solved and code not in self._infeasible:
            # cold restart once: a warm start from a very different cycle
            # can stall ADMM
            self._solver.warm_start(x=np.zeros(self.qp.nx),
                                    y=np.zeros(lf.size))
            res = self._solver.solve(raise_error=False)
            code = int(res.info.status_val)
        if code in self._solved:
            return np.asarray(res.x, dtype=float), "solved", None
        if code in self._infeasible:
            return None, "infeasible", None
        return None, "failed", None
