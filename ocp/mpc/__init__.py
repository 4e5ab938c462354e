"""Receding-horizon attitude control (MPC) and its closed loop."""

from .controller import (
    AttitudeMPC,
    ClosedLoopResult,
    MPCStep,
    MPCWeights,
    QP_SOLVERS,
    available_mpc_solvers,
    closed_loop_table,
    compare_slew,
    simulate_mpc,
)

__all__ = [
    "AttitudeMPC",
    "ClosedLoopResult",
    "MPCStep",
    "MPCWeights",
    "QP_SOLVERS",
    "available_mpc_solvers",
    "closed_loop_table",
    "compare_slew",
    "simulate_mpc",
]
