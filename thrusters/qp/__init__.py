"""Duty-cycle QP: canonical problem, backends and the allocator."""

from .allocator import (
    AllocationResult,
    DutyCycleAllocator,
    MinOnTimeCarry,
)
from .backends import available_solvers
from .problem import DutyCycleQP, build_qp

__all__ = [
    "AllocationResult",
    "DutyCycleAllocator",
    "DutyCycleQP",
    "MinOnTimeCarry",
    "available_solvers",
    "build_qp",
]
