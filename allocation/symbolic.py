"""CasADi versions of the arrays and closed-form laws (for AD and codegen)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from .arrays import PYRAMID_SIGN_Y, PYRAMID_SIGN_Z, WheelArray
from .laws import SIGN_MATRIX


def pyramid_axes_sym(delta: ca.SX, gamma: ca.SX) -> ca.SX:
    """Symbolic pyramid axes (3, 4), [1] eq. (6).

    ``delta`` and ``gamma`` are scalars or 4-vectors (per-wheel angles).
    """
    d = delta if delta.numel() == 4 else ca.repmat(delta, 4, 1)
    g = gamma if gamma.numel() == 4 else ca.repmat(gamma, 4, 1)
    sy = ca.DM(PYRAMID_SIGN_Y)
    sz = ca.DM(PYRAMID_SIGN_Z)
    return ca.vertcat(
        (-ca.sin(d) * ca.cos(g)).T,
        (sy * ca.sin(d) * ca.sin(g)).T,
        (sz * ca.cos(d)).T,
    )


def pyramid_axes_function(per_wheel: bool = True) -> ca.Function:
    """A(δ, γ) of the pyramid as a casadi Function.

    Parameters
    ----------
    per_wheel : bool
        True: inputs ``delta`` and ``gamma`` are 4-vectors (per-wheel
        mounting angles [rad]); False: scalars.

    Returns
    -------
    casadi.Function
        ``pyramid_axes(delta, gamma) -> (A)`` with A of shape (3, 4);
        differentiate it with ``jacobian`` or ``ca.jacobian``.
    """
    n = 4 if per_wheel else 1
    delta = ca.SX.sym("delta", n)
    gamma = ca.SX.sym("gamma", n)
    return ca.Function("pyramid_axes", [delta, gamma],
                       [pyramid_axes_sym(delta, gamma)],
                       ["delta", "gamma"], ["A"])


def min_norm_sym(A, torque, weights=None):
    """Eq. (5) (or its weighted form) for symbolic or numeric A.

    .. math:: m = W^{-1}A^T (A W^{-1} A^T)^{-1} M

    Parameters
    ----------
    A : casadi.SX/MX/DM, shape (3, N)
        Working axes (failed columns zeroed).
    torque : casadi expression, shape (3, 1)
        Demanded torque M [N·m].
    weights : casadi expression (N, 1), optional
        Positive weights V_i (None: all ones).
    """
    AWi = A if weights is None else A @ ca.diag(1.0 / weights)
    return AWi.T @ ca.solve(AWi @ A.T, torque)


def min_norm_function(array: WheelArray) -> ca.Function:
    """Minimum-norm law (eq. 5) of ``array`` as ``min_norm(M) -> (m)``."""
    array.require_full_rank()
    M = ca.SX.sym("M", 3)
    A = ca.DM(array.working_axes)
    return ca.Function("min_norm", [M], [min_norm_sym(A, M)], ["M"], ["m"])


def weighted_function(array: WheelArray) -> ca.Function:
    """Weighted law of ``array`` as ``weighted(M, V) -> (m)``."""
    array.require_full_rank()
    M = ca.SX.sym("M", 3)
    V = ca.SX.sym("V", array.n_wheels)
    A = ca.DM(array.working_axes)
    return ca.Function("weighted", [M, V], [min_norm_sym(A, M, V)],
                       ["M", "V"], ["m"])


def pyramid_min_norm_function() -> ca.Function:
    """``pyramid_min_norm(M, delta, gamma) -> (m)``, fully symbolic.

    The minimum-norm law (eq. 5) of the pyramid with per-wheel angles as
    inputs, so a study can differentiate wheel torques with respect to the
    mounting angles.
    """
    M = ca.SX.sym("M", 3)
    delta = ca.SX.sym("delta", 4)
    gamma = ca.SX.sym("gamma", 4)
    m = min_norm_sym(pyramid_axes_sym(delta, gamma), M)
    return ca.Function("pyramid_min_norm", [M, delta, gamma], [m],
                       ["M", "delta", "gamma"], ["m"])


def sign_matrix_function() -> ca.Function:
    """Eqs. (7)-(8): ``sign_matrix_law(M, delta, gamma) -> (m)``."""
    M = ca.SX.sym("M", 3)
    delta = ca.SX.sym("delta")
    gamma = ca.SX.sym("gamma")
    scale = ca.vertcat(ca.sin(delta) * ca.cos(gamma),
                       ca.sin(delta) * ca.sin(gamma), ca.cos(delta))
    m = ca.DM(SIGN_MATRIX.T / 4.0) @ (M / scale)
    return ca.Function("sign_matrix_law", [M, delta, gamma], [m],
                       ["M", "delta", "gamma"], ["m"])


def gains_function(gains: np.ndarray, name: str = "linear_law"
                   ) -> ca.Function:
    """Any gain matrix G (N, 3) as ``name(M) -> (m)`` for code generation."""
    M = ca.SX.sym("M", 3)
    return ca.Function(name, [M], [ca.DM(gains) @ M], ["M"], ["m"])
