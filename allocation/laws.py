"""Closed-form allocation laws of [1] (numpy)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError, ShapeError
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_instance,
    check_positive,
)

from .arrays import WheelArray

#: Eq. (9) of [1] as printed (4 decimals). Its m2 row repeats m1:
#: ERRATUM, see `EQ9_GAINS` and the errata (docs/errata.md)
PAPER_EQ9_GAINS_PRINTED = np.array([
    [-0.4316, 0.4316, -0.4359],
    [-0.4316, 0.4316, -0.4359],
    [-0.4316, -0.4316, 0.4359],
    [-0.4316, 0.4316, 0.4359],
])

#: Eq. (9) corrected (theory §1.1): gains for δ = 55°, γ = 45°, 4 decimals.
EQ9_GAINS = np.array([
    [-0.4316, 0.4316, -0.4359],
    [-0.4316, -0.4316, -0.4359],
    [-0.4316, -0.4316, 0.4359],
    [-0.4316, 0.4316, 0.4359],
])

#: Sign matrix B of eq. (7): A = diag(sδcγ, sδsγ, cδ) B.
SIGN_MATRIX = np.array([
    [-1.0, -1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0, 1.0],
    [-1.0, -1.0, 1.0, 1.0],
])

#: The paper's four single-failure laws: 2 x (gain on M̂x, M̂y, M̂z) for each
#: wheel, failed wheel k (0-based) -> (4, 3) coefficients.
PAPER_FAILURE_LAWS = {
    0: np.array([[0, 0, 0], [-1, 0, -1], [0, -1, 1], [-1, 1, 0]]) / 2.0,
    1: np.array([[-1, 0, -1], [0, 0, 0], [-1, -1, 0], [0, 1, 1]]) / 2.0,
    2: np.array([[0, 1, -1], [-1, -1, 0], [0, 0, 0], [-1, 0, 1]]) / 2.0,
    3: np.array([[-1, 1, 0], [0, -1, -1], [-1, 0, 1], [0, 0, 0]]) / 2.0,
}


@dataclass(frozen=True, eq=False)
class LinearLaw:
    """A closed-form allocation law ``m = G M``.

    Attributes
    ----------
    gains : numpy.ndarray, shape (N, 3)
        Gain matrix G [1] (wheel torque per body torque).
    name : str
        Label for reports.
    """

    gains: np.ndarray
    name: str = "linear"

    def allocate(self, torque: ArrayLike) -> np.ndarray:
        """Wheel torques for body demand(s).

        Parameters
        ----------
        torque : array_like, shape (3,) or (3, K)
            Demanded array torque(s) M [N·m].

        Returns
        -------
        numpy.ndarray, shape (N,) or (N, K)
            Motor torques m [N·m].
        """
        M = as_finite_array(torque, "torque")
        if M.shape[:1] != (3,) or M.ndim > 2:
            raise ShapeError(
                f"torque must have shape (3,) or (3, K), got {M.shape}")
        if not np.all(np.isfinite(M)):
            raise InvalidValueError(f"torque must be finite, got {M!r}")
        return self.gains @ M


def _pinv_with_failures(array: WheelArray, weights=None) -> np.ndarray:
    array.require_full_rank()
    A = array.working_axes
    if weights is None:
        return A.T @ np.linalg.inv(A @ A.T)
    w_inv = 1.0 / weights
    AWi = A * w_inv
    return AWi.T @ np.linalg.inv(AWi @ A.T)


def min_norm_gains(array: WheelArray) -> np.ndarray:
    r"""Minimum-norm gains, [1] eq. (5), failures included.

    .. math:: m = A^T (A A^T)^{-1} M

    minimises :math:`J = \sum m_i^2` (eq. 4) subject to :math:`A m = M`.
    Failed wheels have their column of A zeroed ([1], "control
    algorithm under failures"), which makes their row of G zero: this is
    the general failure law for any set of failed wheels.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        The gain matrix G.

    Raises
    ------
    RankError
        The working wheels do not span 3-D space.
    """
    check_instance(array, WheelArray, "array")
    return _pinv_with_failures(array)


def min_norm_law(array: WheelArray) -> LinearLaw:
    """Return the minimum-norm law (eq. 5) of ``array`` as a `LinearLaw`."""
    check_instance(array, WheelArray, "array")
    return LinearLaw(min_norm_gains(array), "minimum-norm (eq. 5)")


def sign_matrix_gains(delta: float, gamma: float) -> np.ndarray:
    r"""Gains of the pyramid by the sign-matrix form, eqs. (7)-(8).

    .. math::
        m = \tfrac14 B^T \hat M,\quad
        \hat M = (M_x/(s_\delta c_\gamma),\; M_y/(s_\delta s_\gamma),
                   \; M_z/c_\delta),\quad B B^T = 4 I

    Parameters
    ----------
    delta, gamma : float
        Pyramid angles [rad].

    Returns
    -------
    numpy.ndarray, shape (4, 3)
    """
    scale = pyramid_scale(delta, gamma)
    return SIGN_MATRIX.T / 4.0 / scale


def pyramid_scale(delta: float, gamma: float) -> np.ndarray:
    """Row scales ``(sδcγ, sδsγ, cδ)`` with ``A = diag(scale) B``."""
    delta = as_finite_scalar(delta, "delta")
    gamma = as_finite_scalar(gamma, "gamma")
    return np.array([np.sin(delta) * np.cos(gamma),
                     np.sin(delta) * np.sin(gamma), np.cos(delta)])


def pyramid_failure_gains(failed: int, delta: float,
                          gamma: float) -> np.ndarray:
    r"""Return the paper's single-failure law of the pyramid.

    [1], "four variants": the failed wheel gives zero and the other
    three solve the 3x3 system, e.g. wheel 1 (index 0) failed:
    :math:`m_2 = \tfrac12(-\hat M_x - \hat M_z)`,
    :math:`m_3 = \tfrac12(-\hat M_y + \hat M_z)`,
    :math:`m_4 = \tfrac12(-\hat M_x + \hat M_y)`.

    Parameters
    ----------
    failed : int
        0-based index of the failed wheel (0..3).
    delta, gamma : float
        Pyramid angles [rad].

    Returns
    -------
    numpy.ndarray, shape (4, 3)
    """
    if isinstance(failed, bool) or not isinstance(failed, (int, np.integer)) \
            or failed not in PAPER_FAILURE_LAWS:
        raise InvalidValueError(
            f"failed must be a wheel index 0..3, got {failed!r}")
    return PAPER_FAILURE_LAWS[failed] / pyramid_scale(delta, gamma)


def weighted_gains(array: WheelArray, weights: ArrayLike) -> np.ndarray:
    r"""Weighted minimum-norm gains ([1], criterion of ref. [10]).

    .. math::
        \min \sum V_i m_i^2 \;\text{s.t.}\; A m = M \;\Rightarrow\;
        m = W^{-1}A^T (A W^{-1} A^T)^{-1} M,\quad W = \mathrm{diag}(V)

    Parameters
    ----------
    array : WheelArray
    weights : array_like (N,)
        Positive weights V_i (e.g. `WheelMotor.current_weights`).

    Returns
    -------
    numpy.ndarray, shape (N, 3)
    """
    check_instance(array, WheelArray, "array")
    w = as_vector(weights, array.n_wheels, "weights")
    check_positive(w, "weights")
    return _pinv_with_failures(array, w)


def weighted_law(array: WheelArray, weights: ArrayLike) -> LinearLaw:
    """Return the weighted law of ``array`` as a `LinearLaw`."""
    check_instance(array, WheelArray, "array")
    return LinearLaw(weighted_gains(array, weights), "weighted")


def allocate_min_norm(array: WheelArray, torque: ArrayLike) -> np.ndarray:
    """Minimum-norm wheel torques (N,) or (N, K) for demand(s) (3,)/(3, K).

    Convenience for ``min_norm_law(array).allocate(torque)``.
    """
    check_instance(array, WheelArray, "array")
    return min_norm_law(array).allocate(torque)
