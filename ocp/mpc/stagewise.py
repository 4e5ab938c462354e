"""The MPC's Gauss–Newton SQP on the stage-wise QP (cost linear in N).

`AttitudeMPC` with ``solver="stagewise"`` solves the same optimal-control
problem as ``"condensed"`` (same cost, bounds, RK4 multiple shooting and
the same Gauss–Newton QP, so the same steps), but it keeps the QP in its
stage-wise form, states and controls both, and solves it with a Riccati
interior point (`ocp.mpc.stagewise_ipm`): work and generated code grow
linearly in the horizon N, where the condensed QP grows as (N·n_u)².
The linearisation, the stage costs and every sweep are CasADi ``map`` /
``mapaccum`` of one stage's kernel, so the generated C loops over the
stages instead of unrolling them.

The condensed QP's exact active-set solve (DAQP) is faster at short
horizons; the stage-wise interior point wins as N grows (docs/benchmarks.md
measures where). Both certify their QP point (``qp_kkt``).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError
from .condensed import (ANDERSON_MEMORY, STEP_TOL, _kernels,
                        sqp_step_functions)
from .keepout import (CONE_FLOOR, CONE_WIDTH, planning_cone_function,
                      qp_stage_functions, stage_defects)
from .problem import QP_KKT_TOL
from .stagewise_boxes import BoxLayout
from .stagewise_ipm import (IPM_MAX_ITER, IPM_TOL, Tree,
                            ipm_solve)
from .stagewise_kernels import stage_kernels


def _nz_kernels(kern: dict, nx: int, nu: int,
                cones: ca.Function | None = None) -> tuple:
    """The linearisation and the stage cost with matrices as nonzeros.

    Without ``cones``: ``sw_lin(x, u, τ) -> (F, A, B)``. With them (the
    keep-out cones' values, `ocp.mpc.keepout`), the cones are states of
    the QP: ``sw_lin(x, u, τ, x_next) -> (d, A, B)`` with the defect d
    and the augmented matrices, and the stage cost padded with zeros.
    """
    x, u, tau = ca.SX.sym("x", nx), ca.SX.sym("u", nu), ca.SX.sym("tau", 3)
    F, A, B = kern["lin"](x, u, tau)
    qf, a, c = ca.SX.sym("qf", 4), ca.SX.sym("a"), ca.SX.sym("c")
    Q, q, _ = kern["stage"](x, qf, a, c)
    lin, stage, sp = qp_stage_functions("sw", [x, u, tau], F, A, B,
                                        [x, qf, a, c], Q, q, cones)
    return (lin, stage, *sp)


def box_layout(mpc: Any) -> BoxLayout:
    """The boxes of the stage-wise QP: torques, momenta (and rates, and
    the keep-out cones' states, `ocp.mpc.keepout`)."""
    model, wh = mpc.model, mpc.wheels
    lo, hi = model.control_bounds()
    nw, nx, nc = wh.n_wheels, model.nx, len(mpc.keep_out)
    bx = list(range(7, 7 + nw))
    wx = 2.0 * np.asarray(wh.h_max, dtype=float)
    if mpc.rate_max is not None:
        bx = [4, 5, 6] + bx
        wx = np.r_[np.full(3, 2.0 * mpc.rate_max), wx]
    bx += list(range(nx, nx + nc))
    wx = np.r_[wx, np.full(nc, CONE_WIDTH)]
    return BoxLayout(nx + nc, model.nu, hi > lo, hi - lo, bx, wx)


def _bound_values(mpc: Any, side: float) -> np.ndarray:
    """The state bound on each component (−1: lower, +1: upper), (n_x,)."""
    x = np.zeros(mpc.model.nx)
    x[7:] = side * np.asarray(mpc.wheels.h_max, dtype=float)
    if mpc.rate_max is not None:
        x[4:7] = side * mpc.rate_max
    return x


def state_box_sides(mpc: Any, X1: Any, cones: ca.Function | None) -> tuple:
    """``(lo, hi)`` of the QP's states from the planned next states X1
    (n_x × C): the bounds minus X1, then each cone's ``(CONE_FLOOR,
    −backoff) − c(X1)`` (`ocp.mpc.keepout`)."""
    C = X1.shape[1]
    lo, hi = (ca.repmat(ca.DM(_bound_values(mpc, s)), 1, C) - X1
              for s in (-1.0, 1.0))
    if cones is None:
        return lo, hi
    c = cones.map(C)(X1)
    return (ca.vertcat(lo, CONE_FLOOR - c),
            ca.vertcat(hi, -mpc.keep_out_backoff - c))


def block_lengths(blocks: Any, horizon: int, solver: str
                  ) -> tuple[int, ...] | None:
    """Check ``move_blocks`` of an `AttitudeMPC`; the block lengths.

    None: no blocking. An int M (1 ≤ M ≤ N): M blocks as even as
    possible, the shorter ones first (the near future keeps the finer
    control). A sequence: the lengths themselves (positive ints summing
    to N).
    """
    if blocks is None:
        return None
    if solver != "stagewise":
        raise InvalidValueError(
            f"move_blocks needs solver='stagewise', got {solver!r}")
    if isinstance(blocks, (int, np.integer)) and not isinstance(blocks,
                                                                bool):
        m = int(blocks)
        if not 1 <= m <= horizon:
            raise InvalidValueError(
                f"move_blocks must be between 1 and the horizon {horizon},"
                f" got {m}")
        return tuple(int(n) for n in sorted(
            len(a) for a in np.array_split(np.arange(horizon), m)))
    try:
        lengths = tuple(blocks)
    except TypeError:
        raise InvalidValueError(
            "move_blocks must be an int or a sequence of block lengths, "
            f"got {blocks!r}") from None
    if not lengths or not all(
            isinstance(n, (int, np.integer)) and not isinstance(n, bool)
            and n >= 1 for n in lengths) or sum(lengths) != horizon:
        raise InvalidValueError(
            "move_blocks must be positive ints summing to the horizon "
            f"{horizon}, got {blocks!r}")
    return tuple(int(n) for n in lengths)


def block_flags(lengths: tuple[int, ...] | None, horizon: int
                ) -> np.ndarray:
    """1 at each block's first stage, 0 where a stage holds (N,)."""
    flags = np.zeros(horizon) if lengths else np.ones(horizon)
    if lengths:
        flags[np.r_[0, np.cumsum(lengths)[:-1]]] = 1.0
    return flags


class StageParts:
    """The stage-wise QP's pieces for one MPC: kernels, boxes, solver."""

    def __init__(self, mpc: Any, tol: float, max_iter: int,
                 ipm: bool = True) -> None:
        model, wh, w = mpc.model, mpc.wheels, mpc.weights
        nx, nu = model.nx, model.nu
        kern = _kernels(mpc)
        self.cones = planning_cone_function(mpc)
        self.lin, self.stage, sp_a, sp_b, sp_q = _nz_kernels(
            kern, nx, nu, self.cones)
        self.patterns = (sp_a, sp_b, sp_q)  # of A, B and Q's nonzeros
        self.nq = nx + len(mpc.keep_out)     # the QP's state
        self.m_max = np.asarray(wh.m_max, dtype=float)
        self.r_diag = 2.0 * w.torque / self.m_max ** 2 + mpc.regularization
        self.lay = box_layout(mpc)
        lo, hi = model.control_bounds()
        self.free = np.asarray(hi > lo)
        blocks = getattr(mpc, "move_blocks", None)
        self.flags = block_flags(blocks, mpc.horizon)
        self.kern = stage_kernels(sp_a, sp_b, sp_q, self.free,
                                  self.lay.bu, self.lay.bx,
                                  blocked=blocks is not None)
        self.ipm = ipm_solve(self.kern, self.lay, Tree(mpc.horizon),
                             self.nq, nu, max_iter, tol,
                             self.flags) if ipm else None


def qp_data(mpc: Any, parts: StageParts, z: ca.MX, p: ca.MX) -> tuple:
    """``(X, U, xN, data, D)``: the plan's stages, its QP's data and the
    dynamics' defects D (n_q × N).

    ``data = (dU0, dX0, A, B, Q, q, g, r, lo, hi)``, `ipm_solve`'s inputs:
    the dynamics-feasible start (zero steps but the fixed controls, the
    defects carried along), the stages' Jacobians and Hessians (as
    nonzeros, one column per stage), gradients and scaled boxes.
    """
    model, w, N = mpc.model, mpc.weights, mpc.horizon
    nx, nu = model.nx, model.nu
    lay = parts.lay
    qf, tau = p[nx:nx + 4], p[nx + 4:]
    n_stage = N * (nx + nu)
    Z = ca.reshape(z[:n_stage], nx + nu, N)
    X, U, xN = Z[:nx, :], Z[nx:, :], z[n_stage:]
    X1 = ca.horzcat(X[:, 1:], xN)
    D, An, Bn = stage_defects(parts.lin.map(N), [X, U, tau], X1,
                              parts.cones)
    a = ca.DM([[1.0] * (N - 1) + [0.0]])
    c = ca.DM([[1.0] * (N - 1) + [w.terminal]])
    Qn, q = parts.stage.map(N)(X1, qf, a, c)
    g = ca.mtimes(_diag(2.0 * w.torque / parts.m_max ** 2), U)
    u_lo, u_hi = (ca.repmat(ca.DM(v), 1, N) for v in model.control_bounds())
    x_lo, x_hi = state_box_sides(mpc, X1, parts.cones)
    lo = lay.values(u_lo - U, x_lo)
    hi = lay.values(u_hi - U, x_hi)
    # the start holds the blocks: each stage takes its block's first
    # control (a product with the constant 0/1 holder matrix)
    first = np.maximum.accumulate(np.where(parts.flags > 0,
                                           np.arange(N), 0))
    hold = ca.DM(ca.Sparsity.triplet(N, N, list(first), list(range(N))),
                 1.0)
    dU0 = (ca.mtimes(_diag((~parts.free).astype(float)), u_lo - U)
           + ca.mtimes(_diag(parts.free.astype(float)),
                       ca.mtimes(U, hold) - U))
    dX0 = parts.kern["roll"].mapaccum("sw_roll_N", N, 1)(
        ca.DM.zeros(parts.nq), An, Bn, dU0, D)
    r = ca.repmat(ca.DM(parts.r_diag), 1, N)
    return X, U, xN, (dU0, dX0, An, Bn, Qn, q, g, r, lo, hi), D


def _diag(v: np.ndarray) -> ca.DM:
    """A constant sparse diagonal matrix."""
    return ca.DM(ca.diag(ca.DM(np.asarray(v, dtype=float))))


def stagewise_qp_function(mpc: Any) -> ca.Function:
    """``sw_qp(z, p) -> (dU0, dX0, A, B, Q, q, g, r, lo, hi)``, for checks.

    The stage-wise QP (`ocp.mpc.stagewise_ipm`) of the plan ``z`` (x_0
    the measured state) and parameters ``p = (x, q_f, τ)``.
    """
    parts = StageParts(mpc, IPM_TOL, 1)
    z = ca.MX.sym("z", mpc.nz)
    p = ca.MX.sym("p", mpc.model.nx + 7)
    return ca.Function("sw_qp", [z, p], list(qp_data(mpc, parts, z, p)[3]))


def stagewise_iteration(mpc: Any, tol: float = IPM_TOL,
                        max_iter: int = IPM_MAX_ITER) -> ca.Function:
    """``sw_iter(z, lam_x0, p) -> (z_new, lam_x, step, qp_kkt)``.

    One Gauss–Newton SQP step (the condensed step's QP, stage-wise):
    ``z`` a plan whose x_0 is the measured state (p's first n_x entries);
    ``lam_x0`` is not used (an interior point starts cold); ``lam_x`` the
    boxes' multipliers in z's layout; ``step = max |δu / m_max|``;
    ``qp_kkt`` the interior point's KKT residual.
    """
    parts = StageParts(mpc, tol, max_iter)
    z = ca.MX.sym("z", mpc.nz)
    lx0 = ca.MX.sym("lam_x", mpc.nz)
    p = ca.MX.sym("p", mpc.model.nx + 7)
    X, U, xN, data, _ = qp_data(mpc, parts, z, p)
    assert parts.ipm is not None
    dU, dX, lam, _, kkt = parts.ipm(*data)
    return ca.Function("sw_iter", [z, lx0, p],
                       [*new_plan(mpc, parts, X, U, xN, dU, dX, lam), kkt],
                       ["z", "lam_x0", "p"],
                       ["z_new", "lam_x", "step", "qp_kkt"])


def new_plan(mpc: Any, parts: StageParts, X, U, xN, dU, dX, lam) -> list:
    """``[z_new, lam_x, step]`` of a QP's step (dU, dX) from the plan's
    stages (X, U, xN), with the boxes' multipliers ``lam`` (n_b × N) in
    z's layout and ``step = max |δu / m_max|``."""
    N, nx, lay = mpc.horizon, mpc.model.nx, parts.lay
    dX = dX[:nx, :]                         # the cones' states dropped
    z_new = ca.vertcat(
        ca.vec(ca.vertcat(X + ca.horzcat(ca.DM.zeros(nx, 1), dX[:, :N - 1]),
                          U + dU)), xN + dX[:, N - 1])
    lam_u = ca.densify(ca.mtimes(lay.Eu.T, lam))
    lam_xs = ca.densify(ca.mtimes(lay.Ex.T, lam))[:nx, :]
    lam_z = ca.vertcat(
        ca.vec(ca.vertcat(ca.horzcat(ca.DM.zeros(nx, 1),
                                     lam_xs[:, :N - 1]), lam_u)),
        lam_xs[:, N - 1])
    step = ca.mmax(ca.mtimes(_diag(1.0 / parts.m_max), ca.fabs(dU)))
    return [z_new, lam_z, step]


def check_stagewise_options(options: dict,
                            who: str = "solver='stagewise'",
                            qp_solver: str = "") -> None:
    """Refuse ``solver_options`` the stage-wise SQP does not take: the
    interior point's with ``qp_solver="rqp"``, and ``qp_max_iter``
    without it."""
    allowed = {"step_tol", "anderson", "kkt_tol"} | (
        {"qp_max_iter"} if qp_solver == "rqp" else
        {"ipm_tol", "ipm_max_iter"})
    extra = set(options) - allowed
    if extra:
        raise InvalidValueError(
            f"{who} takes solver_options {sorted(allowed)}: "
            f"{sorted(extra)}")


def stagewise_step_functions(mpc: Any, step_tol: float = STEP_TOL,
                             anderson: int = ANDERSON_MEMORY,
                             ipm_tol: float = IPM_TOL,
                             ipm_max_iter: int = IPM_MAX_ITER,
                             qp_max_iter: int | None = None,
                             kkt_tol: float = QP_KKT_TOL
                             ) -> tuple[ca.Function, ca.Function]:
    """``(rti_function, step_function)`` of the stage-wise SQP.

    The same Functions as `ocp.mpc.condensed.condensed_step_functions`
    (inputs, outputs, RTI and the iterations to ``step_tol`` with
    Anderson acceleration), named ``mpc_sw_rti`` and ``mpc_sw_step``;
    ``ipm_tol`` and ``ipm_max_iter`` are the interior point's
    (`ocp.mpc.stagewise_ipm.IPM_TOL`, `IPM_MAX_ITER`). With
    ``mpc.qp_solver == "rqp"`` the Riccati active set in C solves the QP
    (`ocp.mpc.stagewise_rqp`), at most ``qp_max_iter`` iterations (a
    positive int; default `ocp.mpc.condensed_qp.QP_ITER_LIMIT`), and both
    Functions output ``qp_capped`` too, and the shifted plan's last
    torque is clipped to keep the momentum bound
    (`ocp.mpc.condensed.momentum_safe_tail`). ``kkt_tol``: the QP
    certificate's threshold (`ocp.mpc.condensed.sqp_step_functions`;
    float exports take `ocp.codegen.precision.TOLERANCES`' ``qp_kkt_tol``).
    """
    from .condensed import check_qp_max_iter

    if mpc.model.thrusters is not None:
        raise InvalidValueError(
            "solver='stagewise' handles wheel-only models; with thrusters "
            "use solver='sqpmethod'")
    rqp = mpc.qp_solver == "rqp"
    if rqp:
        from .stagewise_rqp import rqp_iteration
        it = rqp_iteration(mpc, check_qp_max_iter("rqp", qp_max_iter))
    else:
        it = stagewise_iteration(mpc, ipm_tol, ipm_max_iter)
    # a primal active set starts where the step starts: the shifted
    # plan's repeated last torque must keep the momentum bound
    return sqp_step_functions(mpc, it, "mpc_sw", step_tol, anderson,
                              kkt_tol, safe_tail=rqp)
