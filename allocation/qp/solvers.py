"""The QP backends the wheel allocator offers: every one of the QP layer."""

from __future__ import annotations

from adcs_common.qp import available_solvers as _layer_solvers

__all__ = ["available_solvers"]


def available_solvers() -> tuple[str, ...]:
    """Every QP backend name `QPAllocator` takes on this installation.

    ``"osqp"`` (persistent), ``"daqp"`` (direct), each installed qpsolvers
    backend (bare or ``"qpsolvers:NAME"``), ``"casadi:daqp|qrqp|osqp"``
    and ``"casadi-c:qrqp"`` where a C compiler is found.
    """
    return _layer_solvers()
