"""Reaction-wheel arrays and torque allocation (seed 001, SPEC section 1)."""

from .arrays import WheelArray, pyramid_axes
from .electrical import WheelMotor
from .exceptions import (
    AdcsError,
    InfeasibleError,
    InvalidValueError,
    RankError,
    ShapeError,
    SolverError,
    SolverNotFound,
)
from .laws import (
    EQ9_GAINS,
    PAPER_EQ9_GAINS_PRINTED,
    LinearLaw,
    allocate_min_norm,
    min_norm_gains,
    min_norm_law,
    pyramid_failure_gains,
    sign_matrix_gains,
    weighted_gains,
    weighted_law,
)
from .qp import (
    AllocationResult,
    QPAllocator,
    available_solvers,
    conic_allocator_function,
)
from .symbolic import (
    min_norm_function,
    pyramid_axes_function,
    pyramid_min_norm_function,
    sign_matrix_function,
    weighted_function,
)

__all__ = [
    "AdcsError",
    "AllocationResult",
    "EQ9_GAINS",
    "InfeasibleError",
    "InvalidValueError",
    "LinearLaw",
    "PAPER_EQ9_GAINS_PRINTED",
    "QPAllocator",
    "RankError",
    "ShapeError",
    "SolverError",
    "SolverNotFound",
    "WheelArray",
    "WheelMotor",
    "allocate_min_norm",
    "available_solvers",
    "conic_allocator_function",
    "min_norm_function",
    "min_norm_gains",
    "min_norm_law",
    "pyramid_axes",
    "pyramid_axes_function",
    "pyramid_failure_gains",
    "pyramid_min_norm_function",
    "sign_matrix_function",
    "sign_matrix_gains",
    "weighted_function",
    "weighted_gains",
    "weighted_law",
]
