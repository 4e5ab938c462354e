"""The duty-cycle QP as CasADi Functions of the parameters (fast path, C)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from adcs_common.buffers import BoundCall
from adcs_common.codegen import CompilerNotFound, find_compiler

from .problem import INF, DutyCycleQP

#: Options set per plugin (printing off, no exception on failure: the
#: allocator checks residuals itself, since qrqp can report success on a
#: violated point, SOLVER_NOTES).
DEFAULTS: dict[str, dict[str, Any]] = {
    "qrqp": {"print_iter": False, "print_header": False,
             "print_info": False, "error_on_fail": False},

    "osqp": {"osqp": {"eps_abs": 1e-6, "eps_rel": 1e-6, "polishing": True,
                      "max_iter": 20000, "verbose": False},
             "error_on_fail": False},
    # DAQP's default primal_tol (1e-6) leaves equality rows off by up to
    # ~3e-5 in duty on this QP; with 1e-10 the plugin is exact to the
    # reference (max error 6e-12 on 300 random cycles, tests check it)
    "daqp": {"daqp": {"primal_tol": 1e-10}, "error_on_fail": False},
}
#: Conic plugin of the allocator's fast path (`duty_function`).
FAST_PLUGIN = "daqp"


def _has_compiler() -> bool:
    try:
        find_compiler()
    except CompilerNotFound:
        return False
    return True


def infinite_bounds(v: np.ndarray) -> np.ndarray:
    """Replace the finite stand-in ``±INF`` of absent bounds by ``±inf``."""
    out = v.astype(float).copy()
    out[out >= INF / 2] = np.inf
    out[out <= -INF / 2] = -np.inf
    return out


def conic_function(qp: DutyCycleQP, plugin: str,
                   options: dict | None = None) -> ca.Function:
    """``duty_qp(theta[9], kmax[n]) -> (x[n+1], violation)``, casadi.

    ``q, l, u`` are formed from ``theta`` inside the Function, so one call
    (or one `casadi.Function.buffer` trigger, or generated C) solves a
    cycle; ``kmax`` are the variables' upper bounds (ones at the build
    pressure); ``violation`` is the largest constraint violation of ``x``.
    """
    opts = {**DEFAULTS.get(plugin, {"error_on_fail": False}),
            **(options or {})}
    H = ca.DM(qp.P)
    Asp = ca.DM(qp.A)
    solver = ca.conic("duty_conic", plugin,
                      {"h": H.sparsity(), "a": Asp.sparsity()}, opts)
    theta = ca.MX.sym("theta", qp.Lm.shape[1])
    q = ca.DM(qp.q0) + ca.DM(qp.Q) @ theta
    l = ca.DM(infinite_bounds(qp.l0)) + ca.DM(qp.Lm) @ theta
    u = ca.DM(infinite_bounds(qp.u0)) + ca.DM(qp.Um) @ theta
    n = qp.nx - 1
    kmax = ca.MX.sym("kmax", n)
    lbx = ca.DM(qp.lb)
    ubx = ca.vertcat(kmax, ca.DM(qp.ub[n]))
    sol = solver(h=H, g=q, a=Asp, lba=l, uba=u, lbx=lbx, ubx=ubx)
    x = sol["x"]
    Ax = Asp @ x
    viol = ca.mmax(ca.vertcat(ca.fmax(l - Ax, 0), ca.fmax(Ax - u, 0),
                              ca.fmax(lbx - x, 0), ca.fmax(x - ubx, 0)))
    return ca.Function("duty_qp", [theta, kmax], [x, viol],
                       ["theta", "kmax"], ["x", "violation"])


def _equality_reduction(qp: DutyCycleQP):
    """Null-space elimination of the QP's equality rows.

    The equality rows ``E k = e(theta)`` (thrust, and the torques with
    ``tracking="hard"``; the slack is not in them) are solved exactly by
    ``k = kp(theta) + Z z`` with ``kp = E^+ e(theta)`` and ``Z`` an
    orthonormal basis of the null space of ``E`` (n, n - n_eq). Returns
    ``(Ep, Z)``: ``kp = Ep @ (l0_eq + Lm_eq @ theta)``.
    """
    n = qp.nx - 1
    E = qp.A[:qp.n_eq, :n]
    if np.any(qp.A[:qp.n_eq, n] != 0.0):
        raise ValueError("the slack appears in an equality row")
    _, sv, Vt = np.linalg.svd(E)
    rank = int(np.sum(sv > sv[0] * 1e-12))
    if rank < qp.n_eq:
        raise ValueError("dependent equality rows")
    return np.linalg.pinv(E), Vt[rank:].T


def slack_decouples(qp: DutyCycleQP, Z: np.ndarray) -> bool:
    """Tell whether the momentum rows see the duties only through ``E k``.

    Then (hard tracking) every feasible k gives them the same value and
    the slack's optimum is the worst excess over the bound (`_slack`).
    Needs each momentum row one-sided, with the slack in it.
    """
    n = qp.nx - 1
    rows = qp.A[qp.n_eq:]
    one_sided = np.logical_xor(qp.upper_rows[qp.n_eq:],
                               qp.lower_rows[qp.n_eq:])
    scale = max(float(np.abs(rows[:, :n]).max(initial=0.0)), 1e-300)
    return bool(Z.shape[1] > 0 and np.all(one_sided)
                and np.all(rows[:, n] != 0.0)
                and np.abs(rows[:, :n] @ Z).max(initial=0.0)
                <= 1e-12 * scale)


def _slack(qp: DutyCycleQP, kp, l_in, u_in):
    """Least slack [1] meeting every momentum row at duties ``kp`` (SX).

    Row j reads ``l_j <= a_j k + σ_j s <= u_j`` with one side finite; the
    cost ``w s + s²/2`` rises with s, so the optimum is the largest
    excess, at least 0, at most the slack's upper bound.
    """
    n = qp.nx - 1
    rows = qp.A[qp.n_eq:]
    value = ca.DM(rows[:, :n]) @ kp
    need: list[ca.SX | ca.DM | float] = [ca.DM(0.0)]
    for j, sigma in enumerate(rows[:, n]):
        if qp.upper_rows[qp.n_eq + j]:
            need.append((value[j] - u_in[j]) / -sigma if sigma < 0
                        else -ca.inf)
        else:
            need.append((l_in[j] - value[j]) / sigma if sigma > 0
                        else -ca.inf)
    return ca.fmin(ca.mmax(ca.vertcat(*need)), float(qp.ub[n]))


def _certificate(qp: DutyCycleQP, Tm: np.ndarray, Ar: np.ndarray,
                 Hr: np.ndarray, lby: np.ndarray, uby: np.ndarray,
                 viol_tol: float, kkt_tol: float, jit: dict) -> ca.Function:
    """``duty_fast_post``: duties, slack and the check of a conic point.

    The reduced QP's KKT conditions certify the conic's point y (convex
    QP: primal feasibility, stationarity and complementarity with
    sign-correct multipliers make it the optimum); the violation is
    measured on the original QP, equality rows included.
    """
    n = qp.nx - 1
    ny = Tm.shape[1]
    nth = qp.Lm.shape[1]
    Hd, Ad = ca.DM(Hr), ca.DM(Ar)
    th = ca.SX.sym("theta", nth)
    km = ca.SX.sym("kmax", n)
    l = ca.DM(infinite_bounds(qp.l0)) + ca.DM(qp.Lm) @ th
    u = ca.DM(infinite_bounds(qp.u0)) + ca.DM(qp.Um) @ th
    y = ca.SX.sym("y", ny)
    la = ca.SX.sym("lam_a", Ar.shape[0])
    ly = ca.SX.sym("lam_x", ny)
    xps = ca.SX.sym("xp", qp.nx)
    gs = ca.SX.sym("g", ny)
    ls = ca.SX.sym("lr", Ar.shape[0])
    us = ca.SX.sym("ur", Ar.shape[0])
    x = xps + ca.DM(Tm) @ y
    Ay = Ad @ y
    # a multiplier > 0 marks the upper bound active, < 0 the lower one:
    # that bound must hold with equality (an infinite one, i.e. a wrong
    # sign on a one-sided row, fails)
    b_a = ca.if_else(la > 0, us, ls, False)
    b_y = ca.if_else(ly > 0, ca.DM(uby), ca.DM(lby), False)
    comp = ca.mmax(ca.vertcat(
        ca.if_else(la != 0, ca.fabs(Ay - b_a), 0, False),
        ca.if_else(ly != 0, ca.fabs(y - b_y), 0, False)))
    grad = Hd @ y + gs
    stat = ca.mmax(ca.fabs(grad + Ad.T @ la + ly)) / (
        1.0 + ca.mmax(ca.fabs(grad)) + ca.mmax(ca.fabs(la))
        + ca.mmax(ca.fabs(ly)))
    # violation measured on the original QP, equality rows included
    A = ca.DM(qp.A)
    Ax = A @ x
    ubx = ca.vertcat(km, ca.DM(qp.ub[n]))
    viol = ca.mmax(ca.vertcat(ca.fmax(l - Ax, 0), ca.fmax(Ax - u, 0),
                              ca.fmax(ca.DM(qp.lb) - x, 0),
                              ca.fmax(x - ubx, 0)))
    score = ca.fmax(viol / viol_tol, ca.fmax(comp, stat) / kkt_tol)
    total = ca.sum1(th) + ca.sum1(y) + ca.sum1(la) + ca.sum1(ly) + score
    check = ca.if_else(ca.fabs(total) < np.inf, score, np.inf)
    duty = ca.fmin(ca.fmax(x[:n], 0), km) / km
    return ca.Function("duty_fast_post", [y, la, ly, xps, gs, ls, us, th,
                                          km], [duty, x[n], check], jit)


def duty_function(qp: DutyCycleQP, plugin: str = FAST_PLUGIN,
                  options: dict | None = None, viol_tol: float = 1e-6,
                  kkt_tol: float = 1e-9, jit: bool = True) -> ca.Function:
    """``duty_fast(theta[9], kmax[n]) -> (duty[n], slack, check)``.

    The whole allocation of one cycle as one Function (one
    `casadi.Function.buffer` trigger). The equality rows are eliminated
    first (`_equality_reduction`: ``k = kp(theta) + Z z``), so the conic
    sees an inequality-only QP in ``(z, slack)``: DAQP takes equality rows
    as two-sided inequalities that are degenerate with the momentum rows
    and then stops ~1.5e-6 off the optimum on most hard-tracking cycles;
    the reduced problem has no such rows. Outputs: the duties
    ``clip(k, 0, kmax) / kmax`` (in [0, 1] at any pressure), the slack and
    ``check``, the larger of the original QP's constraint violation over
    ``viol_tol`` and the reduced QP's KKT residuals (complementarity and
    stationarity relative to the gradient and multipliers) over
    ``kkt_tol``; ``inf`` when ``theta`` or the point holds a NaN or an
    infinity (C's ``fmax`` drops NaNs, so the scores alone would hide
    them). Accept the duties only when ``check <= 1``: the reduced QP is
    convex, so a point passing its KKT test is its optimum, and the
    reduction is exact.
    """
    opts = {**DEFAULTS.get(plugin, {"error_on_fail": False}),
            **(options or {})}
    # the arithmetic around the conic compiled to C when a compiler is
    # there (CasADi's SX virtual machine costs ~3 µs more per call)
    jit_opts: dict[str, Any] = (
        {"jit": True, "compiler": "shell",
         "jit_options": {"flags": ["-O2"], "verbose": False}}
        if jit and _has_compiler() else {})
    n = qp.nx - 1
    ne = qp.n_eq
    nth = qp.Lm.shape[1]
    Ep, Z = _equality_reduction(qp)
    nz = Z.shape[1]
    A_in = qp.A[ne:]
    # hard tracking: the momentum rows see only E k (fixed), so the slack
    # is theirs alone, s = max(0, worst excess), and the conic solves for
    # z only (fewer rows, about half the time)
    apart = slack_decouples(qp, Z)
    ny = nz if apart else nz + 1
    # x = xp(theta) + Tm @ y, y = z (apart) or (z, slack)
    Tm = np.zeros((qp.nx, ny))
    Tm[:n, :nz] = Z
    if not apart:
        Tm[n, nz] = 1.0
    Hr = Tm.T @ qp.P @ Tm
    # Z's columns are orthonormal: ZᵀZ's off-diagonal rounding (~1e-20)
    # would give the conic a dense Hessian (DAQP then factors it)
    Hr[np.abs(Hr) <= 1e-12 * np.abs(Hr).max()] = 0.0
    Ar = Tm[:n] if apart else np.vstack([A_in @ Tm, Tm[:n]])
    Hd, Ad = ca.sparsify(ca.DM(Hr)), ca.DM(Ar)
    solver = ca.conic("duty_fast_conic", plugin,
                      {"h": Hd.sparsity(), "a": Ad.sparsity()}, opts)
    lby = np.full(ny, -np.inf)
    uby = np.full(ny, np.inf)
    if not apart:
        lby[nz] = 0.0
        uby[nz] = qp.ub[n]

    th = ca.SX.sym("theta", nth)
    km = ca.SX.sym("kmax", n)
    # a NaN or infinity in theta: solve at theta = 0 and report check=inf
    # (the conic rejects NaN bounds with an exception)
    ok_in = ca.fabs(ca.sum1(th)) < np.inf
    th0 = ca.if_else(ok_in, th, ca.DM.zeros(nth))
    q = ca.DM(qp.q0) + ca.DM(qp.Q) @ th0
    l = ca.DM(infinite_bounds(qp.l0)) + ca.DM(qp.Lm) @ th0
    u = ca.DM(infinite_bounds(qp.u0)) + ca.DM(qp.Um) @ th0
    kp = ca.DM(Ep) @ l[:ne]
    xp = ca.vertcat(kp, _slack(qp, kp, l[ne:], u[ne:]) if apart else 0)
    gr = ca.DM(Tm.T) @ (ca.DM(qp.P) @ xp + q)
    if apart:
        lr, ur = -kp, km - kp
    else:
        Axp = ca.DM(A_in) @ xp
        lr = ca.vertcat(l[ne:] - Axp, -kp)
        ur = ca.vertcat(u[ne:] - Axp, km - kp)
    pre = ca.Function("duty_fast_pre", [th, km], [gr, lr, ur, xp], jit_opts)

    post = _certificate(qp, Tm, Ar, Hr, lby, uby, viol_tol, kkt_tol, jit_opts)
    theta = ca.MX.sym("theta", nth)
    kmax = ca.MX.sym("kmax", n)
    gm, lm, um, xpm = pre(theta, kmax)
    sol = solver(h=Hd, g=gm, a=Ad, lba=lm, uba=um, lbx=lby, ubx=uby)
    duty_m, slack_m, check_m = post(sol["x"], sol["lam_a"], sol["lam_x"],
                                    xpm, gm, lm, um, theta, kmax)
    return ca.Function("duty_fast", [theta, kmax],
                       [duty_m, slack_m, check_m],
                       ["theta", "kmax"], ["duty", "slack", "check"])


class FastDuty:
    """`duty_function` bound to numpy work arrays through a buffer.

    Attributes ``theta`` (9,) and ``kmax`` (n,) are the inputs, ``duty``
    (n,), ``slack`` (1,) and ``check`` (1,) the outputs; `trigger`
    evaluates in place (no argument conversion).
    """

    __slots__ = ("function", "theta", "kmax", "duty", "slack", "check",
                 "trigger", "_call")

    def __init__(self, qp: DutyCycleQP, kmax: np.ndarray,
                 plugin: str = FAST_PLUGIN, options: dict | None = None,
                 viol_tol: float = 1e-6, kkt_tol: float = 1e-9) -> None:
        try:
            self.function = duty_function(qp, plugin, options, viol_tol,
                                          kkt_tol)
        except RuntimeError:         # the JIT compilation failed
            self.function = duty_function(qp, plugin, options, viol_tol,
                                          kkt_tol, jit=False)
        n = qp.nx - 1
        self.theta = np.zeros(qp.Lm.shape[1])
        self.kmax = np.array(kmax, dtype=float)
        self.duty = np.zeros(n)
        self.slack = np.zeros(1)
        self.check = np.zeros(1)
        self._call = BoundCall(self.function, (self.theta, self.kmax),
                               (self.duty, self.slack, self.check))
        self.trigger = self._call.trigger
