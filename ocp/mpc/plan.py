"""The MPC plan's shift (warm start) and its checks, as CasADi Functions."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .keepout import cone_function, plan_cone_violation
from .problem import (dynamics_sign, momentum_residual,
                      pointing_residuals, torque_residual)


def shift_function(nx: int, nu: int, nz: int, ng: int) -> ca.Function:
    """``shift(x, z_prev, lam_x_prev, lam_g_prev) -> (z0, lam_x0, lam_g0)``.

    The previous plan (layout ``x_0, u_0, …, x_N``) moved one interval
    ahead, its last interval repeated and its first state replaced by the
    measured one ``x`` (nx,).
    """
    x = ca.MX.sym("x", nx)
    z_prev = ca.MX.sym("z_prev", nz)
    lam_x_prev = ca.MX.sym("lam_x_prev", nz)
    lam_g_prev = ca.MX.sym("lam_g_prev", ng)
    blk = nx + nu
    z_sh = ca.vertcat(x, z_prev[blk + nx:], z_prev[-(nu + nx):])
    lx_sh = ca.vertcat(lam_x_prev[blk:], lam_x_prev[-(nu + nx):])
    lg_sh = ca.vertcat(lam_g_prev[:nx], lam_g_prev[2 * nx:],
                       lam_g_prev[-nx:])
    return ca.Function(
        "mpc_shift", [x, z_prev, lam_x_prev, lam_g_prev],
        [z_sh, lx_sh, lg_sh], ["x", "z_prev", "lam_x_prev", "lam_g_prev"],
        ["z0", "lam_x0", "lam_g0"])


def nan_unless_finite(z: ca.MX, *values: ca.MX) -> list[ca.MX]:
    """``values``, or NaN each when ``z`` holds a NaN or an infinity.

    A plan's figures (violations, defect, certificate) are maxima, and
    ``fmax``/``mmax`` skip NaN: without this a NaN plan would report a
    violation of 0 (a check ``violation <= tol`` must then fail, also in
    generated C, where nothing raises).
    """
    # one sum: a NaN or an infinity in z makes it NaN or infinite
    finite = ca.fabs(ca.sum1(z)) < np.inf
    return [ca.if_else(finite, v, np.nan) for v in values]


def bound_violation(z: ca.MX, lb: np.ndarray, ub: np.ndarray,
                    scale: np.ndarray, idx: np.ndarray | None = None
                    ) -> ca.MX:
    """``max(0, (lb − z)/scale, (z − ub)/scale)`` over ``idx`` (default
    all) [1]: the largest violation of the finite bounds, each scaled.

    Components with no finite bound are left out, and the final 0 stands
    for the ``max(·, 0)`` of each term (fewer operations in C). NaN in z
    is skipped by the maximum: `nan_unless_finite` makes it NaN.
    """
    idx = np.arange(len(lb)) if idx is None else np.asarray(idx)
    lo = idx[np.isfinite(lb[idx])]
    hi = idx[np.isfinite(ub[idx])]
    terms: list[Any] = [ca.DM(0.0)]
    if len(lo):
        terms.append((ca.DM(lb[lo]) - z[lo]) * ca.DM(1.0 / scale[lo]))
    if len(hi):
        terms.append((z[hi] - ca.DM(ub[hi])) * ca.DM(1.0 / scale[hi]))
    return ca.mmax(ca.vertcat(*terms))


def residual_function(mpc: Any) -> ca.Function:
    """``mpc_residuals(z, p) -> (cost, g)``: the plan's cost and dynamics
    rows (`AttitudeMPC`'s objective and constraints, ``p = (x, q_f, τ)``).

    One stage's RK4 defect and least-squares terms, ``map``-ped over the
    horizon: a loop in generated C (the check runs in every step).
    """
    model, wh, w, N = mpc.model, mpc.wheels, mpc.weights, mpc.horizon
    nx, nu, nw = model.nx, model.nu, wh.n_wheels
    m_max = np.asarray(wh.m_max, dtype=float)
    h_max = np.asarray(wh.h_max, dtype=float)
    prop = mpc._propellant_weights()
    x, x1 = ca.SX.sym("x", nx), ca.SX.sym("x1", nx)
    u, qf, tau = ca.SX.sym("u", nu), ca.SX.sym("qf", 4), ca.SX.sym("tau", 3)
    c = ca.SX.sym("c")
    defect = dynamics_sign(mpc.solver) * (
        x1 - model.rk4_step(1).expand()(x, u, tau, mpc.dt))
    r = ca.vertcat(torque_residual(u, w, m_max),
                   momentum_residual(x, w, h_max),
                   pointing_residuals(x1, qf, w, c))
    cost = ca.sumsqr(r)
    if prop.size:
        cost = cost + w.propellant * ca.dot(ca.DM(prop), u[nw:])
    stage = ca.Function("mpc_residual_stage", [x, u, x1, qf, tau, c],
                        [cost, defect])
    z = ca.MX.sym("z", mpc.nz)
    p = ca.MX.sym("p", nx + 7)
    Z = ca.reshape(z[:N * (nx + nu)], nx + nu, N)
    X1 = ca.horzcat(Z[:nx, 1:], z[N * (nx + nu):])
    costs, D = stage.map(N)(Z[:nx, :], Z[nx:, :], X1, p[nx:nx + 4],
                            p[nx + 4:],
                            ca.DM([[1.0] * (N - 1) + [w.terminal]]))
    return ca.Function("mpc_residuals", [z, p],
                       [ca.sum2(costs), ca.vertcat(z[:nx] - p[:nx],
                                                   ca.vec(D))])


def check_function(mpc: Any, p: ca.MX) -> ca.Function:
    """``check(z, p) -> (cost, violation, first_violation, defect)``.

    ``mpc`` is the `AttitudeMPC` (its bounds, their scale, the residuals);
    the violations are scaled by each bound [1] (a keep-out cone's in cos
    units, `ocp.mpc.keepout`), ``first_violation`` over
    the applied command and the state after it; ``defect`` is the largest
    dynamics defect of the plan [state units]. A plan with a NaN or an
    infinity has NaN violations and defect (`nan_unless_finite`).
    """
    nz = mpc.nz
    zs = ca.MX.sym("z", nz)
    cost, gs = mpc._residuals(zs, p)
    first = np.r_[np.arange(nz)[mpc._us[0]], np.arange(nz)[mpc._xs[1]]]
    viol = bound_violation(zs, mpc.lbz, mpc.ubz, mpc._bound_scale)
    viol_first = bound_violation(zs, mpc.lbz, mpc.ubz, mpc._bound_scale,
                                 first)
    defect = ca.mmax(ca.fabs(gs))
    if mpc.keep_out:
        cones = cone_function(mpc.keep_out, mpc.model.nx)
        viol = ca.fmax(viol, plan_cone_violation(
            cones, ca.horzcat(*[zs[s] for s in mpc._xs[1:]])))
        viol_first = ca.fmax(viol_first, plan_cone_violation(
            cones, zs[mpc._xs[1]]))
    viol, viol_first, defect = nan_unless_finite(zs, viol, viol_first,
                                                 defect)
    return ca.Function(
        "mpc_check", [zs, p], [cost, viol, viol_first, defect],
        ["z", "p"], ["cost", "violation", "first_violation", "defect"])


def plan_bounds(mpc: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(lbz, ubz, scale)`` of an `AttitudeMPC`'s decision vector.

    Torques within ±m_max (duties in [0, 1]), wheel momenta within
    ±h_max, body rates within ±rate_max when set; x_0 free (its
    equality row fixes it); ``scale`` of each bound, for the violations.
    """
    model, N, wh = mpc.model, mpc.horizon, mpc.wheels
    xs, us = mpc._xs, mpc._us
    inf = np.inf
    h_max = np.asarray(wh.h_max, dtype=float)
    m_max = np.asarray(wh.m_max, dtype=float)
    u_lo, u_hi = model.control_bounds()
    wmax = inf if mpc.rate_max is None else mpc.rate_max
    x_hi = np.r_[np.full(4, inf), np.full(3, wmax), h_max]
    ub = np.empty(mpc._nz)
    lb = np.empty(mpc._nz)
    scale = np.ones(mpc._nz)   # of each bound, for the violation
    n_thr = len(mpc._propellant_weights())
    for k in range(N + 1):
        ub[xs[k]], lb[xs[k]] = x_hi, -x_hi
        scale[xs[k]] = np.r_[np.ones(4), np.full(3, 1.0 if wmax == inf
                                                 else wmax), h_max]
        if k < N:
            ub[us[k]], lb[us[k]] = u_hi, u_lo
            scale[us[k]] = np.r_[m_max, np.ones(n_thr)]
    ub[xs[0]] = inf  # x_0 is fixed by its equality row
    lb[xs[0]] = -inf
    return lb, ub, scale
