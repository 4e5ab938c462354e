"""Bounded QP wheel allocation on the shared QP layer."""

from .allocator import QPAllocator
from .result import BatchAllocation, WheelAllocation
from .conic_function import conic_allocator_function
from .solvers import available_solvers

__all__ = ["BatchAllocation", "QPAllocator", "WheelAllocation",
           "available_solvers", "conic_allocator_function"]
