"""Conversions between Basilisk's conventions and the toolbox's."""

from __future__ import annotations

import numpy as np

from adcs_common.validation import as_finite_array
from allocation import WheelArray


def mrp_to_quaternion(sigma) -> np.ndarray:
    """Scalar-first unit quaternion (4,) of the MRP ``sigma`` (3,)."""
    s = as_finite_array(sigma, "sigma", (3,))
    s2 = float(s @ s)
    return np.r_[1.0 - s2, 2.0 * s] / (1.0 + s2)


def quaternion_to_mrp(q) -> np.ndarray:
    """MRP (3,) of the scalar-first quaternion ``q``, the short rotation."""
    q = as_finite_array(q, "q", (4,))
    q = q / np.linalg.norm(q)
    if q[0] < 0:
        q = -q
    return q[1:] / (1.0 + q[0])


def mrp_angle(sigma) -> float:
    """Rotation angle [rad] of the MRP ``sigma`` (``4 atan |σ|``)."""
    return float(4.0 * np.arctan(np.linalg.norm(sigma)))


def gs_matrix(array: WheelArray) -> list[float]:
    """Basilisk's ``GsMatrix_B`` (the spin axes, wheel after wheel)."""
    return [float(v) for v in np.asarray(array.axes).T.ravel()]


def body_torque(array: WheelArray, motor_torques) -> np.ndarray:
    """Torque [N·m] the body receives from the wheels' motor torques."""
    return -np.asarray(array.axes) @ np.asarray(motor_torques, float)


def hub_inertia(inertia, array: WheelArray, Js) -> np.ndarray:
    """Basilisk's ``IHubPntBc_B`` [kg·m²] for the toolbox's inertia ``J``.

    The toolbox's ``J`` leaves the rotors' spin-axis inertia out (their
    momentum is in ``H_w``); Basilisk's balanced-wheel model wants the hub
    inertia with it in: ``J + Σ J_s,i g_i g_iᵀ``. With this hub and the
    rotor momenta ``H_w,i = J_s,i (Ω_i + g_iᵀ ω)`` both models integrate
    the same motion (tests: to 1e-8 over 10 s).
    """
    G = np.asarray(array.axes, float)
    js = np.broadcast_to(np.asarray(Js, float), (G.shape[1],))
    return np.asarray(inertia, float) + (G * js) @ G.T


def rotor_momenta(array: WheelArray, Js, wheel_speeds, omega) -> np.ndarray:
    """``H_w`` [N·m·s] from Basilisk's relative wheel speeds Ω [rad/s]."""
    G = np.asarray(array.axes, float)
    js = np.broadcast_to(np.asarray(Js, float), (G.shape[1],))
    return js * (np.asarray(wheel_speeds, float) + G.T @ np.asarray(omega))
