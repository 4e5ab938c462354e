"""CasADi versions of the thruster force/torque matrices (AD, codegen)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from .unit import SIX_UNIT_ANGLES


def force_torque_sym(positions, directions, center_of_mass, levels):
    """Force and torque matrices for symbolic or numeric data.

    .. math::
        F_{:,i} = P_i d_i,\\qquad M_{:,i} = P_i (r_i - c) \\times d_i

    Parameters
    ----------
    positions, directions : casadi expression, shape (3, n)
    center_of_mass : casadi expression, shape (3, 1)
    levels : casadi expression, shape (n, 1)
        Cycle thrust levels :math:`K_{pi}(a_i p_{in} + b_i)` [N].

    Returns
    -------
    tuple of casadi expressions
        ``(F, M)``, each (3, n).
    """
    n = positions.shape[1]
    cols_f, cols_m = [], []
    for i in range(n):
        r = positions[:, i] - center_of_mass
        d = directions[:, i]
        cols_f.append(levels[i] * d)
        cols_m.append(levels[i] * ca.cross(r, d))
    return ca.horzcat(*cols_f), ca.horzcat(*cols_m)


def force_torque_function(n: int) -> ca.Function:
    """General thruster set as a casadi Function.

    Returns
    -------
    casadi.Function
        ``thruster_matrices(positions[3xn], directions[3xn], com[3],
        pressure, a[n], b[n], K_p[n]) -> (F[3xn], M[3xn])`` with levels
        :math:`K_p (a p + b)` ([4] eqs. 1, 4).
    """
    pos = ca.SX.sym("positions", 3, n)
    dirs = ca.SX.sym("directions", 3, n)
    com = ca.SX.sym("com", 3)
    p = ca.SX.sym("pressure")
    a = ca.SX.sym("a", n)
    b = ca.SX.sym("b", n)
    kp = ca.SX.sym("K_p", n)
    F, M = force_torque_sym(pos, dirs, com, kp * (a * p + b))
    return ca.Function(
        "thruster_matrices", [pos, dirs, com, p, a, b, kp], [F, M],
        ["positions", "directions", "com", "pressure", "a", "b", "K_p"],
        ["F", "M"])


def six_unit_geometry_sym(R, L):
    """Positions and directions (3, 6) of the unit of [4], symbolic."""
    c = [float(np.cos(t)) for t in SIX_UNIT_ANGLES]
    s = [float(np.sin(t)) for t in SIX_UNIT_ANGLES]
    order = [0, 1, 2, 0, 2, 1]
    xs = [R * c[j] for j in order]
    zs = [R * s[j] for j in order]
    ys = [-L, -L, -L, L, L, L]
    pos = ca.vertcat(ca.horzcat(*xs), ca.horzcat(*ys), ca.horzcat(*zs))
    dirs = ca.DM([[0] * 6, [1, 1, 1, -1, -1, -1], [0] * 6])
    return pos, dirs


def six_unit_function() -> ca.Function:
    """Build the six-thruster unit of [4] as a casadi Function.

    Returns
    -------
    casadi.Function
        ``six_unit_matrices(R, L, pressure, a[6], b[6], K_p[6]) ->
        (F[3x6], M[3x6], levels[6])``: force and torque per unit duty
        (Table 1 arms times cycle thrust, eqs. 1, 4), symbolic in the
        geometry, the thrust-model coefficients and the inlet pressure.
    """
    R = ca.SX.sym("R")
    L = ca.SX.sym("L")
    p = ca.SX.sym("pressure")
    a = ca.SX.sym("a", 6)
    b = ca.SX.sym("b", 6)
    kp = ca.SX.sym("K_p", 6)
    pos, dirs = six_unit_geometry_sym(R, L)
    levels = kp * (a * p + b)
    F, M = force_torque_sym(pos, ca.SX(dirs), ca.SX.zeros(3), levels)
    return ca.Function(
        "six_unit_matrices", [R, L, p, a, b, kp], [F, M, levels],
        ["R", "L", "pressure", "a", "b", "K_p"], ["F", "M", "levels"])
