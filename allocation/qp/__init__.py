"""Bounded QP wheel allocation with pluggable backends."""

from .allocator import AllocationResult, QPAllocator
from .backends import available_solvers

__all__ = ["AllocationResult", "QPAllocator", "available_solvers"]
