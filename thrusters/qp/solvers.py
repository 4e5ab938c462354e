"""The QP backends the duty-cycle allocator offers, and their settings.

All come from the shared QP layer (`adcs_common.qp`); this module says
which of them pass this QP's reference tests and with which tolerances.
"""

from __future__ import annotations

from typing import Any

from adcs_common.exceptions import SolverNotFound
from adcs_common.options import merge_options
from adcs_common.qp import INSTALL_HINT, available_solvers as _layer
from adcs_common.qp import make_backend as _make, resolve
from adcs_common.qp.backends import canonical_name

__all__ = ["CASADI_PLUGINS", "QPSOLVERS_NAMES", "available_solvers",
           "backend_options"]

#: CasADi conic plugins offered (each tested against the reference).
#: Not offered, measured on 150 random cycles of this QP: CasADi's 'daqp'
#: (on relaxed-bound cycles a duty stays at ~1.5e-6 instead of 0 whatever
#: its tolerances; the allocator's `duty_fast` uses it behind its
#: residual check, falling back to `solve`; daqp called directly is exact
#: and is offered), 'qpoases' (5 of 150 cycles fail the residual check),
#: 'proxqp' (26 of 150 fail).
CASADI_PLUGINS = ("qrqp", "osqp")
#: qpsolvers backends offered (tested to 1e-6 against the reference with
#: the tolerances of `backend_options`). Not offered: 'proxqp' (11 of
#: 150 random cycles without a solution at any tolerance tried) and
#: qpsolvers' 'osqp' (set up again on every call; the persistent "osqp"
#: backend is the OSQP offering).
QPSOLVERS_NAMES = ("clarabel", "daqp", "piqp", "quadprog")

#: Settings per backend, over the QP layer's defaults. OSQP at its own
#: default tolerances fires both engines of an opposed pair; eps 1e-6
#: with polishing is exact to the reference (polishing solves the KKT
#: system of the detected active set), and an inaccurate answer is still
#: taken since the allocator checks every point's residual. Interior
#: point solvers are tightened to 1e-12.
_OPTIONS: dict[str, dict[str, Any]] = {
    "osqp": {"eps_abs": 1e-6, "eps_rel": 1e-6, "polishing": True,
             "max_iter": 20000, "warm_starting": True, "verbose": False,
             "eps_prim_inf": 1e-4, "eps_dual_inf": 1e-4,
             "accept_inaccurate": True},
    "qpsolvers:osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True,
                       "max_iter": 200000},
    "qpsolvers:proxqp": {"eps_abs": 1e-10, "eps_rel": 0.0},
    "qpsolvers:piqp": {"eps_abs": 1e-12, "eps_rel": 1e-12},
    "qpsolvers:clarabel": {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12,
                           "tol_feas": 1e-12},
    "casadi:osqp": {"osqp": {"eps_abs": 1e-6, "eps_rel": 1e-6,
                             "polishing": True, "max_iter": 20000,
                             "verbose": False}},
}


def available_solvers() -> tuple[str, ...]:
    """Solver names `DutyCycleAllocator` takes on this installation.

    ``"osqp"`` (persistent), ``"daqp"`` (direct, exact), ``"casadi:qrqp"``,
    ``"casadi:osqp"``, ``"casadi-c:qrqp"`` (generated C, needs a C
    compiler) and ``"qpsolvers:NAME"`` for `QPSOLVERS_NAMES`.
    """
    return _layer(qpsolvers_names=QPSOLVERS_NAMES,
                  casadi_plugins=CASADI_PLUGINS, bare_names=False)


def backend_options(name: str, user: dict | None) -> dict[str, Any]:
    """Return the settings of backend ``name`` on this QP, user's over."""
    family, plugin = resolve(name)
    key = name if family != "qpsolvers" else f"qpsolvers:{plugin}"
    return merge_options(_OPTIONS.get(key, {}), dict(user or {}))


def make_backend(name: str, n: int, k: int, n_eq: int,
                 user_options: dict | None):
    """Build backend ``name`` for the duty QP (or `SolverNotFound`)."""
    offered = available_solvers()
    name = canonical_name(name, offered)
    hint = INSTALL_HINT
    if isinstance(name, str) and name not in offered:
        _, plugin = resolve(name)
        if plugin in _layer():
            hint = (f"{name!r} is installed but not offered for this QP "
                    "(it failed the reference tests; see "
                    "thrusters.qp.solvers)")
    if not isinstance(name, str) or name not in offered:
        raise SolverNotFound(str(name), offered, hint)
    return _make(name, n, k, n_eq, backend_options(name, user_options),
                 offered)
