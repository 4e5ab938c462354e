"""Persistent OSQP backend: set up once, update data, warm start.

Tolerances: ``eps_abs = eps_rel = 1e-9`` with polishing, because OSQP's
defaults (1e-3) give visibly wrong allocations (see SOLVER_NOTES).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp

from . import BackendResult
from ..problem import QPData

_V1 = int(osqp.__version__.split(".")[0]) >= 1
DEFAULTS = {"eps_abs": 1e-9, "eps_rel": 1e-9,
            ("polishing" if _V1 else "polish"): True,
            "max_iter": 20000, "verbose": False,
            "eps_prim_inf": 1e-10, "eps_dual_inf": 1e-10}
_INF = 1e30


class OsqpBackend:
    """OSQP with a fixed dense sparsity pattern, updated on every call."""

    name = "osqp"

    def __init__(self, n: int, k: int, options: dict[str, Any]) -> None:
        self.n, self.k = n, k
        self.settings = {**DEFAULTS, **options}
        iu = np.triu_indices(n)
        self._p_pattern = sp.csc_matrix(
            (np.ones(len(iu[0])), iu), shape=(n, n))
        rows, cols = np.indices((k + n, n))
        self._a_pattern = sp.csc_matrix(
            (np.ones(rows.size), (rows.ravel(), cols.ravel())),
            shape=(k + n, n))
        # csc data order of each pattern, to map dense values into it
        self._p_order = self._order(self._p_pattern)
        self._a_order = self._order(self._a_pattern)
        self._solver: osqp.OSQP | None = None

    @staticmethod
    def _order(pattern: sp.csc_matrix) -> tuple[np.ndarray, np.ndarray]:
        cols = np.repeat(np.arange(pattern.shape[1]), np.diff(pattern.indptr))
        return pattern.indices, cols

    def _setup(self, px, ax, q, l_all, u_all) -> None:
        self._solver = osqp.OSQP()
        P = self._p_pattern.copy()
        P.data = px
        A = self._a_pattern.copy()
        A.data = ax
        self._solver.setup(P=P, q=q, A=A, l=l_all, u=u_all, **self.settings)

    def _solve(self):
        if _V1:
            return self._solver.solve(raise_error=False)
        return self._solver.solve()

    def solve(self, data: QPData) -> BackendResult:
        """Solve one QP, warm-started from the previous call."""
        full = np.vstack([data.C, np.eye(self.n)])
        px = data.P[self._p_order]
        ax = full[self._a_order]
        l_all = np.clip(np.concatenate([data.l, data.lb]), -_INF, _INF)
        u_all = np.clip(np.concatenate([data.u, data.ub]), -_INF, _INF)
        fresh = self._solver is None
        if fresh:
            self._setup(px, ax, data.q, l_all, u_all)
        else:
            self._solver.update(Px=px, Ax=ax, q=data.q, l=l_all, u=u_all)
        res = self._solve()
        status = str(res.info.status)
        found = status == "solved"
        if not found and not fresh:
            # The adapted step size of a long run of degenerate (saturated)
            # problems can stall OSQP: start once more from a fresh setup.
            self._setup(px, ax, data.q, l_all, u_all)
            res = self._solve()
            status = str(res.info.status)
            found = status == "solved"
        x = np.array(res.x) if found else None
        return BackendResult(x, found, status, int(res.info.iter))


def make(_: Any, n: int, k: int, n_eq: int,
         options: dict[str, Any]) -> OsqpBackend:
    """Build the persistent OSQP backend."""
    return OsqpBackend(n, k, options)
