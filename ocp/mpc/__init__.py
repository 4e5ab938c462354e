"""Receding-horizon attitude control (MPC) and its closed loop."""

from .closed_loop import (
    ClosedLoopResult,
    closed_loop_table,
    closed_loop_frame,
    compare_slew,
    keep_out_margin,
    simulate_mpc,
)
from .controller import (
    QP_SOLVERS,
    AttitudeMPC,
    default_mpc_solver,
    MPCStep,
    MPCWeights,
    available_mpc_solvers,
)
from .robust import RobustMPC
from .scenarios import Scenario, inertia_corners, scenario_grid

__all__ = [
    "AttitudeMPC",
    "default_mpc_solver",
    "ClosedLoopResult",
    "MPCStep",
    "MPCWeights",
    "RobustMPC",
    "Scenario",
    "QP_SOLVERS",
    "available_mpc_solvers",
    "closed_loop_table",
    "closed_loop_frame",
    "compare_slew",
    "inertia_corners",
    "keep_out_margin",
    "scenario_grid",
    "simulate_mpc",
]
