"""Euler–Krylov (airplane) angle kinematics, numpy and CasADi.

The airplane (Euler–Krylov) angles of the four-wheel model are roll γ
about X, yaw ψ about Y and pitch ϑ about Z, applied as pitch, then yaw,
then roll: :math:`C_{body\\leftarrow ref} = R_1(γ) R_2(ψ) R_3(ϑ)` with
passive elementary rotations. They are singular at :math:`\\cos ψ = 0`.
Quaternion conventions are those of `adcs_common.quaternion`.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_array
from adcs_common.quaternion import (Vector, array_lib, vcat, quat_mul,
                                    quat_to_dcm)

__all__ = [
    "body_rates_from_angle_rates",
    "dcm_body_from_ref_ek",
    "ek_angle_rates",
    "ek_angle_rates_function",
    "ek_from_quat",
    "quat_from_ek",
]

#: |cos ψ| below which the Euler–Krylov kinematics are declared singular.
EK_SINGULAR_TOL = 1e-6


def dcm_body_from_ref_ek(angles: Vector) -> Any:
    """:math:`C_{body\\leftarrow ref} = R_1(γ) R_2(ψ) R_3(ϑ)` ([3]).

    Parameters
    ----------
    angles : array_like or casadi, shape (3,)
        Roll γ, yaw ψ, pitch ϑ [rad].
    """
    lib = array_lib(angles)
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


def body_rates_from_angle_rates(angles: Vector, rates: Vector) -> Any:
    """Body rates from angle rates, [3] eq. (1).

    .. math::
        ω_x = \\dot γ - \\dot ϑ \\sin ψ,\\quad
        ω_y = \\dot ψ \\cos γ + \\dot ϑ \\sin γ \\cos ψ,\\quad
        ω_z = \\dot ϑ \\cos γ \\cos ψ - \\dot ψ \\sin γ

    Parameters
    ----------
    angles, rates : shape (3,)
        (γ, ψ, ϑ) [rad] and their rates [rad/s].
    """
    lib = array_lib(angles, rates)
    g, p = angles[0], angles[1]
    dg, dp, dt = rates[0], rates[1], rates[2]
    return vcat(lib, [
        dg - dt * lib.sin(p),
        dp * lib.cos(g) + dt * lib.sin(g) * lib.cos(p),
        dt * lib.cos(g) * lib.cos(p) - dp * lib.sin(g),
    ])


def ek_angle_rates(angles: Vector, w: Vector) -> Any:
    """Angle rates from body rates: the inverse of [3] eq. (1).

    .. math::
        \\dot ϑ = \\frac{ω_y \\sin γ + ω_z \\cos γ}{\\cos ψ},\\quad
        \\dot ψ = ω_y \\cos γ - ω_z \\sin γ,\\quad
        \\dot γ = ω_x + \\dot ϑ \\sin ψ

    Singular at :math:`\\cos ψ = 0` (yaw ±90°): there roll and pitch
    rotate about the same axis. The numpy version raises
    `InvalidValueError` within `EK_SINGULAR_TOL`; the CasADi version
    returns inf/NaN there, as the quaternion model never does.
    """
    lib = array_lib(angles, w)
    g, p = angles[0], angles[1]
    cp = lib.cos(p)
    if lib is np and abs(cp) < EK_SINGULAR_TOL:
        raise InvalidValueError(
            f"angles: yaw ψ = {p!r} rad is at the Euler–Krylov singularity "
            "cos ψ = 0; use the quaternion model")
    dt = (w[1] * lib.sin(g) + w[2] * lib.cos(g)) / cp
    dp = w[1] * lib.cos(g) - w[2] * lib.sin(g)
    dg = w[0] + dt * lib.sin(p)
    return vcat(lib, [dg, dp, dt])


def ek_angle_rates_function() -> ca.Function:
    """CasADi Function ``ek_rates(angles[3], w[3]) -> (rates[3])``."""
    a = ca.SX.sym("angles", 3)
    w = ca.SX.sym("w", 3)
    return ca.Function("ek_rates", [a, w], [ek_angle_rates(a, w)],
                       ["angles", "w"], ["rates"])


def quat_from_ek(angles: ArrayLike) -> np.ndarray:
    """Quaternion (body to reference) of Euler–Krylov angles (γ, ψ, ϑ)."""
    g, p, t = as_finite_array(angles, "angles", (3,))
    qz = np.array([np.cos(t / 2), 0.0, 0.0, np.sin(t / 2)])
    qy = np.array([np.cos(p / 2), 0.0, np.sin(p / 2), 0.0])
    qx = np.array([np.cos(g / 2), np.sin(g / 2), 0.0, 0.0])
    return quat_mul(quat_mul(qz, qy), qx)


def ek_from_quat(q: ArrayLike) -> np.ndarray:
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
