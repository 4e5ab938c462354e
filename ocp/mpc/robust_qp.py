"""The robust MPC's SQP step: a scenario tree solved stage-wise.

The robust (multi-stage) MPC plans one trajectory per `Scenario`, all
from the measured state and all applying the same first control
(non-anticipativity; robust horizon 1). Its cost is the weighted sum of
the scenarios' costs, each the nominal MPC's cost; every bound holds in
every scenario. One Gauss–Newton SQP step linearises each scenario
along its own plan with its own inertia and wheel axes, and solves the
QP on the tree with the stage-wise interior point
(`ocp.mpc.stagewise_ipm`, `Tree` with a root): the scenarios' sweeps run
side by side (CasADi ``map`` over the scenarios of the ``mapaccum`` over
the stages), their first stages carry their terms in the shared control
back to the root, which chooses it. Work and generated code grow with
S·N and N respectively.

The plan ``z`` stacks the scenarios' nominal-layout plans
(`AttitudeMPC`: x_0, u_0, x_1, …, x_N each), their u_0 equal.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from adcs_common.quaternion import quat_rate
from .condensed import _kernels
from .keepout import (planning_cone_function, qp_stage_functions,
                      stage_defects)
from .stagewise import _diag, box_layout, state_box_sides
from .stagewise_ipm import IPM_MAX_ITER, IPM_TOL, Tree, ipm_solve
from .stagewise_kernels import stage_kernels


#: How far [scaled, 1] the copies of the shared control's box are moved
#: out in the scenarios after the first.
UNBOX = 1e3


def scenario_parameters(mpc: Any) -> np.ndarray:
    """θ (p × S): each scenario's J, J⁻¹ and wheel axes, column-major."""
    cols = []
    for sc in mpc.scenarios:
        A = mpc.wheels.axes if sc.axes is None else sc.axes
        cols.append(np.r_[sc.inertia.ravel(order="F"),
                          np.linalg.inv(sc.inertia).ravel(order="F"),
                          np.asarray(A, float).ravel(order="F")])
    return np.array(cols).T


def param_rk4(mpc: Any) -> ca.Function:
    """``rk4_p(x, u, tau, θ) -> x⁺``: one RK4 step of the wheeled craft
    whose inertia and axes are the parameters θ (`scenario_parameters`).

    The same equations as `ocp.rigid_spacecraft`'s dynamics (theory §3).
    """
    wh, nx, nu = mpc.wheels, mpc.model.nx, mpc.model.nu
    n = wh.n_wheels
    x, u, tau = ca.SX.sym("x", nx), ca.SX.sym("u", nu), ca.SX.sym("tau", 3)
    th = ca.SX.sym("theta", 18 + 3 * n)
    J = ca.reshape(th[:9], 3, 3)
    Jinv = ca.reshape(th[9:18], 3, 3)
    A = ca.reshape(th[18:], 3, n)
    scale = ca.DM(np.asarray(wh.scale * wh.active, float))

    def f(xv):
        q, w, h = xv[:4], xv[4:7], xv[7:]
        m = scale * u
        wdot = ca.mtimes(Jinv, -ca.cross(w, ca.mtimes(J, w)
                                          + ca.mtimes(A, h))
                         - ca.mtimes(A, m) + tau)
        return ca.vertcat(quat_rate(q, w), wdot, m)

    dt = mpc.dt
    k1 = f(x)
    k2 = f(x + dt / 2 * k1)
    k3 = f(x + dt / 2 * k2)
    k4 = f(x + dt * k3)
    xf = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("rk4_p", [x, u, tau, th], [xf],
                       ["x", "u", "tau", "theta"], ["xf"])


class _RobustParts:
    """Kernels, boxes, the tree and its solver for one robust MPC."""

    def __init__(self, mpc: Any, tol: float, max_iter: int) -> None:
        model, wh, w = mpc.model, mpc.wheels, mpc.weights
        nx, nu, N = model.nx, model.nu, mpc.horizon
        self.S = S = len(mpc.scenarios)
        rk4 = param_rk4(mpc)
        x, u, tau = ca.SX.sym("x", nx), ca.SX.sym("u", nu), ca.SX.sym("t", 3)
        th = ca.SX.sym("th", rk4.size1_in(3))
        F = rk4(x, u, tau, th)
        Aj, Bj = ca.jacobian(F, x), ca.jacobian(F, u)
        self.cones = planning_cone_function(mpc)
        self.nq = nx + len(mpc.keep_out)     # the QP's state
        kern = _kernels(mpc)
        qf, a, c = ca.SX.sym("qf", 4), ca.SX.sym("a"), ca.SX.sym("c")
        Q, q, _ = kern["stage"](x, qf, a, c)
        #: patterns of A_k, B_k and Q_k (their nonzeros cross the kernels)
        self.lin, self.stage, self.sparsity = qp_stage_functions(
            "rb", [x, u, tau, th], F, Aj, Bj, [x, qf, a, c], Q, q,
            self.cones)
        self.rk4 = rk4
        self.m_max = np.asarray(wh.m_max, dtype=float)
        self.r_diag = 2.0 * w.torque / self.m_max ** 2 + mpc.regularization
        self.lay = box_layout(mpc)
        lo, hi = model.control_bounds()
        self.free = np.asarray(hi > lo)
        self.kern = stage_kernels(*self.sparsity, self.free, self.lay.bu,
                                  self.lay.bx)
        self.tree = Tree(N, S, root=True)
        # every stage is an unblocked Riccati step; the first stages'
        # factors give the root its terms (`Tree.root_factor`)
        self.flags = np.ones(N * S)
        self.ipm = ipm_solve(self.kern, self.lay, self.tree, self.nq, nu,
                             max_iter, tol, self.flags)
        wts = np.array([sc.weight for sc in mpc.scenarios], float)
        self.weights = wts / wts.sum()
        self.theta = ca.DM(scenario_parameters(mpc))
        self.tau = ca.DM(np.array([sc.tau for sc in mpc.scenarios]).T)
        # column selections of the (N + 1)·S states: k < N, k ≥ 1
        self.sel0, self.sel1 = stage_selections(N, S)
        rows = [i for i in range(self.lay.nbu) for _ in range(1, S)]
        cols_ = [s_ * N for _ in range(self.lay.nbu) for s_ in range(1, S)]
        self.unbox = ca.DM(ca.Sparsity.triplet(self.lay.nb, N * S, rows,
                                               cols_), UNBOX)
        # the root's start: every scenario's u_0 from scenario 0's
        first = np.arange(N * S)
        first[::N] = 0
        self.share = ca.DM(ca.Sparsity.triplet(N * S, N * S, list(first),
                                               list(range(N * S))), 1.0)


def _selection(columns: np.ndarray, n: int) -> ca.DM:
    """The (n × len(columns)) 0/1 matrix picking ``columns``."""
    return ca.DM(ca.Sparsity.triplet(n, len(columns), list(columns),
                                     list(range(len(columns)))), 1.0)


def stage_selections(N: int, S: int, first: bool = False) -> tuple:
    """Selections of the stage columns of a robust plan (`split_plan`).

    ``(sel0, sel1)``: the ((N+1)·S × N·S) 0/1 matrices picking, from the
    (N + 1)·S stage columns of `split_plan` (scenario-major), each
    scenario's stages k < N and k ≥ 1; ``first`` adds a third, the
    ((N+1)·S × S) selection of each scenario's stage 0. ``Xall @ sel0``
    picks, ``dX @ sel1.T`` puts back.
    """
    n = (N + 1) * S
    cols = np.arange(n).reshape(S, N + 1)
    sels = (_selection(cols[:, :N].ravel(), n),
            _selection(cols[:, 1:].ravel(), n))
    return sels + (_selection(cols[:, 0], n),) if first else sels


def plan_stages(mpc: Any, z, sels: tuple | None = None) -> tuple:
    """``(Xall, Uall, X, U, X1)`` of a robust plan ``z``.

    `split_plan`'s stages and, picked by `stage_selections` (or the
    given ``sels``), the states and controls of the stages k < N (X,
    U: n_x × N·S, n_u × N·S) and the states of the stages k ≥ 1 (X1),
    scenario-major: the arguments of a ``f.map(N).map(S)`` over the
    stages and the states it should reach.
    """
    sel0, sel1 = sels if sels is not None else stage_selections(
        mpc.horizon, len(mpc.scenarios))
    Xall, Uall = split_plan(mpc, z)
    return (Xall, Uall, ca.mtimes(Xall, sel0), ca.mtimes(Uall, sel0),
            ca.mtimes(Xall, sel1))


def per_stage(v: Any, N: int) -> Any:
    """Each column of ``v`` (one per scenario) repeated ``N`` times.

    ``(m, S) -> (m, N S)``, scenario-major: the argument of a
    ``f.map(N).map(S)`` that is constant over a scenario's stages.
    """
    return ca.kron(v, ca.DM.ones(1, N))


def split_plan(mpc: Any, z) -> tuple:
    """``(Xall (n_x × (N+1)S), Uall (n_u × (N+1)S))`` of a robust plan.

    Each scenario's plan gets a dummy u_N (zero) so that it reshapes to
    (n_x + n_u) × (N + 1).
    """
    nx, nu, N = mpc.model.nx, mpc.model.nu, mpc.horizon
    S = len(mpc.scenarios)
    Z = ca.reshape(z, mpc.nz // S, S)
    W = ca.reshape(ca.vertcat(Z, ca.MX.zeros(nu, S)), nx + nu, (N + 1) * S)
    return W[:nx, :], W[nx:, :]


def join_plan(mpc: Any, Xall, Uall) -> ca.MX:
    """The inverse of `split_plan` (the dummy controls dropped)."""
    nx, nu, N = mpc.model.nx, mpc.model.nu, mpc.horizon
    S = len(mpc.scenarios)
    W = ca.reshape(ca.vertcat(Xall, Uall), (nx + nu) * (N + 1), S)
    return ca.vec(W[:mpc.nz // S, :])


def _qp_data(mpc: Any, parts: _RobustParts, z, p) -> tuple:
    """``(Xall, Uall, data)``: the plan's stages and the tree's QP data."""
    model, w, N, S = mpc.model, mpc.weights, mpc.horizon, parts.S
    nx = model.nx
    lay = parts.lay
    qf = p[nx:nx + 4]
    tau = ca.repmat(p[nx + 4:], 1, S) + parts.tau
    Xall, Uall, X, U, X1 = plan_stages(mpc, z, (parts.sel0, parts.sel1))
    # one column per stage, scenario-major: a (·, S) argument would be
    # tiled by the map, stage k of scenario s getting scenario (sN+k) mod S
    args = [X, U, per_stage(tau, N), per_stage(parts.theta, N)]
    D, An, Bn = stage_defects(parts.lin.map(N).map(S), args, X1,
                              parts.cones)
    a = ca.DM([[1.0] * (N - 1) + [0.0]])
    c = ca.DM([[1.0] * (N - 1) + [w.terminal]])
    Qn, q = parts.stage.map(N).map(S)(X1, qf, a, c)
    wcol = _diag(np.repeat(parts.weights, N))
    Qn, q = ca.mtimes(Qn, wcol), ca.mtimes(q, wcol)
    g = ca.mtimes(ca.mtimes(_diag(2.0 * w.torque / parts.m_max ** 2), U),
                  wcol)
    r = ca.mtimes(ca.repmat(ca.DM(parts.r_diag), 1, N * S), wcol)
    u_lo, u_hi = (ca.repmat(ca.DM(v), 1, N * S)
                  for v in model.control_bounds())
    x_lo, x_hi = state_box_sides(mpc, X1, parts.cones)
    # the shared u_0 is boxed once, in scenario 0: the other scenarios'
    # copies of its box are moved far out (duplicate rows are degenerate)
    lo = lay.values(u_lo - U, x_lo) - parts.unbox
    hi = lay.values(u_hi - U, x_hi) + parts.unbox
    fixed = _diag((~parts.free).astype(float))
    dU0 = (ca.mtimes(fixed, u_lo - U) + ca.mtimes(
        _diag(parts.free.astype(float)), ca.mtimes(U, parts.share) - U))
    roll = parts.tree.sweep(parts.kern["roll"], "rb_roll_N", 1)
    dX0 = roll(ca.DM.zeros(parts.nq), An, Bn, dU0, D)
    return Xall, Uall, (dU0, dX0, An, Bn, Qn, q, g, r, lo, hi)


def robust_qp_function(mpc: Any) -> ca.Function:
    """``rb_qp(z, p) -> (dU0, dX0, A, B, Q, q, g, r, lo, hi)``, for checks."""
    parts = _RobustParts(mpc, IPM_TOL, 1)
    z = ca.MX.sym("z", mpc.nz)
    p = ca.MX.sym("p", mpc.model.nx + 7)
    return ca.Function("rb_qp", [z, p], list(_qp_data(mpc, parts, z, p)[2]))


def robust_iteration(mpc: Any, tol: float = IPM_TOL,
                     max_iter: int = IPM_MAX_ITER) -> ca.Function:
    """``rb_iter(z, lam_x0, p) -> (z_new, lam_x, step, qp_kkt)``.

    One Gauss–Newton SQP step of the scenario tree (module doc), the
    same outputs as `ocp.mpc.stagewise.stagewise_iteration`.
    """
    parts = _RobustParts(mpc, tol, max_iter)
    lay = parts.lay
    z = ca.MX.sym("z", mpc.nz)
    lx0 = ca.MX.sym("lam_x", mpc.nz)
    p = ca.MX.sym("p", mpc.model.nx + 7)
    Xall, Uall, data = _qp_data(mpc, parts, z, p)
    dU, dX, lam, _, kkt = parts.ipm(*data)
    nx = mpc.model.nx
    dX = dX[:nx, :]                         # the cones' states dropped
    z_new = join_plan(mpc, Xall + ca.mtimes(dX, parts.sel1.T),
                      Uall + ca.mtimes(dU, parts.sel0.T))
    lam_u = ca.densify(ca.mtimes(lay.Eu.T, lam))
    lam_xs = ca.densify(ca.mtimes(lay.Ex.T, lam))[:nx, :]
    lam_z = join_plan(mpc, ca.densify(ca.mtimes(lam_xs, parts.sel1.T)),
                      ca.densify(ca.mtimes(lam_u, parts.sel0.T)))
    step = ca.mmax(ca.mtimes(_diag(1.0 / parts.m_max), ca.fabs(dU)))
    return ca.Function("rb_iter", [z, lx0, p], [z_new, lam_z, step, kkt],
                       ["z", "lam_x0", "p"],
                       ["z_new", "lam_x", "step", "qp_kkt"])
