"""Dispatch of duty-cycle QP backends: one name -> module table."""

from __future__ import annotations

import importlib

from adcs_common.exceptions import SolverNotFound

from ..problem import DutyCycleQP

#: Backend family -> module (imported lazily).
_MODULES = {
    "osqp": ".osqp_",
    "qpsolvers": ".qpsolvers_",
    "casadi": ".casadi_conic_",
    "casadi-c": ".casadi_conic_",
    "daqp": ".daqp_",
}
#: CasADi conic plugins offered (each tested against the reference).
#: Not offered, measured on 150 random cycles of this QP: CasADi's 'daqp'
#: (default primal_tol leaves points off by up to ~3e-5; with primal_tol
#: 1e-10, `casadi_conic_.DEFAULTS`, it is exact on cycles that keep the
#: momentum bound, but on relaxed-bound cycles a duty stays at ~1.5e-6
#: instead of 0, whatever its tolerances: the allocator's `duty_fast`
#: uses it behind its residual check, falling back to `solve`; daqp
#: called directly is exact and is offered), 'qpoases' (5 of 150 cycles
#: fail the residual check), 'proxqp' (26 of 150 fail).
CASADI_PLUGINS = ("qrqp", "osqp")
#: Plugins offered as generated C (``"casadi-c:<plugin>"``), needing a C
#: compiler; qrqp generates self-contained C.
CODEGEN_PLUGINS = ("qrqp",)
#: qpsolvers backends offered (tested to 1e-6 against the reference with
#: the tolerances of `qpsolvers_.DEFAULTS`). Not offered: 'proxqp' (11 of
#: 150 random cycles without a solution at any tolerance tried) and
#: qpsolvers' 'osqp' (set up again on every call; the persistent "osqp"
#: backend is the OSQP offering).
QPSOLVERS_NAMES = ("clarabel", "daqp", "piqp", "quadprog")
INSTALL_HINT = ('Install the optional solvers with: '
                'pip install "adcs-toolbox[solvers]"')


def _qpsolvers_names() -> tuple[str, ...]:
    try:
        import qpsolvers
    except ImportError:
        return ()
    return tuple(n for n in QPSOLVERS_NAMES
                 if n in qpsolvers.available_solvers)


def _casadi_names() -> tuple[str, ...]:
    import casadi as ca

    return tuple(f"casadi:{p}" for p in CASADI_PLUGINS if ca.has_conic(p))


def _codegen_names() -> tuple[str, ...]:
    from .casadi_conic_ import compiler

    if compiler() is None:
        return ()
    return tuple(f"casadi-c:{p}" for p in CODEGEN_PLUGINS)


def _has_daqp() -> bool:
    import importlib.util

    return importlib.util.find_spec("daqp") is not None


def available_solvers() -> tuple[str, ...]:
    """Solver names that work on this installation.

    ``"osqp"`` is the persistent OSQP object; ``"daqp"`` DAQP called
    directly (the fastest exact backend); ``"casadi:<plugin>"`` a
    CasADi conic (`CASADI_PLUGINS`); ``"casadi-c:<plugin>"`` the same
    conic exported to C and compiled at build time (`CODEGEN_PLUGINS`,
    needs a C compiler); ``"qpsolvers:<name>"`` (or a bare ``"<name>"``)
    an installed qpsolvers backend among `QPSOLVERS_NAMES`.
    """
    names = []
    try:
        import osqp  # noqa: F401
        names.append("osqp")
    except ImportError:
        pass
    if _has_daqp():
        names.append("daqp")
    names += list(_casadi_names())
    names += list(_codegen_names())
    names += [f"qpsolvers:{n}" for n in _qpsolvers_names()]
    return tuple(names)


def _installed_elsewhere(plugin: str) -> bool:
    try:
        import qpsolvers
    except ImportError:
        return False
    return plugin in qpsolvers.available_solvers


def resolve(name: str) -> tuple[str, str]:
    """``(family, plugin)`` of a solver name, or raise `SolverNotFound`."""
    if not isinstance(name, str):
        raise SolverNotFound(repr(name), available_solvers(), INSTALL_HINT)
    if name == "osqp":
        family, plugin = "osqp", "osqp"
    elif name == "daqp":
        family, plugin = "daqp", "daqp"
    elif name.startswith("casadi:"):
        family, plugin = "casadi", name.split(":", 1)[1]
    elif name.startswith("casadi-c:"):
        family, plugin = "casadi-c", name.split(":", 1)[1]
    elif name.startswith("qpsolvers:"):
        family, plugin = "qpsolvers", name.split(":", 1)[1]
    else:
        family, plugin = "qpsolvers", name
    ok = {
        "osqp": lambda: "osqp" in available_solvers(),
        "daqp": _has_daqp,
        "casadi": lambda: f"casadi:{plugin}" in _casadi_names(),
        "casadi-c": lambda: f"casadi-c:{plugin}" in _codegen_names(),
        "qpsolvers": lambda: plugin in _qpsolvers_names(),
    }[family]()
    if not ok:
        hint = INSTALL_HINT
        if family == "qpsolvers" and _installed_elsewhere(plugin):
            hint = (f"{plugin!r} is installed but not offered for this QP "
                    "(it failed the reference tests; see "
                    "thrusters.qp.backends.QPSOLVERS_NAMES)")
        raise SolverNotFound(name, available_solvers(), hint)
    return family, plugin


def make_backend(name: str, qp: DutyCycleQP, options: dict):
    """Build the backend object of solver ``name`` for ``qp``."""
    family, plugin = resolve(name)
    module = importlib.import_module(_MODULES[family], __name__)
    cls = module.CodegenBackend if family == "casadi-c" else module.Backend
    return cls(qp, plugin, dict(options))
