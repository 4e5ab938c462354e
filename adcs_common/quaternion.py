"""Quaternion algebra shared by every package, numpy and CasADi alike.

Conventions: quaternions are scalar-first ``(w, x, y, z)``; a quaternion
``q`` maps body vectors to the reference (orbit or inertial) frame,
:math:`v_{ref} = R(q)\\,v_{body}`, and the body rate ``ω`` is expressed in
body axes, so :math:`\\dot q = \\tfrac12 q \\otimes (0, ω)`. Each function
takes numpy arrays or CasADi symbols and returns the same kind.
"""

from __future__ import annotations

from typing import Any, Sequence, Union

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_angle, as_finite_array

#: What the quaternion algebra takes: a numpy array or sequence, or a
#: CasADi SX, MX or DM (the result is of the same kind).
Vector = Union[np.ndarray, Sequence[float], ca.SX, ca.MX, ca.DM]

__all__ = [
    "Vector",
    "as_unit_quaternion",
    "quat_conj",
    "quat_error_angle",
    "quat_from_axis_angle",
    "quat_mul",
    "quat_rate",
    "quat_to_dcm",
    "rotation_between",
]


def array_lib(*args):
    """Return ``ca`` if any argument is symbolic, else ``np``."""
    symbolic = (ca.SX, ca.MX, ca.DM)
    return ca if any(isinstance(a, symbolic) for a in args) else np


def vcat(lib, items):
    return ca.vertcat(*items) if lib is ca else np.array(items)


def quat_mul(p: Vector, q: Vector) -> Any:
    """Hamilton product ``p ⊗ q`` of scalar-first quaternions (numpy/CasADi).

    .. math::
        p \\otimes q = (p_w q_w - p_v\\cdot q_v,\\;
                        p_w q_v + q_w p_v + p_v \\times q_v)
    """
    lib = array_lib(p, q)
    a: Any = p
    b: Any = q
    pw, px, py, pz = a[0], a[1], a[2], a[3]
    qw, qx, qy, qz = b[0], b[1], b[2], b[3]
    return vcat(lib, [
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ])


def quat_conj(q: Vector) -> Any:
    """Conjugate ``(w, -x, -y, -z)`` (the inverse of a unit quaternion)."""
    lib = array_lib(q)
    a: Any = q
    return vcat(lib, [a[0], -a[1], -a[2], -a[3]])


def quat_rate(q: Vector, w: Vector) -> Any:
    """Quaternion kinematics :math:`\\dot q = \\tfrac12 q \\otimes (0, ω)`.

    Parameters
    ----------
    q : array_like or casadi, shape (4,)
        Attitude quaternion (body to reference).
    w : array_like or casadi, shape (3,)
        Body angular rate in body axes [rad/s].
    """
    lib = array_lib(q, w)
    r: Any = w
    omega = vcat(lib, [0 * r[0], r[0], r[1], r[2]])
    return 0.5 * quat_mul(q, omega)


def quat_to_dcm(q: Vector) -> Any:
    """Rotation matrix :math:`R(q)` with :math:`v_{ref} = R v_{body}`."""
    lib = array_lib(q)
    a: Any = q
    w, x, y, z = a[0], a[1], a[2], a[3]
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    if lib is ca:
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])
    return np.array(rows, dtype=float)


def quat_from_axis_angle(axis: ArrayLike, angle: float) -> np.ndarray:
    """Return the quaternion of a rotation by ``angle`` [rad] about ``axis``.

    Raises
    ------
    InvalidValueError
        ``axis`` has zero length, or ``|angle| > 2π`` (degrees given for
        radians: the message suggests ``np.deg2rad``).
    """
    a = as_finite_array(axis, "axis", (3,))
    n = np.linalg.norm(a)
    if n < 1e-12:
        raise InvalidValueError(f"axis must be non-zero, got {a}")
    half = 0.5 * as_angle(angle, "angle")
    return np.concatenate([[np.cos(half)], np.sin(half) * a / n])


def rotation_between(q0: ArrayLike, qf: ArrayLike) -> tuple[np.ndarray, float]:
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


def quat_error_angle(q: ArrayLike, qf: ArrayLike) -> np.ndarray:
    """Angle [rad] between attitudes ``q`` (…, 4) and ``qf`` (4,).

    ``2 atan2(|v|, |w|)`` of the error quaternion ``(w, v) = q_f* ⊗ q``:
    accurate down to the last bits of the quaternions (``2 acos(q·q_f)``
    reads a rounding δ of q·q_f as an angle of up to 2√(2δ): 3e-8 rad
    in double, 0.05° for float quaternions), and independent of their
    norms.
    """
    q = np.asarray(q, dtype=float)
    f = np.asarray(qf, dtype=float)
    w = q @ f
    v = (f[0] * q[..., 1:] - q[..., :1] * f[1:]
         - np.cross(f[1:], q[..., 1:]))
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=-1), np.abs(w))


def as_unit_quaternion(q, name: str = "q") -> np.ndarray:
    """Return ``q`` (4,) normalised; refuse what is not a quaternion.

    Any finite non-zero 4-vector is normalised (scaled by its largest
    entry first, so 1e200 or 1e-200 entries neither overflow nor vanish);
    a scalar, a wrong length, NaN, inf or the zero vector raises.

    Raises
    ------
    ShapeError, InvalidValueError
    """
    q = as_finite_array(q, name, (4,))
    big = float(np.abs(q).max())
    if big == 0.0:
        raise InvalidValueError(f"{name} must be a non-zero quaternion")
    q = q / big
    return q / np.linalg.norm(q)
