"""QP backends, one module each, behind one table and one constructor.

Names a user passes (``solver=``):

* ``"osqp"``: OSQP kept across calls, warm-started (`osqp_`);
* ``"daqp"``: DAQP called directly, exact (`daqp_`);
* ``"qpsolvers:NAME"`` (or a bare ``"NAME"``): any installed `qpsolvers`
  backend, set up again on every call (`qpsolvers_`);
* ``"casadi:PLUGIN"``: a CasADi conic plugin (`casadi_conic_`);
* ``"casadi-c:PLUGIN"``: that conic as generated C, compiled (needs a C
  compiler; `casadi_codegen_`).

A new backend is one module with a ``Backend`` class (``Backend(plugin,
n, k, n_eq, options).solve(qp) -> QPSolution``) and one line in
`FAMILIES`; every allocator then offers it.
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import Any, Protocol

import casadi as ca
import numpy as np

from ...exceptions import SolverNotFound
from ...solver_options import check_backend_options
from ..certificate import CERTIFY_TOL, certify
from ..problem import QP
from ..solution import QPSolution

#: family -> module of this package
FAMILIES = {
    "osqp": "osqp_",
    "daqp": "daqp_",
    "qpsolvers": "qpsolvers_",
    "casadi": "casadi_conic_",
    "casadi-c": "casadi_codegen_",
}
#: CasADi conic plugins offered. Left out: hpipm (rejects this
#: structure), proxqp (reports primal infeasibility when a failed wheel
#: has lbx == ubx), qpoases (prints a licence banner on every build).
CASADI_PLUGINS = ("daqp", "qrqp", "osqp")
INSTALL_HINT = ('install the optional backends with '
                'pip install "adcs-toolbox[solvers]"')


class Backend(Protocol):
    """A QP backend bound to one problem size."""

    name: str

    def solve(self, qp: QP) -> QPSolution:
        """Solve ``qp``; a numerical failure is a status, never raised."""


def resolve(name: str) -> tuple[str, str]:
    """``(family, plugin)`` of a solver name (not checked installed)."""
    if not isinstance(name, str) or not name:
        raise SolverNotFound(repr(name), available_solvers(), INSTALL_HINT)
    family, sep, plugin = name.partition(":")
    if sep and family in FAMILIES:
        return family, plugin
    if name in ("osqp", "daqp"):
        return name, name
    return "qpsolvers", name


def canonical_name(name, offered: tuple[str, ...]):
    """``"qpsolvers:NAME"`` for a bare qpsolvers ``NAME`` it offers."""
    if isinstance(name, str) and name not in offered \
            and f"qpsolvers:{name}" in offered and ":" not in name:
        return f"qpsolvers:{name}"
    return name


def _qpsolvers_names() -> tuple[str, ...]:
    from .qpsolvers_ import installed

    return installed()


def available_solvers(qpsolvers_names: tuple[str, ...] | None = None,
                      casadi_plugins: tuple[str, ...] = CASADI_PLUGINS,
                      codegen_plugins: tuple[str, ...] = ("qrqp",),
                      bare_names: bool = True) -> tuple[str, ...]:
    """Every solver name that works on this installation.

    Parameters
    ----------
    qpsolvers_names : tuple of str, optional
        The qpsolvers backends to offer (default every installed one).
    casadi_plugins, codegen_plugins : tuple of str
        The CasADi conic plugins to offer, as called and as generated C.
    bare_names : bool
        Also offer each qpsolvers backend by its bare name (``"piqp"``
        for ``"qpsolvers:piqp"``).
    """
    names = []
    if importlib.util.find_spec("osqp") is not None:
        names.append("osqp")
    if importlib.util.find_spec("daqp") is not None:
        names.append("daqp")
    qps = [n for n in _qpsolvers_names()
           if qpsolvers_names is None or n in qpsolvers_names]
    if bare_names:
        names += [n for n in qps if n not in ("osqp", "daqp")]
    names += [f"qpsolvers:{n}" for n in qps]
    names += [f"casadi:{p}" for p in casadi_plugins if ca.has_conic(p)]
    from .casadi_codegen_ import PLUGINS, available

    if available():
        names += [f"casadi-c:{p}" for p in codegen_plugins if p in PLUGINS
                  and ca.has_conic(p)]
    return tuple(names)


class CertifiedBackend:
    """A backend whose every answer is polished and certified optimal.

    `certificate.certify` runs on each point the backend returns: the
    exact KKT solution of the active set the backend found replaces it
    when that is the optimum; otherwise the answer keeps the backend's
    point with ``success=False`` and ``status="inaccurate"``. The
    verdict is ``extras["certificate"]`` either way, with ``"moved"``:
    how far the polish moved the backend's point (∞-norm).
    """

    def __init__(self, backend: Backend, tol: float = CERTIFY_TOL) -> None:
        self.backend = backend
        self.name = backend.name
        self.tol = tol

    def __getattr__(self, attr: str) -> Any:
        return getattr(self.backend, attr)

    def solve(self, qp: QP) -> QPSolution:
        """Solve with the backend, then polish and certify its point."""
        sol = self.backend.solve(qp)
        if sol.x is None:
            return sol
        x, cert = certify(qp, sol.x, self.tol)
        # how far the polish moved the backend's point (∞-norm, in the
        # QP's variables): what the certificate corrected
        moved = float(np.max(np.abs(x - sol.x))) if x.size else 0.0
        extras = {**sol.extras,
                  "certificate": {**cert.as_dict(), "moved": moved}}
        if cert.certified:
            return QPSolution(x, True, "solved", sol.iterations,
                              sol.solve_time, extras)
        extras.setdefault("backend_status", sol.status)
        return QPSolution(sol.x, False, "inaccurate", sol.iterations,
                          sol.solve_time, extras)


def make_backend(name: str, n: int, k: int, n_eq: int,
                 options: dict[str, Any] | None = None,
                 offered: tuple[str, ...] | None = None,
                 hint: str = INSTALL_HINT,
                 certified: bool = True) -> Backend:
    """Build backend ``name`` for a QP of n variables and k rows.

    Parameters
    ----------
    offered : tuple of str, optional
        The names the caller offers (default `available_solvers`).
    certified : bool
        Wrap the backend in `CertifiedBackend` (default): every answer it
        calls a success is the QP's optimum to a relative 1e-9, polished
        on the backend's active set.

    Raises
    ------
    SolverNotFound
        ``name`` is not offered here; the message lists what is.
    InvalidValueError
        ``options`` is not a dict or names an option the backend does
        not take (`adcs_common.solver_options`; the message lists those
        it takes).
    """
    offered = available_solvers() if offered is None else offered
    name = canonical_name(name, offered)
    if not isinstance(name, str) or name not in offered:
        raise SolverNotFound(repr(name) if not isinstance(name, str)
                             else name, offered, hint)
    family, plugin = resolve(name)
    # unknown names refused here, not ignored or failing at the first call
    options = check_backend_options(family, plugin, options)
    module = importlib.import_module(f"{__name__}.{FAMILIES[family]}")
    backend = module.Backend(plugin, n, k, n_eq, options)
    return CertifiedBackend(backend) if certified else backend
