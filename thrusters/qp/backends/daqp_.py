"""DAQP called directly (no qpsolvers layer): dense active-set, exact."""

from __future__ import annotations

import numpy as np

from ..problem import DutyCycleQP

#: Settings: DAQP's default primal_tol (1e-6) leaves equality rows off by
#: ~1e-6 (as CasADi's 'daqp' plugin does); 1e-10 is exact to the
#: reference.
DEFAULTS = {"primal_tol": 1e-10}
#: DAQP exit flags (daqp.github.io/daqp/parameters).
_INFEASIBLE = (-1,)


class Backend:
    """A persistent ``daqp.Model``: set up once, update f and bounds.

    Each cycle warm-starts from the previous active set.
    """

    def __init__(self, qp: DutyCycleQP, plugin: str, options: dict) -> None:
        import daqp

        self.qp = qp
        self.settings = {**DEFAULTS, **options}
        self._H = np.ascontiguousarray(qp.P)
        self._A = np.ascontiguousarray(qp.A)
        nx, m = qp.nx, qp.A.shape[0]
        self._bu = np.concatenate([qp.ub, np.zeros(m)])
        self._bl = np.concatenate([qp.lb, np.zeros(m)])
        self._sense = np.zeros(nx + m, dtype=np.int32)
        self._sense[nx:nx + qp.n_eq] = 5          # equality rows
        self._nx = nx
        q, l, u = qp.vectors(np.zeros(qp.Lm.shape[1]))
        self._bu[nx:] = u
        self._bl[nx:] = l
        self._model = daqp.Model()
        flag = self._model.setup(self._H, q, self._A, self._bu, self._bl,
                                 self._sense)
        if isinstance(flag, tuple):
            flag = flag[0]
        if flag < 0:
            from adcs_common.exceptions import SolverError
            raise SolverError(f"daqp setup failed with exit flag {flag}",
                              solver="daqp")
        self._model.settings = dict(self.settings)

    def set_upper(self, ub: np.ndarray) -> None:
        """Change the variables' upper bounds (n+1,) for the next solves."""
        self._bu[:self._nx] = ub

    def solve(self, theta: np.ndarray):
        """Return ``(x, status, None)``."""
        q, l, u = self.qp.vectors(theta)
        self._bu[self._nx:] = u
        self._bl[self._nx:] = l
        self._model.update(f=q, bupper=self._bu, blower=self._bl)
        x, _, flag, _ = self._model.solve()
        if flag == 1 or flag == 2:                  # optimal / soft optimal
            return np.array(x, dtype=float), "solved", None
        if flag in _INFEASIBLE:
            return None, "infeasible", None
        return None, "failed", None
