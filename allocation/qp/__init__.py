"""Bounded QP wheel allocation with pluggable backends."""

from .allocator import AllocationResult, QPAllocator
from .backends import available_solvers
from .conic_function import conic_allocator_function

__all__ = ["AllocationResult", "QPAllocator", "available_solvers",
           "conic_allocator_function"]
