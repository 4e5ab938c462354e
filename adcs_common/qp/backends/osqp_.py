"""OSQP kept across calls: set up once, updated and warm-started.

OSQP's default tolerances are too loose for allocation (answers off by
up to 0.1-0.2 in duty, both engines of an opposed pair fired): the
defaults here are eps 1e-9 with polishing; an allocator may override
them. A run of degenerate problems can stall ADMM after a warm start, so
a failed solve is tried once more from a fresh setup.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from ..problem import QP
from ..solution import QPSolution

DEFAULTS: dict[str, Any] = {
    "eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True,
    "max_iter": 20000, "verbose": False, "eps_prim_inf": 1e-10,
    "eps_dual_inf": 1e-10}
#: OSQP's own infinity.
_INF = 1e30


class Backend:
    """OSQP with a dense sparsity pattern, updated on every call."""

    def __init__(self, plugin: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any]) -> None:
        import osqp

        self._osqp = osqp
        self.name = "osqp"
        self.n, self.k = n, k
        settings = {**DEFAULTS, **options}
        #: take OSQP's "solved inaccurate" points as solved (the caller
        #: checks every point's residual itself)
        self.accept_inaccurate = bool(settings.pop("accept_inaccurate",
                                                   False))
        self.settings = settings
        iu = np.triu_indices(n)
        self._p_pattern = sp.csc_matrix(
            (np.ones(len(iu[0])), iu), shape=(n, n))
        rows, cols = np.indices((k + n, n))
        self._a_pattern = sp.csc_matrix(
            (np.ones(rows.size), (rows.ravel(), cols.ravel())),
            shape=(k + n, n))
        self._p_order = self._order(self._p_pattern)
        self._a_order = self._order(self._a_pattern)
        self._solver: Any = None          # an osqp.OSQP once set up
        self._px: np.ndarray | None = None
        self._ax: np.ndarray | None = None
        self._P_obj: np.ndarray | None = None
        self._C_obj: np.ndarray | None = None
        S = osqp.SolverStatus
        self._solved = {int(S.OSQP_SOLVED)}
        if self.accept_inaccurate:
            self._solved.add(int(S.OSQP_SOLVED_INACCURATE))
        self._infeasible = {int(S.OSQP_PRIMAL_INFEASIBLE),
                            int(S.OSQP_PRIMAL_INFEASIBLE_INACCURATE)}

    @staticmethod
    def _order(pattern: sp.csc_matrix) -> tuple[np.ndarray, np.ndarray]:
        cols = np.repeat(np.arange(pattern.shape[1]), np.diff(pattern.indptr))
        return pattern.indices, cols

    def _setup(self, px, ax, q, l_all, u_all) -> None:
        self._solver = self._osqp.OSQP()
        P = self._p_pattern.copy()
        P.data = px
        A = self._a_pattern.copy()
        A.data = ax
        self._solver.setup(P=P, q=q, A=A, l=l_all, u=u_all, **self.settings)
        self._px, self._ax = px, ax

    def solve(self, qp: QP) -> QPSolution:
        """Solve one QP, warm-started from the previous call."""
        if qp.P is self._P_obj and qp.C is self._C_obj:
            px, ax = self._px, self._ax      # the same matrices as before
        else:
            full = np.vstack([qp.C, np.eye(self.n)])
            px = qp.P[self._p_order]
            ax = full[self._a_order]
            self._P_obj, self._C_obj = qp.P, qp.C
        assert px is not None and ax is not None   # set with _P_obj
        l_all = np.clip(np.concatenate([qp.l, qp.lb]), -_INF, _INF)
        u_all = np.clip(np.concatenate([qp.u, qp.ub]), -_INF, _INF)
        fresh = self._solver is None
        if fresh:
            self._setup(px, ax, qp.q, l_all, u_all)
        else:
            assert self._px is not None and self._ax is not None
            change = {}
            if px is not self._px and not np.array_equal(px, self._px):
                change["Px"] = px
            if ax is not self._ax and not np.array_equal(ax, self._ax):
                change["Ax"] = ax
            self._solver.update(q=qp.q, l=l_all, u=u_all, **change)
            self._px, self._ax = px, ax
        res = self._solver.solve(raise_error=False)
        code = int(res.info.status_val)
        if code not in self._solved and code not in self._infeasible \
                and not fresh:
            self._setup(px, ax, qp.q, l_all, u_all)
            res = self._solver.solve(raise_error=False)
            code = int(res.info.status_val)
        status = ("solved" if code in self._solved else "infeasible"
                  if code in self._infeasible else "failed")
        x = np.array(res.x, dtype=float) if status == "solved" else None
        return QPSolution(x, status == "solved", status,
                          int(res.info.iter),
                          extras={"backend_status": str(res.info.status)})
