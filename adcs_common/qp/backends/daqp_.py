"""DAQP called directly: a dense active-set solver, exact.

Set up once; while H, C and the equality rows stay the same, each call
only updates the linear term and the bounds and warm-starts from the
previous active set. DAQP's default primal_tol (1e-6) leaves equality
rows off by up to ~3e-5; 1e-10 is exact to the references.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..problem import QP
from ..solution import QPSolution

DEFAULTS: dict[str, Any] = {"primal_tol": 1e-10}
#: DAQP's infinity.
_INF = 1e30
#: exit flags: optimal, soft optimal / infeasible
_SOLVED = (1, 2)
_INFEASIBLE = (-1,)


class Backend:
    """A persistent ``daqp.Model``."""

    def __init__(self, plugin: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any]) -> None:
        import daqp

        self._daqp = daqp
        self.name = "daqp"
        self.n, self.n_eq = n, n_eq
        self.settings = {**DEFAULTS, **options}
        self._model: Any = None           # a daqp.Model once set up
        self._H: np.ndarray | None = None
        self._C: np.ndarray | None = None
        self._P_obj: np.ndarray | None = None
        self._C_obj: np.ndarray | None = None
        self._sense = np.zeros(n + k, dtype=np.int32)
        self._sense[n:n + n_eq] = 5          # equality rows (immutable)
        self._bu = np.zeros(n + k)
        self._bl = np.zeros(n + k)

    def solve(self, qp: QP) -> QPSolution:
        """Solve one QP (set up again only if H or C changed)."""
        n, bu, bl = self.n, self._bu, self._bl
        bu[:n], bu[n:], bl[:n], bl[n:] = qp.ub, qp.u, qp.lb, qp.l
        np.clip(bu, -_INF, _INF, out=bu)
        np.clip(bl, -_INF, _INF, out=bl)
        same = (qp.P is self._P_obj and qp.C is self._C_obj) or (
            self._model is not None and self._H is not None
            and self._C is not None and np.array_equal(qp.P, self._H)
            and np.array_equal(qp.C, self._C))
        self._P_obj, self._C_obj = qp.P, qp.C
        if self._model is None or not same:
            self._H = np.ascontiguousarray(qp.P, dtype=float)
            self._C = np.ascontiguousarray(qp.C, dtype=float)
            self._model = self._daqp.Model()
            flag = self._model.setup(self._H, np.array(qp.q, dtype=float),
                                     self._C, bu, bl, self._sense)
            flag = flag[0] if isinstance(flag, tuple) else flag
            if flag < 0:
                self._model = None
                return QPSolution.failed(
                    "infeasible" if flag in _INFEASIBLE else "failed",
                    backend_status=f"setup exit flag {flag}")
            self._model.settings = dict(self.settings)
        else:
            self._model.update(f=np.array(qp.q, dtype=float), bupper=bu,
                               blower=bl)
        x, _, flag, info = self._model.solve()
        status = ("solved" if flag in _SOLVED else "infeasible"
                  if flag in _INFEASIBLE else "failed")
        iters = int(info.get("iterations", -1)) if isinstance(info, dict) \
            else -1
        return QPSolution(np.array(x, dtype=float) if status == "solved"
                          else None, status == "solved", status, iters,
                          extras={"backend_status": f"exit flag {flag}"})
