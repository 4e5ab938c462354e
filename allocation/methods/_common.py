"""Shared pieces of the literature's allocation methods.

Bounds, validation and the bounded least-squares solver (Härkegård's
active-set iteration) that several methods reuse.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_array, as_vector

from ..arrays import WheelArray

#: Rank tolerance of the pseudo-inverses [1] (relative singular value).
RCOND = 1e-10


def problem(array: WheelArray, torque: ArrayLike, lo: ArrayLike | None,
            hi: ArrayLike | None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validated ``(A (3, N), M (3,), lo (N,), hi (N,))`` of one demand.

    The bounds are ``±m_max`` intersected with the optional ``lo``/``hi``
    [N·m] (momentum-limited wheels), and 0 for failed wheels; A is the
    working axes (failed columns zeroed).
    """
    if not isinstance(array, WheelArray):
        raise InvalidValueError(
            f"array must be a WheelArray, got {type(array).__name__}")
    n = array.n_wheels
    M = as_finite_array(torque, "torque", (3,))
    low = -np.array(array.m_max, dtype=float)
    high = np.array(array.m_max, dtype=float)
    if lo is not None:
        low = np.maximum(low, as_vector(lo, n, "lo"))
    if hi is not None:
        high = np.minimum(high, as_vector(hi, n, "hi"))
    act = array.active
    low[~act] = 0.0
    high[~act] = 0.0
    if np.any(low > high):
        bad = [int(i) for i in np.flatnonzero(low > high)]
        raise InvalidValueError(f"lo > hi on wheel(s) {bad} (0-based)")
    return array.working_axes, M, low, high


def pinv(A: np.ndarray) -> np.ndarray:
    """Moore–Penrose pseudo-inverse (N, 3) of ``A`` (3, N) (zero if empty)."""
    if A.shape[1] == 0:
        return np.zeros((0, A.shape[0]))
    return np.linalg.pinv(A, rcond=RCOND)


def bounded_lsq(A: np.ndarray, b: np.ndarray, lo: np.ndarray,
                hi: np.ndarray, x0: np.ndarray | None = None,
                max_iter: int = 100) -> tuple[np.ndarray, int]:
    r"""Härkegård's active-set solver of :math:`\min \lVert A x - b\rVert`,
    ``lo <= x <= hi``.

    Härkegård, O., "Efficient active set algorithms for solving
    constrained least squares problems in aircraft control allocation",
    Proc. 41st IEEE CDC, 2002, Algorithm 2 (the primal active-set method
    of QCAT's ``wls_alloc``): from a feasible start with an empty working
    set, solve the unconstrained step on the free variables; if it is
    feasible, stop when every Lagrange multiplier
    :math:`\lambda_i = w_i\,a_i^T (b - A x)` is non-negative, else free the
    most negative one; if not, step to the first bound hit and add it to
    the working set. Exact in finitely many steps when ``A`` has full
    column rank.

    Parameters
    ----------
    A : numpy.ndarray, shape (K, N)
    b : numpy.ndarray, shape (K,)
    lo, hi : numpy.ndarray, shape (N,)
    x0 : numpy.ndarray, shape (N,), optional
        Feasible start (default the box centre).
    max_iter : int
        Iteration cap (the paper's ``imax``).

    Returns
    -------
    x : numpy.ndarray, shape (N,)
    iterations : int
    """
    n = A.shape[1]
    x = (lo + hi) / 2.0 if x0 is None else np.clip(x0, lo, hi)
    W = np.zeros(n)                       # -1 lower, +1 upper, 0 free
    fixed = lo == hi
    W[fixed] = 1.0
    free = ~fixed
    d = b - A @ x
    eps = 1e-12 * max(1.0, float(np.max(np.abs(A))) ** 2)
    for it in range(1, max_iter + 1):
        p = np.zeros(n)
        if free.any():
            p[free] = np.linalg.lstsq(A[:, free], d, rcond=None)[0]
        x_opt = x + p
        bad = free & ((x_opt < lo) | (x_opt > hi))
        if not bad.any():
            x = x_opt
            d = d - A @ p
            lam = W * (A.T @ d)
            lam[fixed] = np.inf
            i = int(np.argmin(lam))
            if lam[i] >= -eps:
                return x, it
            W[i] = 0.0
            free[i] = True
        else:
            dist = np.ones(n)
            neg = free & (p < 0)
            pos = free & (p > 0)
            dist[neg] = (lo[neg] - x[neg]) / p[neg]
            dist[pos] = (hi[pos] - x[pos]) / p[pos]
            i = int(np.argmin(dist))
            a = float(max(dist[i], 0.0))
            x = np.clip(x + a * p, lo, hi)
            x[i] = lo[i] if p[i] < 0 else hi[i]
            d = b - A @ x
            W[i] = np.sign(p[i])
            free[i] = False
    return np.clip(x, lo, hi), max_iter
