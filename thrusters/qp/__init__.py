"""Duty-cycle QP: canonical problem, the allocator, its backends."""

from .allocator import (
    DutyAllocation,
    DutyCycleAllocator,
    MinOnTimeCarry,
)
from .problem import DutyCycleQP, build_qp
from .solvers import available_solvers

__all__ = [
    "DutyAllocation",
    "DutyCycleAllocator",
    "DutyCycleQP",
    "MinOnTimeCarry",
    "available_solvers",
    "build_qp",
]
