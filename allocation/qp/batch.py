r"""Many wheel allocations in one numpy pass (3 or 4 working wheels).

The bounded QP of `QPAllocator` (``saturation="scale"``, no momentum
management or power cost) has an exact closed form when at most four
wheels work, the same one `conic_allocator_function` writes in CasADi:

* the scale: the largest ``α <= 1`` with ``α M`` in the attainable
  zonotope, ``α = min(1, min_f d_f / (n_f·M))`` over its facets
  ``n_f·x <= d_f``, ``d_f = n_f·A c + |n_f A| r`` (box centre c, half
  widths r);
* three working wheels: ``m = A_w⁻¹ α M`` (the only solution);
* four: ``m = m₀ + s ν`` with ``m₀`` the weighted minimum-norm point and
  ``ν`` the null direction of A (V-orthogonal to ``m₀``), so the optimum
  is ``s = 0`` clamped to the interval the bounds leave.

Every step is an array operation over the K demands, so a batch costs
a few numpy calls instead of K solver calls.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..arrays import WheelArray
from .conic_function import (
    _MARGIN,
    _null_direction,
    weighted_pseudo_inverse,
)
from .problem import facet_normals, torque_bounds
from .result import BatchAllocation

#: Relative tolerance of "the demand points at this facet", as in
#: `problem.max_scale`, so both give the same α.
_FACET_TOL = 1e-12


class BatchKernel:
    """The exact vectorised QP of one array and weights (built once)."""

    def __init__(self, array: WheelArray, weights: np.ndarray) -> None:
        act = array.active
        self.axes = array.working_axes
        self.normals = facet_normals(self.axes[:, act])
        na = self.normals @ self.axes
        self.half_sum = 0.5 * na.T          # (N, F): centre term
        self.half_abs = 0.5 * np.abs(na).T  # (N, F): half-width term
        self.pinv_t = weighted_pseudo_inverse(array, weights).T   # (3, N)
        self.null = _null_direction(array) if act.sum() == 4 else None
        if self.null is not None:
            keep = np.abs(self.null) > 1e-12 * np.abs(self.null).max()
            self.null_idx = np.flatnonzero(keep)
            self.null_pos = self.null[self.null_idx] > 0

    def scale(self, M: np.ndarray, lo: np.ndarray, hi: np.ndarray
              ) -> np.ndarray:
        """Largest ``α`` in [0, 1] with ``α M`` attainable, (K,).

        Below 1 it is taken 1e-9 (relative) inside the boundary, as
        `QPAllocator.allocate` and `conic_allocator_function` do.
        """
        d = (lo + hi) @ self.half_sum + (hi - lo) @ self.half_abs
        s = M @ self.normals.T                                 # (K, F)
        d = np.broadcast_to(d, s.shape)
        tol = _FACET_TOL * (np.abs(d).max(axis=1) + np.abs(s).max(axis=1)
                            + 1e-300)
        pos = s > tol[:, None]
        ratio = np.divide(d, s, out=np.full(s.shape, np.inf), where=pos)
        alpha = np.clip(ratio.min(axis=1), 0.0, 1.0)
        # inside by the relative margin `allocate` takes first (1e-9)
        return np.where(alpha < 1.0, alpha * (1.0 - _MARGIN), alpha)

    def solve(self, M: np.ndarray, lo: np.ndarray, hi: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Torques (K, N), scales (K,) and targets (K, 3) of K demands.

        ``lo``/``hi`` are (N,) or (K, N) bounds holding 0 (every working
        wheel within its momentum bound).
        """
        alpha = self.scale(M, lo, hi)
        target = alpha[:, None] * M
        m = target @ self.pinv_t
        if self.null is not None:
            idx, nu = self.null_idx, self.null[self.null_idx]
            lo_i = np.broadcast_to(lo, m.shape)[:, idx]
            hi_i = np.broadcast_to(hi, m.shape)[:, idx]
            a = (lo_i - m[:, idx]) / nu
            b = (hi_i - m[:, idx]) / nu
            s_lo = np.where(self.null_pos, a, b).max(axis=1)
            s_hi = np.where(self.null_pos, b, a).min(axis=1)
            step = np.minimum(np.maximum(0.0, s_lo), s_hi)
            m += step[:, None] * self.null
        return np.clip(m, lo, hi), alpha, target


def allocate_rows(q: Any, kernel: BatchKernel | None, M: np.ndarray,
                  h: np.ndarray | None, dt: float | None, t0: float
                  ) -> BatchAllocation:
    """`QPAllocator.allocate_batch` on validated input.

    Rows the kernel answers and that pass the allocator's check are taken
    from it; every other row goes through ``q.allocate``.
    """
    n = q.array.n_wheels
    K = M.shape[0]
    m = np.zeros((K, n))
    alpha, residual = np.ones(K), np.zeros(K)
    status = np.full(K, "optimal", dtype=object)
    rows = np.zeros(K, bool) if kernel is None else np.ones(K, bool)
    if kernel is not None:
        if dt is None:
            lo, hi, _ = torque_bounds(q.array, None, None, q._active)
        else:
            assert h is not None     # _step_length: dt needs h
            rows &= (np.abs(h) <= q._h_cap).all(axis=1)
            lo, hi, _ = torque_bounds(q.array, h, dt, q._active)
            lo, hi = lo[rows], hi[rows]
        m_k, a_k, target = kernel.solve(M[rows], lo, hi)
        err = np.maximum(np.abs(m_k @ q._axes.T - target).max(
            axis=1, initial=0.0), np.maximum(lo - m_k, m_k - hi).max(
            axis=1, initial=0.0))
        tol = q.check_tol * np.maximum(
            q._m_scale, np.abs(target).max(axis=1, initial=0.0))
        good = err <= tol
        idx = np.flatnonzero(rows)
        rows[idx[~good]] = False
        m[idx[good]], alpha[idx[good]] = m_k[good], a_k[good]
        residual[idx[good]] = err[good]
        status[idx[good & (a_k < 1.0)]] = "saturated"
    for k in np.flatnonzero(~rows):
        r = q.allocate(M[k], None if h is None else h[k], dt)
        m[k], alpha[k], status[k] = r.torques, r.alpha, r.status
        residual[k] = r.residual
    return BatchAllocation(
        torques=m, achieved=m @ q._axes.T, alpha=alpha,
        status=status.astype(str), residual=residual,
        solve_time=time.perf_counter() - t0,
        extras={"vectorised": int(rows.sum()),
                "one_at_a_time": int(K - rows.sum())})
