"""QP backends of the allocators, one module each, behind `get_backend`.

Names the user passes:

* ``"osqp"`` (default): a persistent OSQP object set up once per problem
  size, updated and warm-started on each call (`osqp_`);
* any `qpsolvers` backend by its name (``"daqp"``, ``"quadprog"``,
  ``"proxqp"``, ``"piqp"``, ``"clarabel"``, ...), or ``"qpsolvers:NAME"``
  (``"qpsolvers:osqp"`` is OSQP set up again on every call) (`qpsolvers_`);
* ``"casadi:PLUGIN"`` for a CasADi ``conic`` plugin (``"casadi:daqp"``,
  ``"casadi:qrqp"``, ...), the form used in code generation
  (`casadi_conic_`).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from adcs_common.exceptions import SolverNotFound

from ..problem import QPData

INSTALL_HINT = ('Install the optional backends with '
                'pip install "adcs-toolbox[solvers]"')

#: CasADi conic plugins offered. Left out: hpipm (rejects this structure),
#: proxqp (reports primal infeasibility when a failed wheel has lbx == ubx),
#: qpoases (prints a licence banner on every construction).
CASADI_PLUGINS = ("daqp", "qrqp", "osqp")


@dataclass
class BackendResult:
    """What a backend returns for one QP.

    Attributes
    ----------
    x : (n,) ndarray or None
        The solution, None when the backend found none.
    found : bool
        The backend reports success.
    status : str
        The backend's own status text.
    iterations : int
        Iterations reported (-1 if unknown).
    """

    x: np.ndarray | None
    found: bool
    status: str
    iterations: int = -1
    extras: dict[str, Any] = field(default_factory=dict)


class Backend(Protocol):
    """A QP backend bound to one problem size."""

    name: str

    def solve(self, data: QPData) -> BackendResult:
        """Solve ``data``; never raises for a numerical failure."""


def _qpsolvers_names() -> tuple[str, ...]:
    import qpsolvers

    return tuple(qpsolvers.available_solvers)


def _casadi_names() -> tuple[str, ...]:
    import casadi as ca

    return tuple(f"casadi:{p}" for p in CASADI_PLUGINS if ca.has_conic(p))


def available_solvers() -> tuple[str, ...]:
    """Every solver name that works on this installation."""
    qps = _qpsolvers_names()
    names = ["osqp"] + [n for n in qps if n != "osqp"]
    names += [f"qpsolvers:{n}" for n in qps]
    return tuple(names) + _casadi_names()


def get_backend(name: str, n: int, k: int, n_eq: int,
                options: dict[str, Any] | None = None) -> Backend:
    """Build the backend ``name`` for a QP with n variables and k rows.

    Raises
    ------
    SolverNotFound
        ``name`` is unknown or its package is not installed; the message
        lists the installed names and the extra to install.
    """
    options = dict(options or {})
    if not isinstance(name, str):
        raise SolverNotFound(repr(name), available_solvers(), INSTALL_HINT)
    if name == "osqp":
        module, arg = "osqp_", None
    elif name.startswith("casadi:"):
        arg = name.split(":", 1)[1]
        if name not in _casadi_names():
            raise SolverNotFound(name, available_solvers(), INSTALL_HINT)
        module = "casadi_conic_"
    else:
        arg = name.split(":", 1)[1] if name.startswith("qpsolvers:") \
            else name
        if arg not in _qpsolvers_names():
            raise SolverNotFound(name, available_solvers(), INSTALL_HINT)
        module = "qpsolvers_"
    impl = importlib.import_module(f"{__name__}.{module}")
    return impl.make(arg, n, k, n_eq, options)
