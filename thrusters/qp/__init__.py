"""Duty-cycle QP: canonical problem, the allocator, its backends."""

from .allocator import (
    DutyAllocation,
    DutyCycleAllocator,
    MinOnTimeCarry,
)
from .certified import DUTY_STATUS, certified_duty_function
from .problem import DutyCycleQP, build_qp
from .solvers import available_solvers

__all__ = [
    "DUTY_STATUS",
    "DutyAllocation",
    "DutyCycleAllocator",
    "DutyCycleQP",
    "MinOnTimeCarry",
    "available_solvers",
    "build_qp",
    "certified_duty_function",
]
