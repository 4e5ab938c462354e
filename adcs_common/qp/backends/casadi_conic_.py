"""A CasADi ``conic`` plugin (the solvers CasADi can generate C for).

The conic is built once per problem size with dense sparsity; each call
passes the numeric data. ``qrqp`` can report success on a point that
violates constraints (seen on a few random allocations, by up to 0.01):
the allocators check every point they get. qrqp is never handed a
problem with more equality constraints than variables (`_overdetermined`).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ...buffers import BoundCall
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


def wrapped_conic(plugin: str, n: int, k: int,
                  options: dict[str, Any]) -> ca.Function:
    """``qp(h, g, a, lba, uba, lbx, ubx) -> x``: the conic as a Function."""
    conic = dense_conic("qp_conic", plugin, n, k, options)
    args = [ca.MX.sym(s, *shape) for s, shape in (
        ("h", (n, n)), ("g", (n, 1)), ("a", (k, n)), ("lba", (k, 1)),
        ("uba", (k, 1)), ("lbx", (n, 1)), ("ubx", (n, 1)))]
    x = conic(h=args[0], g=args[1], a=args[2], lba=args[3], uba=args[4],
              lbx=args[5], ubx=args[6])["x"]
    return ca.Function("qp_c", args, [x])


def _overdetermined(qp: QP) -> bool:
    """More equality rows and fixed variables than variables, or every
    variable fixed.

    CasADi's qrqp (called, and its generated C) writes past its buffers
    on such a problem (measured: ``munmap_chunk(): invalid pointer`` a few
    calls after a least-squares QP of three wheels all pinned by their
    momentum bounds), so it never sees one: the allocators hand it to
    DAQP and say so.
    """
    fixed = int(np.count_nonzero(qp.lb == qp.ub))
    eq_rows = int(np.count_nonzero(qp.l == qp.u))
    return fixed + eq_rows > qp.n or fixed == qp.n


class Backend:
    """A ``casadi.conic`` bound to numpy buffers (no argument conversion).

    The point's success is its being finite: the allocators check every
    point's residual themselves (the conic's own flag is not reachable
    through a buffer, and qrqp's can be wrong anyway).
    """

    def __init__(self, plugin: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any]) -> None:
        self.name = f"casadi:{plugin}"
        self.plugin = plugin
        self._bind(wrapped_conic(plugin, n, k, options), n, k)

    def _bind(self, function: ca.Function, n: int, k: int) -> None:
        self.function = function
        self._in = [np.zeros(n * n), np.zeros(n), np.zeros(k * n),
                    np.zeros(k), np.zeros(k), np.zeros(n), np.zeros(n)]
        self._x = np.zeros(n)
        self._call = BoundCall(function, self._in, (self._x,))
        self._P_obj: np.ndarray | None = None
        self._C_obj: np.ndarray | None = None

    def solve(self, qp: QP) -> QPSolution:
        """Solve one QP."""
        if self.plugin == "qrqp" and _overdetermined(qp):
            return QPSolution.failed(
                backend_status="more equality constraints than variables "
                "(qrqp corrupts its memory on such a problem)")
        h, g, a, lba, uba, lbx, ubx = self._in
        if qp.P is not self._P_obj:
            h[:] = qp.P.ravel(order="F")
            self._P_obj = qp.P
        if qp.C is not self._C_obj:
            a[:] = qp.C.ravel(order="F")
            self._C_obj = qp.C
        g[:], lba[:], uba[:], lbx[:], ubx[:] = qp.q, qp.l, qp.u, qp.lb, qp.ub
        # a failed evaluation leaves the output untouched: NaN marks it
        self._x[:] = np.nan
        self._call.trigger()
        x = self._x.copy()
        found = bool(np.all(np.isfinite(x)))
        return QPSolution(x if found else None, found,
                          "solved" if found else "failed",
                          extras={"backend_status": "finite point" if found
                                  else "evaluation failed"})
