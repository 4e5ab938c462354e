"""`QPAllocator.allocate_fast`'s Function, bound to numpy buffers."""

from __future__ import annotations

import math

import numpy as np

from adcs_common.buffers import BoundCall

from ..arrays import WheelArray


class FastWheelQP:
    """`conic_allocator_function` bound to numpy arrays through a buffer."""

    def __init__(self, array: WheelArray, weights: np.ndarray,
                 dt: float | None, tol: float) -> None:
        from .conic_function import conic_allocator_function

        n = array.n_wheels
        self.function = conic_allocator_function(array, weights, dt=dt)
        self.tol = tol
        self.M = np.zeros(3)
        self.h = np.zeros(n)
        self.m = np.zeros(n)
        self._over = np.zeros(n)
        self.alpha = np.zeros(1)
        self.check = np.zeros(1)
        self._call = BoundCall(
            self.function, (self.M,) if dt is None else (self.M, self.h),
            (self.m, self.alpha, self.check))
        self.trigger = self._call.trigger

    def load(self, torque, momentum, h_cap: np.ndarray) -> bool:
        """Copy a demand in; False unless the Function answers as `allocate`.

        (3,) finite torque and (N,) finite momentum (when ``dt`` is set):
        no scalar is broadcast, no NaN gets through; and no working wheel
        beyond its momentum bound ``h_cap`` (it must brake: the attainable
        set then need not hold zero torque, which `allocate`'s geometry
        handles and the Function's fixed facets do not).
        """
        try:
            M = np.asarray(torque, dtype=float)
            h = None if momentum is None else np.asarray(momentum,
                                                         dtype=float)
        except (TypeError, ValueError):
            return False
        if M.shape != (3,) or not math.isfinite(M @ M):
            return False
        if h is not None:
            if h.shape != self.h.shape:
                return False
            over = np.abs(h, out=self._over)
            over -= h_cap
            if not over.max() <= 0.0:     # NaN, inf or past h_max
                return False
        self.M[:] = M
        if h is not None:
            self.h[:] = h
        return True
