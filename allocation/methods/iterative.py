"""Iterative methods: fixed-point iteration and weighted least squares.

Both take a `WheelArray` (axes (3, N), ``m_max`` [N·m], failed wheels at
zero), a demand ``M`` (3,) [N·m] and optional bounds ``lo``/``hi`` (N,)
[N·m], and return wheel torques (N,) [N·m].
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_array

from ..arrays import WheelArray
from ._common import bounded_lsq, problem


def _fixed_point_operator(A: np.ndarray, epsilon: float
                          ) -> tuple[np.ndarray, float]:
    """``(I - ηH (N, N), (1-ε)η)`` of the fixed-point iteration.

    ``H = (1-ε) AᵀA + εI``, ``η = 1/|H|_F``; the iteration is
    ``m ← sat[(1-ε)η AᵀM + (I - ηH) m]``.
    """
    if not 0.0 < epsilon < 1.0:
        raise InvalidValueError(f"epsilon must lie in (0, 1), got {epsilon}")
    n = A.shape[1]
    H = (1.0 - epsilon) * A.T @ A + epsilon * np.eye(n)
    eta = 1.0 / float(np.linalg.norm(H, "fro"))
    return np.eye(n) - eta * H, (1.0 - epsilon) * eta


def fixed_point_batch(array: WheelArray, torques: ArrayLike,
                      epsilon: float = 1e-4, max_iter: int = 2000,
                      tol: float = 1e-12) -> np.ndarray:
    """`fixed_point` for demands (K, 3) [N·m] at once; torques (K, N)."""
    T = as_finite_array(torques, "torques", (None, 3))
    A, _, low, high = problem(array, np.zeros(3), None, None)
    step, gain = _fixed_point_operator(A, epsilon)
    drive = gain * (T @ A)                          # (K, N)
    u = np.zeros((T.shape[0], A.shape[1]))
    lim = tol * float(np.max(array.m_max))
    for _ in range(max_iter):
        new = np.clip(drive + u @ step.T, low, high)
        moved = float(np.max(np.abs(new - u))) if u.size else 0.0
        u = new
        if moved <= lim:
            break
    return u


def fixed_point(array: WheelArray, torque: ArrayLike,
                lo: ArrayLike | None = None, hi: ArrayLike | None = None,
                epsilon: float = 1e-4, max_iter: int = 2000,
                tol: float = 1e-12) -> np.ndarray:
    r"""Fixed-point iteration of Burken et al.

    Burken, J. J., Lu, P., Wu, Z. and Bahm, C., "Two reconfigurable
    flight-control design methods: robust servomechanism and control
    allocation", Journal of Guidance, Control, and Dynamics 24(3),
    482–493, 2001 (the algorithm as evaluated in Bodson 2002, eq. 36).

    Minimises :math:`J = (1-\varepsilon)\lVert A m - M\rVert^2 +
    \varepsilon \lVert m\rVert^2` over the box by the projected iteration

    .. math:: m_{k+1} = \mathrm{sat}\big[(1-\varepsilon)\,\eta\,A^T M
              - (\eta H - I)\,m_k\big],\quad
              H = (1-\varepsilon) A^T A + \varepsilon I,\;
              \eta = 1/\lVert H\rVert_F

    from :math:`m_0 = 0`, until a step moves no wheel by more than
    ``tol * max(m_max)`` or after ``max_iter`` steps.

    Converges to the least-squares QP (``QPAllocator(...,
    saturation="least_squares")``) as ε → 0, with a bias of order ε in
    both the torque error and the wheel torques; the null-space part
    converges at the slow rate 1 − ηε per step (Bodson 2002).

    Parameters
    ----------
    epsilon : float
        ε in (0, 1) [1], the weight of the control effort.
    max_iter : int
        Iteration cap.
    tol : float
        Stopping step, relative to the largest ``m_max`` [1].

    Returns
    -------
    numpy.ndarray, shape (N,)
        Wheel torques [N·m].
    """
    A, M, low, high = problem(array, torque, lo, hi)
    step, gain = _fixed_point_operator(A, epsilon)
    drive = gain * (A.T @ M)
    u = np.clip(np.zeros(A.shape[1]), low, high)
    lim = tol * float(np.max(array.m_max))
    for _ in range(int(max_iter)):
        new = np.clip(drive + step @ u, low, high)
        moved = float(np.max(np.abs(new - u)))
        u = new
        if moved <= lim:
            break
    return u


def wls_alloc(array: WheelArray, torque: ArrayLike,
              lo: ArrayLike | None = None, hi: ArrayLike | None = None,
              gamma: float = 1e6, weights: ArrayLike | None = None,
              max_iter: int = 100) -> np.ndarray:
    r"""Weighted least squares by the active-set method (``wls_alloc``).

    Härkegård, O., "Efficient active set algorithms for solving
    constrained least squares problems in aircraft control allocation",
    Proc. 41st IEEE Conference on Decision and Control, 2002 (eq. 5 and
    Algorithm 2; the ``wls_alloc`` of his QCAT toolbox).

    .. math:: \min_{lo \le m \le hi}\;
              \lVert W_u m\rVert^2 + \gamma\,\lVert A m - M\rVert^2
              = \Big\lVert \begin{pmatrix}\gamma^{1/2} A\\ W_u\end{pmatrix}
              m - \begin{pmatrix}\gamma^{1/2} M\\ 0\end{pmatrix}\Big\rVert^2

    solved exactly by the primal active-set iteration (`bounded_lsq`),
    started at the box centre. The weighting γ of the demand error makes
    the answer approach the least-squares QP (``QPAllocator(...,
    saturation="least_squares")``, weights ``W_u²``) as γ → ∞; the gap
    is of order 1/γ.

    Parameters
    ----------
    gamma : float
        γ > 0 [1/(N·m)² relative to the control term]; QCAT's default 1e6.
    weights : array_like (N,), optional
        Diagonal of :math:`W_u` (default ones).
    max_iter : int
        The paper's ``imax``.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Wheel torques [N·m].
    """
    A, M, low, high = problem(array, torque, lo, hi)
    n = A.shape[1]
    if not gamma > 0.0:
        raise InvalidValueError(f"gamma must be positive, got {gamma}")
    wu = np.ones(n) if weights is None else np.sqrt(np.asarray(
        weights, dtype=float))
    g = np.sqrt(gamma)
    big = np.vstack([g * A, np.diag(wu)])
    rhs = np.concatenate([g * M, np.zeros(n)])
    m, _ = bounded_lsq(big, rhs, low, high, max_iter=max_iter)
    return m
