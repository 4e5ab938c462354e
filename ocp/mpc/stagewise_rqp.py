"""One stage-wise SQP iteration whose QP the Riccati active set solves
(``AttitudeMPC(solver="stagewise", qp_solver="rqp")``).

The QP is `ocp.mpc.stagewise`'s, posed the same way; `ocp.mpc.riccati_qp`
solves it in C from the step's start (the shifted plan, dynamics kept),
its warm working set the shifted multipliers' signs. The point's
certificate is the interior point's KKT residual
(`ocp.mpc.stagewise_ipm.kkt_residual`'s, its costate sweep done by
rqp's wrapper: `costate_residual`) when the solver reached the optimum;
a capped point
(``qp_max_iter`` iterations made) is certified as a feasible descent
instead (`capped_certificate`), and a start that breaks a box fails
(+inf): the step then returns the shifted plan.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from adcs_common.exceptions import InvalidValueError
from .condensed_qp import QP_ITER_LIMIT
from .riccati_qp import qp_external
from .stagewise import StageParts, qp_data, new_plan
from .stagewise_ipm import IPM_TOL, combined_residual, residual_parts


def warm_sides(mpc: Any, parts: StageParts, lam_x) -> ca.MX:
    """The boxes' multipliers (n_b × N, `BoxLayout`'s order; their signs
    are the warm working set) from multipliers ``lam_x`` in z's layout
    (the keep-out cones' states carry none)."""
    N, nx, nu = mpc.horizon, mpc.model.nx, mpc.model.nu
    n_stage = N * (nx + nu)
    L = ca.reshape(lam_x[:n_stage], nx + nu, N)
    Lx = ca.horzcat(L[:nx, 1:], lam_x[n_stage:])
    if parts.nq > nx:
        Lx = ca.vertcat(Lx, ca.MX.zeros(parts.nq - nx, N))
    return parts.lay.values(L[nx:, :], Lx)


def qp_cost(kern: dict, N: int, dU, dX, Q, q, g, r) -> ca.MX:
    """The stage-wise QP's cost at (dU, dX): Σ ½δxᵀQδx + qᵀδx + ½ r δu²
    + gᵀδu over the stages."""
    Qx = kern["qmul"].map(N)(Q, dX)
    return (0.5 * ca.sum1(ca.sum2(dX * Qx)) + ca.sum1(ca.sum2(q * dX))
            + 0.5 * ca.sum1(ca.sum2(r * dU * dU)) + ca.sum1(ca.sum2(g * dU)))


def capped_certificate(parts: StageParts, N: int, start, point, data,
                       moved=None) -> ca.MX:
    """Certificate of a capped point (dU, dX) reached from ``start``:
    the largest box violation (in box widths) and the cost's rise from
    the start's (relative to 1 + |its cost|). Zero for every iterate of
    the solver in exact arithmetic. Where ``moved`` (the wrapper's phase
    one ran: the start broke a box, and the iterates' costs fall from
    phase one's point, not from the start's) the violation alone."""
    _, _, Q, q, g, r, lo, hi = data[:8]
    V = parts.lay.values(point[0], point[1])
    broken = ca.fmax(ca.mmax(ca.vertcat(ca.vec(lo - V), ca.vec(V - hi))),
                     0.0)
    c0 = qp_cost(parts.kern, N, start[0], start[1], Q, q, g, r)
    c1 = qp_cost(parts.kern, N, point[0], point[1], Q, q, g, r)
    rise = ca.fmax(c1 - c0, 0.0) / (1.0 + ca.fabs(c0))
    if moved is not None:
        rise = ca.if_else(moved > 0, 0.0, rise)
    return ca.fmax(broken, rise)


def check_rqp_problem(mpc: Any) -> None:
    """Refuse what rqp cannot take: move blocks, and keep-out cones
    (their states' boxes are not tested with the wrapper's phase one).

    A rate bound takes the phase one (`ocp.mpc.riccati_qp.wrapper_source`
    ``phase_one``): with a rate bound of 1°/s the demo slew's shifted
    plan breaks a rate box in 119 of 453 steps (the linearisation's
    defects); without it each was a refused step returning the shifted
    plan, and a loop that applied them (flight code cannot raise) broke
    more: 448 of the 453 steps, the craft spun up to 259°/s. Torque and
    momentum boxes are kept by the start (the momentum dynamics are
    linear, and the shifted plan's last torque is clipped to the
    momentum bound).

    Raises
    ------
    InvalidValueError
    """
    for what, present in (("move_blocks", mpc.move_blocks is not None),
                          ("keep-out cones (keep_out)", bool(mpc.keep_out))):
        if present:
            raise InvalidValueError(
                f"qp_solver='rqp' takes no {what}; use qp_solver=None "
                "(the interior point) or solver='condensed' with "
                "qp_solver='pqp'")


def costate_residual(parts: StageParts, N: int, dU, dX, lam, mu,
                     data) -> ca.MX:
    """The KKT residual of rqp's optimum (dU, dX) with the boxes'
    multipliers ``lam`` and the costates ``mu`` (n_q × N) that rqp's
    wrapper swept back from them: `ocp.mpc.stagewise_ipm.kkt_residual`'s
    parts (the inputs' reduced gradient r δu + g + E_uᵀλ + B_kᵀμ_k
    relative to 1 + max |q|, |g|; the boxes' residual, complementarity
    and violation), the costate sweep done in C instead of over
    time-reversed copies of the stage data (1,220 reals of the step's
    work at N = 10). +inf for a point with a NaN or an infinity."""
    A, B, _, q, g, r, lo, hi = data
    nu = dU.shape[0]
    V = parts.lay.values(dU, dX)
    point = [dU, dX, V - lo, hi - V, ca.fmax(-lam, 0), ca.fmax(lam, 0)]
    _, gu = parts.lay.lift(ca.MX.zeros(parts.nq, N), r * dU + g, lam)
    _, _, rho = parts.kern["costate"].map(N)(
        ca.MX.zeros(parts.nq, N), ca.MX.zeros(nu, N), A, B, mu, gu,
        ca.DM.ones(1, N))
    dual, primal, comp, brk, total = residual_parts(parts.lay, rho, point,
                                                    lo, hi, q, g)
    return combined_residual(dual, primal, comp, brk,
                             total + ca.sum1(ca.sum2(mu)))


def rqp_iteration(mpc: Any, qp_max_iter: int = QP_ITER_LIMIT
                  ) -> ca.Function:
    """``sw_iter(z, lam_x0, p) -> (z_new, lam_x, step, qp_kkt,
    qp_capped)``: `ocp.mpc.stagewise.stagewise_iteration` with the QP
    solved by rqp (module doc), at most ``qp_max_iter`` iterations; a
    capped point's ``lam_x`` holds its working set's sides, ±1."""
    N, nu = mpc.horizon, mpc.model.nu
    check_rqp_problem(mpc)
    parts = StageParts(mpc, IPM_TOL, 1, ipm=False)
    z = ca.MX.sym("z", mpc.nz)
    lx0 = ca.MX.sym("lam_x", mpc.nz)
    p = ca.MX.sym("p", mpc.model.nx + 7)
    X, U, xN, data, D = qp_data(mpc, parts, z, p)
    dU0, dX0, A, B, Q, q, g, r, lo, hi = data
    phase_one = mpc.rate_max is not None
    ext = qp_external(N, parts.lay, nu, ~parts.free, parts.patterns,
                      qp_max_iter, phase_one)
    dU, dX, lam, capped, infeasible, mu, moved = ext(
        dU0, dX0, D, A, B, Q, q, g, r, lo, hi,
        warm_sides(mpc, parts, lx0))
    qp = [A, B, Q, q, g, r, lo, hi]
    kkt = costate_residual(parts, N, dU, dX, lam, mu, qp)
    kkt = ca.if_else(capped > 0, capped_certificate(
        parts, N, (dU0, dX0), (dU, dX), qp,
        moved if phase_one else None), kkt)
    kkt = ca.if_else(infeasible > 0, ca.inf, kkt)
    return ca.Function("sw_iter", [z, lx0, p],
                       [*new_plan(mpc, parts, X, U, xN, dU, dX, lam), kkt,
                        capped],
                       ["z", "lam_x0", "p"],
                       ["z_new", "lam_x", "step", "qp_kkt", "qp_capped"])

