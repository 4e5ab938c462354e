"""Quaternion and Euler–Krylov (airplane) angle kinematics, numpy and CasADi.

Conventions (SPEC 3): quaternions are scalar-first ``(w, x, y, z)``; a
quaternion ``q`` maps body vectors to the reference (orbit or inertial)
frame, :math:`v_{ref} = R(q)\\,v_{body}`, and the body rate ``ω`` is
expressed in body axes, so :math:`\\dot q = \\tfrac12 q \\otimes (0, ω)`.

The airplane (Euler–Krylov) angles of seed 003 are roll γ about X, yaw ψ
about Y and pitch ϑ about Z, applied as pitch, then yaw, then roll:
:math:`C_{body\\leftarrow ref} = R_1(γ) R_2(ψ) R_3(ϑ)` with passive
elementary rotations. They are singular at :math:`\\cos ψ = 0`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_array

__all__ = [
    "body_rates_from_angle_rates",
    "dcm_body_from_ref_ek",
    "ek_angle_rates",
    "ek_angle_rates_function",
    "ek_from_quat",
    "quat_conj",
    "quat_error_angle",
    "quat_from_axis_angle",
    "quat_from_ek",
    "quat_mul",
    "quat_rate",
    "quat_to_dcm",
    "rotation_between",
]

#: |cos ψ| below which the Euler–Krylov kinematics are declared singular.
EK_SINGULAR_TOL = 1e-6


def _lib(*args):
    """Return ``ca`` if any argument is symbolic, else ``np``."""
    symbolic = (ca.SX, ca.MX, ca.DM)
    return ca if any(isinstance(a, symbolic) for a in args) else np


def _vcat(lib, items):
    return ca.vertcat(*items) if lib is ca else np.array(items)


def quat_mul(p, q):
    """Hamilton product ``p ⊗ q`` of scalar-first quaternions (numpy/CasADi).

    .. math::
        p \\otimes q = (p_w q_w - p_v\\cdot q_v,\\;
                        p_w q_v + q_w p_v + p_v \\times q_v)
    """
    lib = _lib(p, q)
    pw, px, py, pz = p[0], p[1], p[2], p[3]
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    return _vcat(lib, [
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ])


def quat_conj(q):
    """Conjugate ``(w, -x, -y, -z)`` (the inverse of a unit quaternion)."""
    lib = _lib(q)
    return _vcat(lib, [q[0], -q[1], -q[2], -q[3]])


def quat_rate(q, w):
    """Quaternion kinematics :math:`\\dot q = \\tfrac12 q \\otimes (0, ω)`.

    Parameters
    ----------
    q : array_like or casadi, shape (4,)
        Attitude quaternion (body to reference).
    w : array_like or casadi, shape (3,)
        Body angular rate in body axes [rad/s].
    """
    lib = _lib(q, w)
    omega = _vcat(lib, [0 * w[0], w[0], w[1], w[2]])
    return 0.5 * quat_mul(q, omega)


def quat_to_dcm(q):
    """Rotation matrix :math:`R(q)` with :math:`v_{ref} = R v_{body}`."""
    lib = _lib(q)
    w, x, y, z = q[0], q[1], q[2], q[3]
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    if lib is ca:
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])
    return np.array(rows, dtype=float)


def quat_from_axis_angle(axis, angle: float) -> np.ndarray:
    """Return the quaternion of a rotation by ``angle`` [rad] about ``axis``.

    Raises
    ------
    InvalidValueError
        ``axis`` has zero length.
    """
    a = as_finite_array(axis, "axis", (3,))
    n = np.linalg.norm(a)
    if n < 1e-12:
        raise InvalidValueError(f"axis must be non-zero, got {a}")
    half = 0.5 * float(angle)
    return np.concatenate([[np.cos(half)], np.sin(half) * a / n])


def rotation_between(q0, qf) -> tuple[np.ndarray, float]:
    """Eigenaxis (body frame) and angle of the rotation from ``q0`` to ``qf``.

    The shortest of the two equivalent rotations is returned, angle in
    ``[0, π]``.

    Returns
    -------
    axis : numpy.ndarray, shape (3,)
        Unit eigenaxis in body axes (``[1, 0, 0]`` for a zero rotation).
    angle : float
        Rotation angle [rad].
    """
    dq = quat_mul(quat_conj(np.asarray(q0, float)), np.asarray(qf, float))
    if dq[0] < 0:
        dq = -dq
    s = np.linalg.norm(dq[1:])
    angle = 2.0 * np.arctan2(s, dq[0])
    if s < 1e-15:
        return np.array([1.0, 0.0, 0.0]), 0.0
    return dq[1:] / s, float(angle)


def quat_error_angle(q, qf) -> np.ndarray:
    """Angle [rad] between attitudes ``q`` (…, 4) and ``qf`` (4,)."""
    q = np.asarray(q, dtype=float)
    dot = np.abs(q @ np.asarray(qf, dtype=float))
    dot = dot / (np.linalg.norm(q, axis=-1) * np.linalg.norm(qf))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


# ------------------------------------------------------- Euler–Krylov angles
def dcm_body_from_ref_ek(angles):
    """:math:`C_{body\\leftarrow ref} = R_1(γ) R_2(ψ) R_3(ϑ)` (seed 003).

    Parameters
    ----------
    angles : array_like or casadi, shape (3,)
        Roll γ, yaw ψ, pitch ϑ [rad].
    """
    lib = _lib(angles)
    g, p, t = angles[0], angles[1], angles[2]
    cg, sg = lib.cos(g), lib.sin(g)
    cp, sp = lib.cos(p), lib.sin(p)
    ct, st = lib.cos(t), lib.sin(t)
    rows = [
        [cp * ct, cp * st, -sp],
        [sg * sp * ct - cg * st, sg * sp * st + cg * ct, sg * cp],
        [cg * sp * ct + sg * st, cg * sp * st - sg * ct, cg * cp],
    ]
    if lib is ca:
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])
    return np.array(rows, dtype=float)


def body_rates_from_angle_rates(angles, rates):
    """Body rates from angle rates, seed 003 eq. (1).

    .. math::
        ω_x = \\dot γ - \\dot ϑ \\sin ψ,\\quad
        ω_y = \\dot ψ \\cos γ + \\dot ϑ \\sin γ \\cos ψ,\\quad
        ω_z = \\dot ϑ \\cos γ \\cos ψ - \\dot ψ \\sin γ

    Parameters
    ----------
    angles, rates : shape (3,)
        (γ, ψ, ϑ) [rad] and their rates [rad/s].
    """
    lib = _lib(angles, rates)
    g, p = angles[0], angles[1]
    dg, dp, dt = rates[0], rates[1], rates[2]
    return _vcat(lib, [
        dg - dt * lib.sin(p),
        dp * lib.cos(g) + dt * lib.sin(g) * lib.cos(p),
        dt * lib.cos(g) * lib.cos(p) - dp * lib.sin(g),
    ])


def ek_angle_rates(angles, w):
    """Angle rates from body rates: the inverse of seed 003 eq. (1).

    .. math::
        \\dot ϑ = \\frac{ω_y \\sin γ + ω_z \\cos γ}{\\cos ψ},\\quad
        \\dot ψ = ω_y \\cos γ - ω_z \\sin γ,\\quad
        \\dot γ = ω_x + \\dot ϑ \\sin ψ

    Singular at :math:`\\cos ψ = 0` (yaw ±90°): there roll and pitch
    rotate about the same axis. The numpy version raises
    `InvalidValueError` within `EK_SINGULAR_TOL`; the CasADi version
    returns inf/NaN there, as the quaternion model never does.
    """
    lib = _lib(angles, w)
    g, p = angles[0], angles[1]
    cp = lib.cos(p)
    if lib is np and abs(cp) < EK_SINGULAR_TOL:
        raise InvalidValueError(
            f"angles: yaw ψ = {p!r} rad is at the Euler–Krylov singularity "
            "cos ψ = 0; use the quaternion model")
    dt = (w[1] * lib.sin(g) + w[2] * lib.cos(g)) / cp
    dp = w[1] * lib.cos(g) - w[2] * lib.sin(g)
    dg = w[0] + dt * lib.sin(p)
    return _vcat(lib, [dg, dp, dt])


def ek_angle_rates_function() -> ca.Function:
    """CasADi Function ``ek_rates(angles[3], w[3]) -> (rates[3])``."""
    a = ca.SX.sym("angles", 3)
    w = ca.SX.sym("w", 3)
    return ca.Function("ek_rates", [a, w], [ek_angle_rates(a, w)],
                       ["angles", "w"], ["rates"])


def quat_from_ek(angles) -> np.ndarray:
    """Quaternion (body to reference) of Euler–Krylov angles (γ, ψ, ϑ)."""
    g, p, t = as_finite_array(angles, "angles", (3,))
    qz = np.array([np.cos(t / 2), 0.0, 0.0, np.sin(t / 2)])
    qy = np.array([np.cos(p / 2), 0.0, np.sin(p / 2), 0.0])
    qx = np.array([np.cos(g / 2), np.sin(g / 2), 0.0, 0.0])
    return quat_mul(quat_mul(qz, qy), qx)


def ek_from_quat(q) -> np.ndarray:
    """Euler–Krylov angles (γ, ψ, ϑ) [rad] of a quaternion.

    ψ is returned in ``[-π/2, π/2]``; at the singularity the split between
    γ and ϑ is arbitrary (γ is set to zero).
    """
    q = as_finite_array(q, "q", (4,))
    C = quat_to_dcm(q / np.linalg.norm(q)).T  # body <- ref
    p = np.arcsin(np.clip(-C[0, 2], -1.0, 1.0))
    if abs(np.cos(p)) < EK_SINGULAR_TOL:
        return np.array([0.0, p, np.arctan2(-C[1, 0], C[1, 1])])
    g = np.arctan2(C[1, 2], C[2, 2])
    t = np.arctan2(C[0, 1], C[0, 0])
    return np.array([g, p, t])
