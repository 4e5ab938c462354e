"""The QP plugins an export may call, and the thruster duty QP's Function.

`resolve_qp_plugin` checks a plugin name (daqp, qrqp; pqp for the
condensed MPC steps) and picks daqp where CasADi has it;
`duty_qp_function` builds the certified duty-cycle QP that `export_c`
writes as ``duty_qp``.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from adcs_common.exceptions import InvalidValueError
from .precision import check_precision, duty_qp_options

#: Wheel-QP conic plugins `export_c` accepts.
WHEEL_QP_PLUGINS = ("daqp", "qrqp")


def daqp_available() -> bool:
    """Return True when CasADi's daqp conic plugin is there.

    The exports' DAQP C sources are the toolbox's own (vendored, copied
    into each export), so the plugin that builds the Functions is all
    that is needed.
    """
    try:
        return bool(ca.has_conic("daqp"))
    except RuntimeError:
        return False


def resolve_qp_plugin(plugin: str | None,
                      name: str = "wheel_qp_plugin") -> str:
    """The conic plugin ``name`` asks for: daqp where it is there (None),
    else qrqp; ``"pqp"`` for the condensed MPC steps' QP."""
    if plugin is None:
        return "daqp" if daqp_available() else "qrqp"
    if plugin == "pqp" and name == "condensed_qp_plugin":
        return plugin                   # the toolbox's own, `ocp.mpc.primal_qp`
    if plugin not in WHEEL_QP_PLUGINS:
        raise InvalidValueError(
            f"{name} must be one of {WHEEL_QP_PLUGINS} or None, "
            f"got {plugin!r}")
    if plugin == "daqp" and not daqp_available():
        raise InvalidValueError(
            f"{name}='daqp' needs the casadi daqp conic plugin; "
            "use 'qrqp'")
    return plugin


def duty_qp_function(unit: Any, cycle: float, h_max: float, *,
                     plugin: str | None = None, precision: str = "double",
                     **qp_options) -> ca.Function:
    """Build the thruster duty-cycle QP as one certified casadi Function.

    `thrusters.qp.certified.certified_duty_function` on `thrusters.build_qp`
    data: a test of the demand against the thrusters' attainable set, the
    fast path of `DutyCycleAllocator.duty_fast` (equalities eliminated,
    DAQP, a KKT certificate) and a status.

    Parameters
    ----------
    unit : thrusters.ThrusterSet
        The thrusters.
    cycle : float
        Cycle T_T [s].
    h_max : float
        Momentum bound [N·m·s].
    plugin : {None, "daqp", "qrqp"}
        Conic of the fast path: daqp (sub-microsecond in C; its sources
        travel with the export), qrqp (generated inline, about 5 µs) or
        None: daqp when `daqp_available`.
    precision : {"double", "single"}
        Tolerances of the certificate and the conic for that arithmetic
        (`ocp.codegen.precision.TOLERANCES`).
    **qp_options
        Forwarded to `thrusters.build_qp` (tracking, bound, weights).

    Returns
    -------
    casadi.Function
        ``duty_qp(theta[9], kmax[n]) -> (duty[n], slack, violation,
        status)``; ``status`` indexes `thrusters.DUTY_STATUS` (0 optimal,
        1 bound relaxed, 2 infeasible, 3 invalid input, 4 solver failed).
    """
    from thrusters import build_qp
    from thrusters.qp.certified import certified_duty_function

    plugin = resolve_qp_plugin(plugin, "plugin")
    return certified_duty_function(
        build_qp(unit, cycle, h_max, **qp_options), plugin,
        **duty_qp_options(check_precision(precision), plugin))
