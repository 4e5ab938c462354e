"""The MPC's Gauss–Newton SQP on the condensed QP (controls only).

`AttitudeMPC` with ``solver="condensed"`` solves the same optimal-control
problem as ``"sqpmethod"`` (same cost, bounds, RK4 multiple shooting), but
each SQP iteration eliminates the state deviations before the QP:

.. math::
    δx_0 = 0,\\quad δx_{k+1} = A_k δx_k + B_k δu_k + d_k

(:math:`A_k, B_k` the RK4 Jacobians at the plan, :math:`d_k` its defects),
so the QP has the N·n_u control deviations only. Its Hessian is never
formed: a Riccati recursion (`ocp.mpc.riccati`; :math:`Q_k = 2 C_k^T C_k
+ ρI`, :math:`C_k` the Jacobian of the stage's least-squares residuals,
ρ `AttitudeMPC.regularization`, R the torque weight plus ρ) writes it as
``WᵀW`` with W block lower triangular, and the QP is solved in
``y = W δu``, where its Hessian is the identity. DAQP, an exact dual
active-set method (qrqp where the casadi wheel ships no DAQP library),
then factors nothing: the bounds on δu are the rows of ``W⁻¹``, and the
momentum rows (and, with a rate bound, the rate rows) come from the same
closed-loop sweep, as lower block-triangular rows in y. With the
Hessian I the unconstrained optimum is −W⁻ᵀg: formed in O(N) by the
closed loop's adjoint and checked by its rollout
(`ocp.mpc.condensed_sweeps`, `ocp.mpc.riccati.closed_loop`), it is the
answer whenever it
keeps every bound and row, and then W⁻¹ is not formed and no conic
runs. Otherwise the QP is solved with the bounds alone first when the
last plan had no row active, and with the rows when its point breaks
one (`ocp.mpc.condensed_qp`).
One SQP iteration takes a full step; ``rti=True`` makes one per sample,
otherwise the iterations repeat until the step ``max |δu / m_max|`` is below
``step_tol`` (default `STEP_TOL`; at most ``max_iter``). Gauss–Newton
converges linearly: through a saturated slew a step shrinks by about 0.8
per iteration (50 iterations to 1e-6 on the benchmark's slew). Anderson
acceleration (`ocp.mpc.acceleration`, memory `ANDERSON_MEMORY`) mixes
the last iterates and takes that to 10; the plan returned is always a QP
step's, within about step_tol · m_max of the optimum.

The multipliers ``lam_x`` of the returned plan are the QP's (bounds on u,
momentum and rate rows, at their places in z); ``lam_g`` is zero (the
dynamics are eliminated). Their signs, shifted, start the next QP's
active set in generated C (`ocp.codegen.patch_daqp_warm_start`).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_scalar, check_positive
from .acceleration import anderson_function
from .condensed_qp import (QP_ITER_LIMIT, ROW_TOL, RowLayout, capped_residual,
                           kkt_residual, routed_qp)
from .plan import nan_unless_finite
from .problem import QP_KKT_TOL, momentum_residual, pointing_residuals
from .condensed_sweeps import linearise, sweep_kernels
from .riccati import closed_loop, factor_rows, row_adjoint


#: Default step ``max |δu / m_max|`` [1] at which the condensed SQP stops.
STEP_TOL = 1e-6

#: Default memory of the Anderson acceleration (`ocp.mpc.acceleration`).
ANDERSON_MEMORY = 3


def condensed_qp_plugin() -> str:
    """Return the condensed QP's conic: daqp where the casadi wheel has it."""
    try:
        return "daqp" if ca.has_conic("daqp") else "qrqp"
    except RuntimeError:
        return "qrqp"


def _kernels(mpc: Any) -> dict[str, ca.Function]:
    """Small SX Functions the condensing calls (straight-line C)."""
    model, w, dt = mpc.model, mpc.weights, mpc.dt
    nx, nu = model.nx, model.nu
    nw = mpc.wheels.n_wheels
    h_max = np.asarray(mpc.wheels.h_max, dtype=float)
    x = ca.SX.sym("x", nx)
    u = ca.SX.sym("u", nu)
    tau = ca.SX.sym("tau", 3)
    F = model.rk4_step(1)(x, u, tau, dt)
    A = ca.jacobian(F, x)
    B = ca.jacobian(F, u)
    # the ω rows of A do not depend on q, its momentum rows are (0 0 I):
    # the momentum rows of the sensitivities are then exact constants
    # and the ω rows follow from the (ω, H) rows alone
    dense = ca.Function("chk", [x, u, tau], [ca.densify(A)])
    An = np.array(dense(np.r_[0.5, 0.5, 0.5, 0.5, 0.01 * np.arange(1, nx - 3)],
                        0.01 * np.ones(nu), 1e-3 * np.ones(3)))
    if np.any(An[4:7, :4] != 0) or np.any(
            An[7:, :] != np.c_[np.zeros((nw, 7)), np.eye(nw)]):
        raise InvalidValueError(
            "solver='condensed' needs the wheel model (rigid_spacecraft "
            "with wheels): ω independent of q, Ḣ_w = s m")
    # cse: the Jacobians share RK4's stages (3,897 -> 3,603 operations)
    lin = ca.Function("cond_lin", [x, u, tau], [F, A, B],
                      ["x", "u", "tau"], ["F", "A", "B"], {"cse": True})
    qf = ca.SX.sym("qf", 4)
    a = ca.SX.sym("a")     # 1: the stage's momentum term, 0: none
    c = ca.SX.sym("c")     # factor of the attitude and rate terms
    r = ca.vertcat(momentum_residual(x, w, h_max, a),
                   pointing_residuals(x, qf, w, c))
    C = ca.jacobian(r, x)
    rho = mpc.regularization
    Q = 2.0 * ca.mtimes(C.T, C) + rho * ca.DM.eye(nx)
    stage = ca.Function("cond_stage", [x, qf, a, c],
                        [Q, 2.0 * ca.mtimes(C.T, r), ca.sumsqr(r)],
                        ["x", "qf", "a", "c"], ["Q", "q", "cost"],
                        {"cse": True})
    return {"lin": lin, "stage": stage}


def _qp_bounds(mpc: Any, at: "_Layout", z: Any, e: list) -> tuple:
    """``(Xe, u_bar, lbu, ubu, lba, uba)`` of the QP in δu at the plan
    ``z``: its states 1…N plus the defects ``e`` carried along
    (stage-major, each pick one strided copy in C), its torques, the
    bounds on δu and those of the rows (momenta, then rates) on their
    deviations."""
    model, N = mpc.model, mpc.horizon
    h_max = np.asarray(mpc.wheels.h_max, dtype=float)
    Xe = z[at.states()] + ca.vertcat(*e[1:])
    h_now = Xe[at.rows(7, model.nx)]
    lba, uba = [-np.tile(h_max, N) - h_now], [np.tile(h_max, N) - h_now]
    if mpc.rate_max is not None:
        w_now = Xe[at.rows(4, 7)]
        lba.append(-mpc.rate_max - w_now)
        uba.append(mpc.rate_max - w_now)
    u_lo, u_hi = model.control_bounds()
    u_bar = z[at.controls()]
    return (Xe, u_bar, np.tile(u_lo, N) - u_bar, np.tile(u_hi, N) - u_bar,
            ca.vertcat(*lba), ca.vertcat(*uba))


def _iteration(mpc: Any, plugin: str, **qp_tols) -> ca.Function:
    """``cond_iter(z, lam_x, p) -> (z_new, lam_x, step, qp_kkt)``: one SQP
    step and its QP's optimality certificate (`condensed_qp.kkt_residual`).
    With ``plugin="pqp"`` a fifth output ``qp_capped``: 1 when the QP
    stopped at its iteration limit (``qp_tols``' ``max_iter``), and then
    ``qp_kkt`` is the capped point's certificate
    (`condensed_qp.capped_residual`).

    ``z`` is a plan whose x_0 is the measured state (p's first n_x
    entries), ``lam_x`` multipliers in z's layout whose signs start the
    QP's active set (generated C with `ocp.codegen.patch_daqp_warm_start`;
    the result does not depend on them); ``step`` is ``max |δu / m_max|``.
    """
    kern = _kernels(mpc)
    model, wh, N = mpc.model, mpc.wheels, mpc.horizon
    nx, nu, nw = model.nx, model.nu, wh.n_wheels
    z = ca.MX.sym("z", mpc.nz)
    lx0 = ca.MX.sym("lam_x", mpc.nz)
    p = ca.MX.sym("p", nx + 7)
    qf, tau = p[nx:nx + 4], p[nx + 4:]
    m_max = np.asarray(wh.m_max, dtype=float)
    sk = sweep_kernels(mpc, kern)
    rk = sk["rk"]
    A, B, e, K, Lit, gy, _ = linearise(mpc, sk, kern, z, qf, tau)
    rate_rows = mpc.rate_max is not None
    at = _Layout(mpc)
    Xe, u_bar, lbu, ubu, lba, uba = _qp_bounds(mpc, at, z, e)
    lam_a0 = ca.vertcat(lx0[at.states(7, nx)], *(
        [lx0[at.states(4, 7)]] if rate_rows else []))
    # the QP in y has the Hessian I: its unconstrained optimum is -W⁻ᵀg,
    # and the answer (zero multipliers) when it keeps every bound and
    # row; W⁻¹ (O(N²) sweeps) and the conic only otherwise
    du0, dx0 = closed_loop(rk, A, B, K, Lit, -gy)
    rows0 = _rows_of(dx0, rate_rows)
    excess = ca.mmax(ca.vertcat(du0 - ubu, lbu - du0, rows0 - uba,
                                lba - rows0))
    inside = excess <= 0
    # the stages' matrices enter one by one (no copies into one matrix
    # on the unconstrained path; `_QP_TAIL` names the rest)
    qp_in = [*A, *B, *K, *Lit, *dx0, gy, du0, rows0, lbu, ubu, lba, uba,
             lx0[at.controls()], lam_a0, excess]
    capping = plugin == "pqp"
    qp = ca.Function.if_else(
        "cond_qp_first", _free_qp(qp_in, N, capping),
        _constrained_qp(rk, qp_in, plugin, (N, nu, nw), rate_rows, qp_tols))
    du, dx, lam_u, lam_a, kkt, *capped = qp(inside, *qp_in)
    # the commanded torques projected onto their box: a float QP point
    # can sit outside it by its rounding, amplified by W⁻¹ (2.6e-6 N·m
    # measured on the M4F); the certificate is the QP point's
    u_lo, u_hi = model.control_bounds()
    u_new = ca.fmin(ca.fmax(u_bar + du, np.tile(u_lo, N)), np.tile(u_hi, N))
    # the new plan: the states z's plus δx_k = e_k + dx_k (the defects
    # carried along plus the closed loop's response to δu: the dynamics
    # are linear in both), the torques u_new; the multipliers at theirs
    z_new = ca.MX(z)
    z_new[at.states()] = Xe + ca.vec(dx)
    z_new[at.controls()] = u_new
    lam_new = ca.MX(ca.DM.zeros(mpc.nz))
    lam_new[at.states(7, nx)] = lam_a[:N * nw]
    if rate_rows:
        lam_new[at.states(4, 7)] = lam_a[N * nw:]
    lam_new[at.controls()] = lam_u
    step = ca.mmax(ca.fabs(du) / ca.DM(np.tile(np.r_[m_max], N)))
    return ca.Function("cond_iter", [z, lx0, p],
                       [z_new, lam_new, step, kkt, *capped],
                       ["z", "lam_x0", "p"],
                       ["z_new", "lam_x", "step", "qp_kkt"]
                       + ["qp_capped"] * len(capped))


class _Layout:
    """Indices into a plan z (layout x_0, u_0, …, x_N) of its stages' parts,
    stage-major: strided picks, one loop each in generated C."""

    def __init__(self, mpc: Any) -> None:
        self.xs, self.us, self.nx = mpc._xs, mpc._us, mpc.model.nx

    def states(self, lo: int = 0, hi: int | None = None) -> list[int]:
        """Components lo…hi−1 of the states x_1…x_N."""
        hi = self.nx if hi is None else hi
        return [s.start + i for s in self.xs[1:] for i in range(lo, hi)]

    def rows(self, lo: int, hi: int) -> list[int]:
        """Components lo…hi−1 of each state in a stage-major vector of
        the states x_1…x_N (as `states` picks them)."""
        n = len(self.xs) - 1
        return [k * self.nx + i for k in range(n) for i in range(lo, hi)]

    def controls(self) -> list[int]:
        """The controls u_0…u_{N−1}."""
        return [i for s in self.us for i in range(s.start, s.stop)]


#: The QP branches' inputs after the 5N stage inputs (A, B, K, Lit, δx₀
#: of each stage): W⁻ᵀg, the unconstrained point's δu and rows, the
#: bounds, the warm start's multipliers, the unconstrained point's excess.
_QP_TAIL = ("gy", "du0", "rows0", "lbu", "ubu", "lba", "uba", "lam_u0",
            "lam_a0", "excess")


def _qp_symbols(qp_in: list, sym: Any, N: int) -> tuple[list, list, dict]:
    """``(all, stages, tail)``: symbols of the branches' inputs; stages
    ``[A, B, K, Lit, dx0]`` as lists of N, the tail by `_QP_TAIL` name."""
    i = [sym.sym(f"i{k}", v.sparsity()) for k, v in enumerate(qp_in)]
    stages = [i[j * N:(j + 1) * N] for j in range(5)]
    return i, stages, dict(zip(_QP_TAIL, i[5 * N:]))


def _free_qp(qp_in: list, N: int, capping: bool = False) -> ca.Function:
    """``cond_qp_free(qp_in…) -> (δu, δx, λ_u, λ_a, kkt)``: the unconstrained
    optimum, its multipliers zero and its KKT residual: stationarity and
    complementarity hold exactly, so the residual is the bounds' largest
    excess (the last input), 0 where this branch runs. SX, so that it
    reads the few inputs it needs (an MX Function reserves a slot in the
    work vector for every input). ``capping``: a sixth output, 0 (not
    capped)."""
    i, stages, t = _qp_symbols(qp_in, ca.SX, N)
    return ca.Function("cond_qp_free", i,
                       [t["du0"], ca.horzcat(*stages[4]),
                        ca.SX.zeros(t["du0"].numel()),
                        ca.SX.zeros(t["rows0"].numel()),
                        ca.fmax(t["excess"], 0.0)]
                       + [ca.SX(0)] * capping)


def _constrained_qp(rk: dict, qp_in: list, plugin: str, dims: tuple,
                    rate_rows: bool, qp_tols: dict) -> ca.Function:
    """``cond_qp_full(qp_in…) -> (δu, δx, λ_u, λ_a, kkt)``: W⁻¹ and the rows
    from the factors (`riccati.factor_rows`), the routed conic, then δu,
    the rows and the certificate (`condensed_qp.kkt_residual`) along the
    closed loop and its adjoint, in O(N)."""
    N, nu, nw = dims
    i, (A, B, K, Lit, _), t = _qp_symbols(qp_in, ca.MX, N)
    gy = t["gy"]
    bounds = [t[n] for n in ("lbu", "ubu", "lba", "uba")]
    winv, G = factor_rows(rk, A, B, K, Lit, rate_rows)
    y, lam_u, lam_a, lam, *flags = routed_qp(
        plugin, N, nu, nw, winv.sparsity(), G.sparsity(), **qp_tols)(
        gy, winv, G, *bounds, t["lam_u0"], t["lam_a0"])
    du, dx = closed_loop(rk, A, B, K, Lit, y)
    a = _rows_of(dx, rate_rows)
    dual = row_adjoint(rk, A, B, K, Lit, lam)
    kkt = kkt_residual(y, gy, dual, du, a, lam_u, lam_a, *bounds)
    capped_out = []
    if flags:
        # a capped point is certified as a feasible descent, not optimal;
        # no feasible point found: the certificate fails outright
        capped, infeasible, moved = flags
        kkt = ca.if_else(capped > 0,
                         capped_residual(y, gy, du, a, *bounds,
                                         moved=moved), kkt)
        kkt = ca.if_else(infeasible > 0, ca.inf, kkt)
        capped_out = [capped]
    return ca.Function("cond_qp_full", i,
                       [du, ca.horzcat(*dx), lam_u, lam_a, kkt, *capped_out])


def _rows_of(dx: list, rate_rows: bool) -> ca.MX:
    """The momentum (then rate) rows' values: of δx_1…δx_N."""
    return ca.vertcat(*[v[7:] for v in dx],
                      *([v[4:7] for v in dx] if rate_rows else []))


def qp_factor_function(mpc: Any) -> ca.Function:
    """``cond_factor(z, p) -> (Winv, rows, g, lbu, ubu, lba, uba)``: one
    condensed QP, as the RTI step poses it.

    For checks and studies: at the plan ``z`` (x_0 the measured state;
    the step's is the previous plan shifted) and parameters ``p = (x,
    q_f, τ)``, the QP in δu (N·n_u,) has the Hessian ``H = WᵀW`` (``H⁻¹ =
    W⁻¹W⁻ᵀ``; W⁻¹ is block lower triangular in stages) and
    the gradient ``g``; with δu = W⁻¹y it is the QP in y of the Hessian
    I and the gradient W⁻ᵀg. Its bounds: ``lbu ≤ W⁻¹y ≤ ubu`` (torques,
    N·m) and ``lba ≤ rows @ y ≤ uba``, the deviations of the momenta
    (N·m·s) and then, with a rate bound, of the rates (rad/s) of the
    states 1…N, stage-major. Any `AttitudeMPC` poses it from its
    weights, bounds and horizon, whatever its solver; keep-out cones,
    which only the stage-wise QP holds, are not in it.
    """
    from .controller import AttitudeMPC     # it imports this module

    if not isinstance(mpc, AttitudeMPC):
        raise InvalidValueError(
            f"mpc must be an AttitudeMPC, got {type(mpc).__name__}")
    kern = _kernels(mpc)
    nx = mpc.model.nx
    z = ca.MX.sym("z", mpc.nz)
    p = ca.MX.sym("p", nx + 7)
    sk = sweep_kernels(mpc, kern)
    A, B, e, K, Lit, _, g = linearise(mpc, sk, kern, z, p[nx:nx + 4],
                                      p[nx + 4:])
    winv, G = factor_rows(sk["rk"], A, B, K, Lit, mpc.rate_max is not None)
    N, nu, nw = mpc.horizon, mpc.model.nu, mpc.wheels.n_wheels
    at = RowLayout(N, nu, nw, G.shape[0] // N)
    rows = G[[i for idx in at.parts for i in idx], :]
    _, _, lbu, ubu, lba, uba = _qp_bounds(mpc, _Layout(mpc), z, e)
    return ca.Function("cond_factor", [z, p],
                       [winv, rows, g, lbu, ubu, lba, uba], ["z", "p"],
                       ["Winv", "rows", "g", "lbu", "ubu", "lba", "uba"])


#: Names of the step Functions' inputs and outputs (`AttitudeMPC`'s, plus
#: the SQP iteration count and the last QP's KKT residual).
STEP_NAMES = (["x", "qf", "tau", "z_prev", "lam_x_prev", "lam_g_prev"],
              ["u", "z", "lam_x", "lam_g", "cost", "violation",
               "first_violation", "defect", "iterations", "qp_kkt"])


def check_condensed_options(options: dict) -> None:
    """Refuse ``solver_options`` the condensed SQP does not take."""
    extra = set(options) - {"step_tol", "anderson", "row_tol", "qp_tol",
                            "kkt_tol", "qp_max_iter"}
    if extra:
        raise InvalidValueError(
            "solver='condensed' takes solver_options 'step_tol' and "
            f"'anderson' only (+ row_tol, qp_tol, kkt_tol, qp_max_iter): "
            f"{sorted(extra)}")


def condensed_step_functions(mpc: Any, plugin: str | None = None,
                             step_tol: float = STEP_TOL,
                             anderson: int = ANDERSON_MEMORY,
                             row_tol: float = ROW_TOL,
                             qp_tol: float | None = None,
                             kkt_tol: float = QP_KKT_TOL,
                             qp_max_iter: int | None = None
                             ) -> tuple[ca.Function, ca.Function]:
    """``(rti_function, step_function)`` of the condensed SQP.

    Both have `AttitudeMPC.step_function`'s inputs and outputs, plus the
    outputs ``iterations`` and ``qp_kkt`` (the KKT residual of the last
    QP's point, `condensed_qp.kkt_residual`: its optimality certificate): the RTI Function makes one condensed SQP step
    from the shifted plan; the step Function repeats it until the step is
    below ``step_tol`` (at most ``mpc.fallback_max_iter`` iterations; the
    iterations after convergence are skipped, not evaluated).

    Parameters
    ----------
    mpc : AttitudeMPC
        The controller (model, weights, bounds, horizon, dt).
    plugin : {None, "daqp", "qrqp", "pqp"}
        Conic of the dense QP (None: `condensed_qp_plugin`; "pqp": the
        primal active set in C, `ocp.mpc.primal_qp`).
    step_tol : float
        Step ``max |δu / m_max|`` [1] at which the iterations stop.
    anderson : int
        Memory m of the Anderson acceleration of the iterations
        (`ocp.mpc.acceleration`; 0: plain full steps). The plan returned
        is always a QP step's.
    row_tol, qp_tol : float
        `condensed_qp.routed_qp`'s row test and qrqp tolerance (float
        exports raise them: `ocp.codegen.precision.TOLERANCES`).
    kkt_tol : float
        Certificate [1] above which a step returns its warm start
        (`sqp_step_functions`; default `QP_KKT_TOL`, float exports
        `TOLERANCES`' ``qp_kkt_tol``).
    qp_max_iter : int, optional
        ``"pqp"`` only: the QP's iteration cap (default
        `condensed_qp.QP_ITER_LIMIT`). A QP stopped there returns a point
        that keeps every bound and lowers the QP's cost from the shifted
        plan; the step takes it, certified by
        `condensed_qp.capped_residual` instead of the KKT residual, and
        its output ``qp_capped`` is 1. With ``"pqp"`` both Functions have
        that output (after ``qp_kkt``).
    """
    if mpc.model.thrusters is not None:
        raise InvalidValueError(
            "solver='condensed' handles wheel-only models; with thrusters "
            "use solver='sqpmethod'")
    plugin = plugin or condensed_qp_plugin()
    max_iter = check_qp_max_iter(plugin, qp_max_iter)
    it = _iteration(mpc, plugin, row_tol=row_tol, qp_tol=qp_tol,
                    max_iter=max_iter)
    return sqp_step_functions(mpc, it, "mpc_cond", step_tol, anderson,
                              kkt_tol, safe_tail=plugin == "pqp")


def check_qp_max_iter(plugin: str, qp_max_iter: Any) -> int:
    """The QP's iteration limit: ``qp_max_iter`` (the primal active sets
    pqp and rqp only, a positive int) or `condensed_qp.QP_ITER_LIMIT`."""
    if qp_max_iter is None:
        return QP_ITER_LIMIT
    if plugin not in ("pqp", "rqp"):
        raise InvalidValueError(
            "solver_options 'qp_max_iter' caps qp_solver='pqp' or 'rqp' "
            "only (a "
            f"capped {plugin} point is not feasible), got qp_solver "
            f"{plugin!r}")
    if isinstance(qp_max_iter, bool) or not isinstance(
            qp_max_iter, (int, np.integer)) or qp_max_iter < 1:
        raise InvalidValueError(
            f"qp_max_iter must be a positive int, got {qp_max_iter!r}")
    return int(qp_max_iter)


def momentum_safe_tail(mpc: Any, z: ca.MX) -> ca.MX:
    """The shifted plan ``z`` with its repeated last torque clipped so
    that the last interval keeps the wheel momentum bound.

    The shift repeats the last interval: from ``x_N`` the torque
    ``u_{N-1}`` again, so the new last momentum is ``H_N + dt·s·u_{N-1}``
    (``Ḣ_w = s m``, s the wheels' scale factors, 0 for a failed wheel:
    exact), past ``h_max`` whenever a wheel at its bound was still being
    driven into it. Clipped to ``[(−h_max − H_N)/(dt s), (h_max −
    H_N)/(dt s)]`` (and the torque bounds) it stays within, so the
    shifted plan is a feasible start for a primal QP solver
    (`ocp.mpc.primal_qp`).
    """
    wh = mpc.wheels
    nw = wh.n_wheels
    gain = mpc.dt * np.asarray(wh.scale * wh.active, dtype=float)
    h_max = np.asarray(wh.h_max, dtype=float)
    u_lo, u_hi = mpc.model.control_bounds()
    us, h = mpc._us[-1], mpc._xs[-2].start + 7
    u = z[us.start:us.start + nw]
    clipped = []
    for i in range(nw):
        lo, hi = u_lo[i], u_hi[i]
        if gain[i] > 0:           # a failed wheel's torque bounds are 0
            lo = ca.fmax((-h_max[i] - z[h + i]) / gain[i], lo)
            hi = ca.fmin((h_max[i] - z[h + i]) / gain[i], hi)
        clipped.append(ca.fmin(ca.fmax(u[i], lo), hi))
    out = ca.MX(z)
    out[us.start:us.start + nw] = ca.vertcat(*clipped)
    return out


def sqp_step_functions(mpc: Any, it: ca.Function, prefix: str,
                       step_tol: float, anderson: int,
                       kkt_tol: float = QP_KKT_TOL, safe_tail: bool = False
                       ) -> tuple[ca.Function, ca.Function]:
    """``(rti, step)`` Functions around one SQP iteration ``it``.

    ``it(z, lam_x0, p) -> (z_new, lam_x, step, qp_kkt)`` (`_iteration`,
    or the stage-wise one of `ocp.mpc.stagewise`); the Functions are
    named ``prefix + "_rti"`` and ``prefix + "_step"`` and have
    `STEP_NAMES`' inputs and outputs. A step whose last QP fails its
    certificate (``qp_kkt`` above ``kkt_tol``, or NaN) returns the warm
    start, the last plan shifted, as its plan and command (planned within
    every bound one sample ago), and its ``qp_kkt`` still says it failed:
    generated C cannot raise, and a flight loop must not apply a failed
    QP's point. `AttitudeMPC.step` refuses such a step in Python.
    An ``it`` with a fifth output ``qp_capped`` (the pqp iteration) gives
    both Functions that output too, the last QP's, after ``qp_kkt``.
    ``safe_tail``: the shifted plan's last torque clipped to keep the
    momentum bound (`momentum_safe_tail`).
    """
    step_tol = as_finite_scalar(step_tol, "step_tol")
    check_positive(step_tol, "step_tol")
    kkt_tol = as_finite_scalar(kkt_tol, "kkt_tol")
    check_positive(kkt_tol, "kkt_tol")
    if isinstance(anderson, bool) or not isinstance(
            anderson, (int, np.integer)) or anderson < 0:
        raise InvalidValueError(
            f"anderson must be a non-negative int, got {anderson!r}")
    nx, nz, ng = mpc.model.nx, mpc.nz, mpc.ng
    x = ca.MX.sym("x", nx)
    qf = ca.MX.sym("qf", 4)
    tau = ca.MX.sym("tau", 3)
    z_prev = ca.MX.sym("z_prev", nz)
    lx_prev = ca.MX.sym("lam_x_prev", nz)
    lg_prev = ca.MX.sym("lam_g_prev", ng)
    p = ca.vertcat(x, qf, tau)
    z0, lx0, _ = mpc.shift_function(x, z_prev, lx_prev, lg_prev)
    if safe_tail:
        z0 = momentum_safe_tail(mpc, z0)
    ins = [x, qf, tau, z_prev, lx_prev, lg_prev]
    us0 = mpc._us[0]

    capping = it.n_out() == 5
    names = (STEP_NAMES[0], STEP_NAMES[1] + ["qp_capped"] * capping)

    def iterate(z, lx, p):
        # (z, λ, step, certificate): with capping, (qp_kkt, qp_capped)
        zn, ln, sn, *kn = it(z, lx, p)
        return zn, ln, sn, ca.vertcat(*kn)

    def outputs(z, lx, n, kkt_c):
        kkt = kkt_c[0]
        ok = kkt <= kkt_tol                 # False for a NaN certificate
        z, lx = ca.if_else(ok, z, z0), ca.if_else(ok, lx, lx0)
        # a NaN plan's certificate is NaN (its check's figures are too)
        return [z[us0], z, lx, ca.MX.zeros(ng),
                *mpc.check_function(z, p), n, *nan_unless_finite(z, kkt),
                *([kkt_c[1]] if capping else [])]

    z1, lx1, _, kkt1 = iterate(z0, lx0, p)
    rti = ca.Function(prefix + "_rti", ins, outputs(z1, lx1, 1.0, kkt1),
                      *names)
    # the iterations nest: iteration k's Switch runs iteration k + 1 only
    # when its step was not small, so a converged plan returns through the
    # iterations made, not through max_iter skipped ones
    zs, ls = ca.MX.sym("z", nz), ca.MX.sym("lam_x", nz)
    n, ps = ca.MX.sym("n"), ca.MX.sym("p", nx + 7)
    kk = ca.MX.sym("kkt", 1 + capping)
    m = int(anderson)
    mix = anderson_function(nz, m) if m else None
    hist = [ca.MX.sym("G_hist", nz, m + 1), ca.MX.sym("F_hist", nz, m + 1),
            ca.MX.sym("valid", m + 1)] if m else []
    args = [zs, ls, n, kk, ps, *hist]
    sx = [ca.SX.sym(a.name(), a.sparsity()) for a in args]
    done = ca.Function("cond_done", sx, sx[:4])  # SX: reads z, λ, n, kkt
    inner = None
    for k in range(mpc.fallback_max_iter - 1, -1, -1):
        zn, ln, sn, kn = iterate(zs, ls, ps)
        if inner is None:
            out = [zn, ln, n + 1, kn]
        else:
            nxt, hist_n = zn, []
            if mix is not None:          # m > 0
                za, *hist_n = mix(zn, zs, *hist)
                # a converged iteration returns its QP step, not a mix
                nxt = ca.if_else(sn <= step_tol, zn, za)
            out = inner(sn <= step_tol, nxt, ln, n + 1, kn, ps, *hist_n)
        # casadi's stubs: a call with several outputs returns a tuple
        more = ca.Function(f"cond_more_{k}", args,
                           out)  # type: ignore[arg-type]
        inner = ca.Function.if_else(f"cond_iter_{k}", done, more)
    assert inner is not None      # fallback_max_iter >= 1
    hist0 = [ca.MX.zeros(nz, m + 1), ca.MX.zeros(nz, m + 1),
             ca.MX.zeros(m + 1)] if m else []
    z, lx, count, kkt = inner(0, z0, lx0, 0.0, ca.DM.zeros(1 + capping), p,
                              *hist0)
    full = ca.Function(prefix + "_step", ins, outputs(z, lx, count, kkt),
                       *names)
    return rti, full
