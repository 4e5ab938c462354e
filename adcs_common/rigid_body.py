"""The rigid body with wheels, in numpy: right-hand side and RK4.

.. math::
    J\\dot ω = -ω \\times (Jω + h) + τ - \\dot h_m,\\qquad
    \\dot h = \\dot h_m,\\qquad \\dot q = \\tfrac12\\, q \\otimes (0, ω)

``h`` is the wheels' momentum in body axes [N·m·s] (``A H_w`` for an
array with spin axes ``A``), ``\\dot h_m`` the motor torque on the rotors
in body axes [N·m] (the body feels its reaction), ``τ`` the external
torque [N·m], ``q`` scalar-first (body to reference). The CasADi twin is
``ocp.models.rigid_spacecraft``; tests check they agree to 1e-12.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .exceptions import InvalidValueError, ShapeError
from .validation import as_finite_array

__all__ = ["body_rates", "check_inertia", "quat_rate_np", "rk4_step"]


def quat_rate_np(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """:math:`\\dot q = \\tfrac12 q \\otimes (0, ω)` (4,), numpy only."""
    qw, qv = q[0], q[1:]
    return np.concatenate([[-0.5 * qv @ w],
                           0.5 * (qw * w + np.cross(qv, w))])


def body_rates(J: np.ndarray, q: np.ndarray, w: np.ndarray, h: np.ndarray,
               tau: np.ndarray, hdot: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(q̇ (4,), ω̇ (3,))`` of the body (SI units, body axes).

    Parameters
    ----------
    J : (3, 3) inertia [kg·m²]; q : (4,); w : (3,) rate [rad/s];
    h : (3,) wheel momentum [N·m·s]; tau : (3,) external torque [N·m];
    hdot : (3,) motor torque on the rotors [N·m].
    """
    wdot = np.linalg.solve(J, -np.cross(w, J @ w + h) + tau - hdot)
    return quat_rate_np(q, w), wdot


def rk4_step(f: Callable[..., Sequence[np.ndarray]],
             state: Sequence[np.ndarray], dt: float
             ) -> list[np.ndarray]:
    """One classical RK4 step of ``ẏ = f(*y)`` for a tuple of arrays ``y``.

    The inputs of ``f`` besides the state are held over ``dt`` [s]
    (bind them in ``f``); returns the new state as a list.
    """
    def shifted(k, a):
        return [y + a * dt * dy for y, dy in zip(state, k)]

    k1 = f(*state)
    k2 = f(*shifted(k1, 0.5))
    k3 = f(*shifted(k2, 0.5))
    k4 = f(*shifted(k3, 1.0))
    return [y + dt / 6 * (a + 2 * b + 2 * c + d)
            for y, a, b, c, d in zip(state, k1, k2, k3, k4)]


def check_inertia(inertia: ArrayLike, name: str = "inertia") -> np.ndarray:
    """Return ``inertia`` as a symmetric positive-definite (3, 3) array.

    A length-3 vector is read as the principal moments [kg·m²]. Every
    principal moment must lie in [1e-9, 1e12] kg·m² (a bolt to a space
    station); outside, the dynamics divide by nothing or overflow.

    Raises
    ------
    ShapeError, InvalidValueError
        Wrong shape, asymmetric, not positive definite or degenerate.
    """
    J = as_finite_array(inertia, name)
    if J.shape == (3,):
        J = np.diag(J)
    if J.shape != (3, 3):
        raise ShapeError(f"{name} must have shape (3, 3) or (3,), got "
                         f"{J.shape}")
    if not np.allclose(J, J.T, rtol=0.0, atol=1e-12 * np.abs(J).max()):
        raise InvalidValueError(f"{name} must be symmetric, got {J}")
    eig = np.linalg.eigvalsh(J)
    if eig.min() <= 0.0:
        raise InvalidValueError(
            f"{name} must be positive definite, eigenvalues {eig}")
    if eig.min() < 1e-9 or eig.max() > 1e12:
        raise InvalidValueError(
            f"{name}: principal moments {eig} kg·m² lie outside "
            "[1e-9, 1e12] (degenerate physics)")
    return J
