"""The condensed MPC's QP in ``y = W δu`` and how it is routed.

`ocp.mpc.condensed` hands each SQP iteration's QP here: Hessian I (the
Riccati factor W, `ocp.mpc.riccati`), the bounds on δu as the rows of
W⁻¹, the momentum (and rate) rows lower block triangular. The bounds
alone are solved first when the warm start has no active row; the rows
are added only when that point breaks one.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import casadi as ca


#: Largest excess of a momentum or rate row [N·m·s, rad/s] at which the
#: QP without those rows answers the QP with them.
ROW_TOL = 1e-10
#: DAQP iterations allowed per QP solve: with at most three solves per SQP
#: iteration (the bounds alone, the rows, a cold restart) and the SQP's
#: iteration limit, the step's worst case is bounded by construction. The
#: cold first step of the 90° slew takes 107 iterations; a QP stopped by
#: the limit fails its certificate (``qp_kkt``), never silently.
QP_ITER_LIMIT = 1000


def _independent_rows(N: int, nu: int, nw: int, na: int) -> ca.Function:
    """``keep(lam_x0, lbx, ubx, lam_a0) -> lam_a0``: a warm start DAQP takes.

    Momentum row k of wheel i is the sum of its bounds' rows j < k, so a
    working set holding the row, the previous kept row of that wheel and
    every bound between them is dependent (DAQP's setup then fails). The
    scan drops such rows; the other rows (rates) start inactive. It runs
    over the stages as a ``mapaccum`` of one stage's test (the wheels'
    torques are the first n_w controls of a stage).
    """
    cov = ca.SX.sym("covered", nw)
    lx, lb, ub = (ca.SX.sym(n, nu) for n in ("lam_x0", "lbx", "ubx"))
    la = ca.SX.sym("lam_a0", nw)
    cov_next, out = [], []
    for i in range(nw):
        c = cov[i] * ca.logic_or(lx[i] != 0, lb[i] == ub[i])
        keep = ca.logic_and(la[i] != 0, ca.logic_not(c))
        out.append(ca.if_else(keep, la[i], 0))
        cov_next.append(ca.if_else(keep, 1, c))
    stage = ca.Function("cond_rows_stage", [cov, lx, lb, ub, la],
                        [ca.vertcat(*cov_next), ca.vertcat(*out)])
    scan = stage.mapaccum("cond_rows_scan", N, 1)
    ins = [ca.MX.sym(n, m) for n, m in (("lam_x0", N * nu), ("lbx", N * nu),
                                         ("ubx", N * nu), ("lam_a0", na))]
    _, kept = scan(ca.DM.ones(nw), *(ca.reshape(v, nu, N) for v in ins[:3]),
                   ca.reshape(ins[3][:N * nw], nw, N))
    return ca.Function("cond_rows_warm", ins,
                       [ca.vertcat(ca.vec(kept), ca.DM.zeros(na - N * nw))])


class RowLayout:
    """Where the QP's rows sit in G (`ocp.mpc.riccati.factor_rows`):
    stage by stage, h = n_u + n_w (+ 3 with rate rows) each: the bounds
    on δu_k, the momenta of δx_{k+1}, its rates. ``spread`` places the
    bound values (n_u N,) and the rows' values (momenta then rates, as
    `lba` orders them) in that order; ``bounds`` and ``rows`` pick them
    back (strided copies in C)."""

    def __init__(self, N: int, nu: int, nw: int, h: int) -> None:
        def pick(lo: int, hi: int) -> list[int]:
            return [k * h + i for k in range(N) for i in range(lo, hi)]
        self.n = N * h
        self.u = pick(0, nu)
        self.parts = [pick(nu, nu + nw)] + (
            [pick(nu + nw, h)] if h > nu + nw else [])

    def spread(self, bounds, rows) -> ca.MX:
        v = ca.MX(ca.DM.zeros(self.n))
        v[self.u] = bounds
        top = 0
        for idx in self.parts:
            v[idx] = rows[top:top + len(idx)]
            top += len(idx)
        return v

    def bounds(self, v) -> ca.MX:
        return v[self.u]

    def rows(self, v) -> ca.MX:
        return ca.vertcat(*[v[idx] for idx in self.parts])


def routed_qp(plugin: str, N: int, nu: int, nw: int, sp_w: ca.Sparsity,
              sp_g: ca.Sparsity, row_tol: float = ROW_TOL,
              qp_tol: float | None = None,
              max_iter: int = QP_ITER_LIMIT) -> Callable[..., list]:
    """Build the QP in ``y`` (`ocp.mpc.riccati`): Hessian I, bounds as rows.

    ``qp(g, W⁻¹, G, lbu, ubu, lba, uba, lam_u0, lam_a0) -> [y, lam_u,
    lam_a, lam]`` (``lam``: the multipliers in G's order; a Python
    callable of MX that calls the route in the caller's graph): minimise
    ``½|y|² + gᵀy`` subject to ``lbu ≤ W⁻¹y ≤ ubu`` (the bounds on δu)
    and ``lba ≤ rows·y ≤ uba`` (momentum, rate), ``G`` W⁻¹ and the rows
    stage by stage (`ocp.mpc.riccati.factor_rows`, `RowLayout`).
    When the warm start holds no active row (holds, small slews): the QP
    with the bounds alone first; its point is the answer when it meets
    every row within `ROW_TOL` (the rows can only cut that QP's feasible
    set), else the QP with the rows, started from its active set. When
    rows were active: the QP with the rows directly, started from the
    bounds and the rows of the warm start (`_independent_rows`).
    The point's optimality certificate is the caller's (`kkt_residual`,
    from products it can form in O(N)).
    ``row_tol`` replaces `ROW_TOL` and ``qp_tol`` (qrqp only) its
    ``constr_viol_tol`` / ``dual_inf_tol`` (float exports,
    `ocp.codegen.precision.TOLERANCES`).
    With ``"pqp"`` the route returns three values more, ``capped`` (1
    where the solver stopped at ``max_iter`` iterations), ``infeasible``
    and ``moved`` (`_primal_route`).
    """
    n, na = N * nu, sp_g.size1() - N * nu
    if plugin == "pqp":
        return _primal_route(N, nu, nw, sp_g, max_iter)
    at = RowLayout(N, nu, nw, sp_g.size1() // N)
    g = ca.MX.sym("g", n)
    W = ca.MX.sym("Winv", sp_w)
    R = ca.MX.sym("G", sp_g)
    lbu, ubu = ca.MX.sym("lbu", n), ca.MX.sym("ubu", n)
    lba, uba = ca.MX.sym("lba", na), ca.MX.sym("uba", na)
    lu0 = ca.MX.sym("lam_u0", n)
    opts = _qp_options(plugin)
    if qp_tol is not None and plugin == "qrqp":
        opts.update(constr_viol_tol=qp_tol, dual_inf_tol=qp_tol)
    eye = ca.DM.eye(n)
    box = ca.conic("cond_qp_box", plugin, {"h": eye.sparsity(),
                                           "a": sp_w}, opts)
    full = ca.conic("cond_qp", plugin, {"h": eye.sparsity(),
                                        "a": sp_g}, opts)

    def with_rows(lam_u, lam_a):
        # evaluated in the branches with the rows
        s = full(h=eye, g=g, a=R, lba=at.spread(lbu, lba),
                 uba=at.spread(ubu, uba), lam_a0=at.spread(lam_u, lam_a))
        return [s["x"], at.bounds(s["lam_a"]), at.rows(s["lam_a"]),
                s["lam_a"]]

    rows_warm = _independent_rows(N, nu, nw, na)
    # the bounds first (unless the warm start holds a row): their point,
    # multipliers, whether it breaks a row, and the rows it breaks
    bi = [g, W, R, lbu, ubu, lba, uba, lu0]
    s1 = box(h=eye, g=g, a=W, lba=lbu, uba=ubu, lam_a0=lu0)
    ay = at.rows(ca.mtimes(R, s1["x"]))
    broken = ca.if_else(ay > uba, 1, 0) - ca.if_else(ay < lba, 1, 0)
    excess = ca.mmax(ca.vertcat(ay - uba, lba - ay, 0.0))
    # (the branches that skip a QP are MX: an SX Function writes its
    # outputs element by element, kilobytes of flash; their work stays
    # below the QP branch's)
    first = ca.Function.if_else(
        "cond_qp_first_bounds",
        ca.Function("cond_qp_warm_rows", bi, [ca.MX.zeros(n), ca.MX.zeros(n),
                                              1, ca.MX.zeros(na)]),
        ca.Function("cond_qp_bounds", bi, [s1["x"], s1["lam_a"],
                                           excess > row_tol, broken]))
    # then the rows, when the warm start held one or the bounds' point
    # breaks one, started from the bounds and those rows (independent)
    lw, aw, y1 = ca.MX.sym("lam_w", n), ca.MX.sym("rows_w", na), \
        ca.MX.sym("y1", n)
    ri = [g, R, lbu, ubu, lba, uba, lw, aw, y1]
    keep = ca.Function("cond_qp_keep", ri, [y1, lw, ca.MX.zeros(na),
                                            at.spread(lw, ca.MX.zeros(na))])
    with_rows_fn = ca.Function("cond_qp_rows", ri,
                               with_rows(lw, rows_warm(lw, lbu, ubu, aw)))
    rows = ca.Function.if_else("cond_qp_with_rows", with_rows_fn, keep)

    def routed(*a: Any) -> list:
        # called in the caller's own graph, each QP in one Function
        # below it: every level of Functions reserves its arguments (here
        # W⁻¹ and G, 10k reals) in the work vector
        g_, W_, R_, lbu_, ubu_, lba_, uba_, lu0_, la0_ = a
        warm = ca.mmax(ca.fabs(la0_)) > 0
        y1_, l1_, need, broken_ = first(warm, g_, W_, R_, lbu_, ubu_, lba_,
                                        uba_, lu0_)
        return rows(need, g_, R_, lbu_, ubu_, lba_, uba_,
                    ca.if_else(warm, lu0_, l1_), ca.if_else(warm, la0_,
                                                            broken_), y1_)

    return routed


def _primal_route(N: int, nu: int, nw: int, sp_g: ca.Sparsity,
                  max_iter: int) -> Callable[..., list]:
    """`routed_qp`'s QP by the primal active set in C (`ocp.mpc.primal_qp`)
    from y = 0 and the warm start's signs, at most ``max_iter``
    iterations; where y = 0 breaks a bound (a defect, or a rate beyond
    its bound), after a phase one of at most ``max_iter`` iterations to
    the nearest point that keeps every bound. Returns ``[y, lam_u,
    lam_a, lam, capped, infeasible, moved]``: a capped point keeps every
    bound and lowers the cost from where the primal phase started
    (`capped_residual` checks it); in place of multipliers it returns its
    working set's sides, ±1, the next step's warm start. ``infeasible``:
    1 where no point keeping every bound was found (y = 0, no
    multipliers); ``moved``: 1 where phase one ran."""
    from .primal_qp import qp_external

    ext = qp_external(N, nu, nw, sp_g, max_iter)

    def primal(*a: Any) -> list:
        g_, _, R_, lbu_, ubu_, lba_, uba_, lu0_, la0_ = a
        *sol, infeasible, capped, moved = ext(g_, R_, lbu_, ubu_, lba_,
                                              uba_, lu0_, la0_)
        return [*sol, capped, infeasible, moved]
    return primal


def kkt_residual(y, g, dual, v, a, lam_u, lam_a, lbu, ubu, lba, uba):
    """Optimality certificate of the QP's point y: the KKT residual.

    ``v = W⁻¹y`` and ``a = rows·y`` are the point's bounded values and
    ``dual = W⁻ᵀλ_u + rowsᵀλ_a`` its multipliers' gradient (the caller
    forms them in O(N), `ocp.mpc.riccati`). The largest of stationarity
    ``|y + g + dual|_∞`` (relative to ``1 + |g|_∞``), the row violations
    and the complementarity ``λ⁺ (ub - v) + λ⁻ (v - lb)`` of every row
    (relative to the rows' scale): zero at the QP's optimum (the QP is
    strictly convex), whatever conic solved it.
    """
    stat = ca.mmax(ca.fabs(y + g + dual))
    scale_g = 1.0 + ca.mmax(ca.fabs(g))
    primal, size = _violation(v, a, lbu, ubu, lba, uba)
    lam = 1.0 + ca.mmax(ca.vertcat(ca.fabs(lam_u), ca.fabs(lam_a)))
    comp = ca.mmax(ca.vertcat(
        ca.fmax(lam_u, 0) * ca.fabs(ubu - v),
        ca.fmax(-lam_u, 0) * ca.fabs(v - lbu),
        ca.fmax(lam_a, 0) * ca.fabs(uba - a),
        ca.fmax(-lam_a, 0) * ca.fabs(a - lba)))
    return ca.fmax(stat / scale_g, ca.fmax(primal / size,
                                           comp / (lam * size)))


def _violation(v, a, lbu, ubu, lba, uba) -> tuple:
    """``(primal, size)``: the largest violation of the bounds by ``v``
    and of the rows by ``a``, and the rows' scale ``1 + max |bound|``
    (both certificates' feasibility term is their ratio)."""
    size = 1.0 + ca.mmax(ca.vertcat(ca.fabs(lbu), ca.fabs(ubu),
                                    ca.fabs(lba), ca.fabs(uba)))
    primal = ca.mmax(ca.vertcat(v - ubu, lbu - v, a - uba, lba - a, 0.0))
    return primal, size


def capped_residual(y, g, v, a, lbu, ubu, lba, uba, *, moved=0):
    """Certificate of a capped QP point y (the primal active set stopped
    at its iteration limit, started from y = 0, the shifted plan).

    Such a point is not the QP's optimum; what it guarantees, and this
    checks, is that it keeps every bound and row and that its cost
    ``½|y|² + gᵀy`` is no higher than the start's (0): the largest of the
    row violations (relative to the rows' scale, as `kkt_residual`) and
    the cost's rise (relative to ``1 + |g|²``). Zero for every iterate
    of the solver in exact arithmetic. ``moved`` (1 where y = 0 broke a
    bound and phase one moved the start): the rise is not counted, the
    primal phase having started from phase one's point, not from 0.
    """
    primal, size = _violation(v, a, lbu, ubu, lba, uba)
    rise = ca.fmax(0.5 * ca.dot(y, y) + ca.dot(g, y), 0.0) * (1 - moved)
    return ca.fmax(primal / size, rise / (1.0 + ca.dot(g, g)))


def _qp_options(plugin: str) -> dict:
    if plugin == "qrqp":
        return {"print_iter": False, "print_header": False,
                "print_info": False, "error_on_fail": False,
                "max_iter": QP_ITER_LIMIT}
    return {"error_on_fail": False,
            "daqp": {"iter_limit": QP_ITER_LIMIT}}
