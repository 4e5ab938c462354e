"""`thrusters`: six-thruster unit, duty-cycle laws and allocator."""

from .exceptions import (
    AdcsError,
    InfeasibleError,
    InvalidValueError,
    ShapeError,
    SolverError,
    SolverNotFound,
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
    "G0",
    "InfeasibleError",
    "InvalidValueError",
    "KGF_PER_CM2",
    "SIX_UNIT_PAIRS",
    "ShapeError",
    "SolverError",
    "SolverNotFound",
    "ThrusterSet",
    "force_torque_function",
    "six_thruster_unit",
    "six_unit_function",
]
