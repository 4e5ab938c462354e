"""`thrusters`: six-thruster unit, duty-cycle laws and allocator."""

from .exceptions import (
    AdcsError,
    InfeasibleError,
    InvalidValueError,
    ShapeError,
    SolverError,
    SolverNotFound,
)
from .laws import (
    THRUST_AXIS,
    TORQUE_AXES,
    LawResult,
    pair_forces,
    reorientation_law,
    unloading_law,
)
from .qp import (
    AllocationResult,
    DutyCycleAllocator,
    DutyCycleQP,
    MinOnTimeCarry,
    available_solvers,
    build_qp,
)
from .symbolic import force_torque_function, six_unit_function
from .unit import (
    G0,
    KGF_PER_CM2,
    SIX_UNIT_PAIRS,
    ThrusterSet,
    six_thruster_unit,
)

__all__ = [
    "AdcsError",
    "AllocationResult",
    "DutyCycleAllocator",
    "DutyCycleQP",
    "G0",
    "InfeasibleError",
    "InvalidValueError",
    "KGF_PER_CM2",
    "LawResult",
    "MinOnTimeCarry",
    "SIX_UNIT_PAIRS",
    "ShapeError",
    "SolverError",
    "SolverNotFound",
    "THRUST_AXIS",
    "TORQUE_AXES",
    "ThrusterSet",
    "available_solvers",
    "build_qp",
    "force_torque_function",
    "pair_forces",
    "reorientation_law",
    "six_thruster_unit",
    "six_unit_function",
    "unloading_law",
]
