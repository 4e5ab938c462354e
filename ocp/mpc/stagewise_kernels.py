"""Per-stage SX kernels of the stage-wise MPC QP and its Riccati solves.

`ocp.mpc.stagewise` keeps the MPC's QP in its stage-wise form, states
and controls both, and solves it by an interior point whose Newton
systems are Riccati recursions (`ocp.mpc.stagewise_ipm`). Every kernel
here is one stage's work; the caller runs it over the horizon with
CasADi ``map`` / ``mapaccum``, so the generated C loops over the stages
and its size does not grow with N.

Matrices cross the kernels' boundaries as their nonzeros (dense column
vectors, one column per stage), so a whole horizon is one dense matrix
that a constant permutation reverses in time (`reverse_columns`).

The recursion, for stage k with the value ``½xᵀPx + pᵀx`` of x_{k+1}
(its own stage cost added first: ``P̂ = P + Q̃_{k+1}``, ``p̂ = p +
q̃_{k+1}``):

.. math::
    R^e = \\tilde R + B^T \\hat P B = L L^T,\\quad
    K = -(R^e)^{-1} B^T \\hat P A,\\quad
    k_{ff} = -(R^e)^{-1}(\\tilde r + B^T \\hat p),

    P_k = A^T \\hat P A + (B^T \\hat P A)^T K,\\quad
    p_k = A^T \\hat p + K^T(\\tilde r + B^T \\hat p),

and the step runs forward, ``Δu_k = K Δx_k + k_ff``, ``Δx_{k+1} = AΔx_k
+ BΔu_k`` from ``Δx_0 = 0``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .riccati import chol_lower, inv_lower, lower_nz, lower_symbol


def from_nz(name: str, sp: ca.Sparsity) -> tuple[ca.SX, ca.SX]:
    """``(v, M)``: a symbol of sp's nonzeros and the matrix it fills."""
    v = ca.SX.sym(name, sp.nnz())
    return v, ca.SX(sp, v)


def nz_of(M: ca.SX) -> ca.SX:
    """The nonzeros of ``M`` as a column vector (its storage order)."""
    return ca.vertcat(*[M.nz[i] for i in range(M.nnz())]) if M.nnz() \
        else ca.SX(0, 1)


def reverse_columns(M: ca.MX) -> ca.MX:
    """``M`` (m × N, dense) with its columns in reverse order.

    A product with the constant anti-diagonal permutation: in generated
    C that is one loop and an index array of about 2N integers, shared
    by every reversal of the same N, whatever m.
    """
    N = M.shape[1]
    J = ca.DM(ca.Sparsity.triplet(N, N, list(range(N)),
                                  list(range(N - 1, -1, -1))), 1.0)
    return ca.mtimes(M, J)


def stage_kernels(sp_a: ca.Sparsity, sp_b: ca.Sparsity, sp_q: ca.Sparsity,
                  free: np.ndarray, bu: list[int], bx: list[int],
                  blocked: bool = False) -> dict[str, ca.Function]:
    """The kernels of one stage's Riccati step, rollout and costate.

    Parameters
    ----------
    sp_a, sp_b, sp_q : casadi.Sparsity
        Patterns of A_k (n_x × n_x), B_k (n_x × n_u) and Q_{k+1}.
    free : ndarray (n_u,) of bool
        Controls that may move (a failed wheel's torque is fixed: its
        column of B and its gradient are masked out of the recursion).
    bu, bx : list of int
        Components of u and of x that carry a box (their barrier
        diagonals ``su``, ``sx`` are added to R and to Q).
    blocked : bool
        Move blocking: a stage whose flag ``s`` is 0 holds the control of
        the stage before it. The recursion then carries the value's terms
        in that held control v (``Pxv``, ``Pvv``, ``pv``) back to the
        block's first stage (``s = 1``), where v is chosen. Without
        blocking every stage chooses (``s = 1``) and those terms vanish
        from the kernels.
    """
    nx, nu = sp_b.size1(), sp_b.size2()
    an, A = from_nz("a", sp_a)
    bn, B0 = from_nz("b", sp_b)
    qn, Q = from_nz("q", sp_q)
    mask = ca.DM(np.asarray(free, dtype=float))
    B = ca.mtimes(B0, ca.diag(mask))
    # P is symmetric: its lower triangle crosses the boundary, and only
    # the lower triangle of P_k is computed
    pl, P = lower_symbol("P", nx)
    p = ca.SX.sym("p", nx)
    held = [ca.SX.sym("Pxv", nx, nu), ca.SX.sym("Pvv", nu, nu),
            ca.SX.sym("pv", nu)]
    s = ca.SX.sym("s")
    Pxv, Pvv, pv = held if blocked else (ca.SX(nx, nu), ca.SX(nu, nu),
                                         ca.SX(nu, 1))
    flag = s if blocked else 1.0
    sx = ca.SX.sym("sx", len(bx))
    su = ca.SX.sym("su", len(bu))
    qt = ca.SX.sym("qt", nx)
    rt = ca.SX.sym("rt", nu)
    r = ca.SX.sym("r", nu)      # the diagonal of the control Hessian R
    Ph = P + Q
    for j, i in enumerate(bx):
        Ph[i, i] += sx[j]
    PhB = ca.mtimes(Ph, B)
    Mxv = ca.mtimes(A.T, PhB + Pxv)
    Re = (ca.diag(r) + Pvv + ca.mtimes(B.T, PhB) + ca.mtimes(B.T, Pxv)
          + ca.mtimes(Pxv.T, B))
    for j, i in enumerate(bu):
        Re[i, i] += su[j]
    Lit = inv_lower(chol_lower(Re)).T
    Rinv = ca.mtimes(Lit, Lit.T)
    # P_k = AᵀP̂A − MRe⁻¹Mᵀ as AᵀP̂A − WᵀW with W = L⁻¹Mᵀ: the subtracted
    # term stays positive semidefinite in rounding. With Re⁻¹ formed first
    # (MK), a barrier diagonal of 1e10 or more on a controllable state (a
    # rate bound active over many stages) left P_k indefinite by 1e2–1e5
    # and the next stages' factors NaN
    W = ca.mtimes(Lit.T, Mxv.T)
    K = -ca.mtimes(Lit, W)
    ph = p + qt
    rhs = rt * mask + ca.mtimes(B.T, ph) + pv
    Pk = ca.mtimes(A.T, ca.mtimes(Ph, A)) - flag * ca.mtimes(W.T, W)
    keep = 1.0 - flag
    ric = ca.Function(
        "sw_ric", [pl, p, *held, an, bn, qn, sx, su, qt, rt, r, s],
        [lower_nz(Pk),
         ca.mtimes(A.T, ph) + flag * ca.mtimes(K.T, rhs),
         ca.densify(keep * Mxv), ca.densify(keep * Re),
         ca.densify(keep * rhs),
         nz_of(ca.densify(K)), -ca.mtimes(Rinv, rhs),
         nz_of(ca.densify(Lit)), nz_of(ca.densify(Mxv))])
    ln, L = from_nz("L", ca.Sparsity.dense(nu, nu))
    mn, M = from_nz("M", ca.Sparsity.dense(nx, nu))
    kv = -ca.mtimes([L, L.T, rhs])
    vec = ca.Function(
        "sw_ricvec", [p, held[2], an, bn, mn, ln, qt, rt, s],
        [ca.mtimes(A.T, ph) + flag * ca.mtimes(M, kv),
         ca.densify(keep * rhs), kv])
    kn, Kd = from_nz("K", ca.Sparsity.dense(nu, nx))
    dx = ca.SX.sym("dx", nx)
    v = ca.SX.sym("v", nu)
    kff = ca.SX.sym("kff", nu)
    du = flag * (ca.mtimes(Kd, dx) + kff) + keep * v
    fwd = ca.Function("sw_fwd", [dx, v, an, bn, kn, kff, s],
                      [ca.mtimes(A, dx) + ca.mtimes(B0, du), du, du])
    psi = ca.SX.sym("psi", nx)
    gx = ca.SX.sym("gx", nx)
    gu = ca.SX.sym("gu", nu)
    lam = psi + gx
    total = (gu + ca.mtimes(B0.T, lam)) * mask + (held[2] if blocked
                                                  else 0.0)
    costate = ca.Function("sw_costate", [psi, held[2], an, bn, gx, gu, s],
                          [ca.mtimes(A.T, lam), ca.densify(keep * total),
                           ca.densify(flag * total)])
    qmul = ca.Function("sw_qmul", [qn, dx], [ca.mtimes(Q, dx)])
    d = ca.SX.sym("d", nx)
    roll = ca.Function("sw_roll", [dx, an, bn, kff, d],
                       [ca.mtimes(A, dx) + ca.mtimes(B0, kff) + d])
    return {"ric": ric, "vec": vec, "fwd": fwd, "costate": costate,
            "qmul": qmul, "roll": roll}


def root_kernel(nu: int) -> ca.Function:
    """``root(Pvv, pv) -> (v, Lit)``: the shared control of a scenario tree.

    ``Pvv`` (n_u × n_u) and ``pv`` (n_u,) are the sums over the scenarios
    of their value's terms in the shared first control v; ``v = −Pvv⁻¹
    pv`` and ``Lit`` = L⁻ᵀ of ``Pvv = LLᵀ`` (nonzeros, for a second right
    hand side, `root_solve`).
    """
    pn, P = from_nz("Pvv", ca.Sparsity.dense(nu, nu))
    pv = ca.SX.sym("pv", nu)
    Lit = inv_lower(chol_lower(0.5 * (P + P.T))).T
    return ca.Function("sw_root", [pn, pv],
                       [-ca.mtimes([Lit, Lit.T, pv]), nz_of(Lit)])


def root_solve(nu: int) -> ca.Function:
    """``root2(Lit, pv) -> −Pvv⁻¹ pv`` from `root_kernel`'s factor."""
    ln, L = from_nz("L", ca.Sparsity.dense(nu, nu))
    pv = ca.SX.sym("pv", nu)
    return ca.Function("sw_root2", [ln, pv], [-ca.mtimes([L, L.T, pv])])


def root_terms(nu: int) -> ca.Function:
    """``terms(Lit, kff) -> (Re, rhs)``: a scenario's terms in the root's
    control, from its first stage's unblocked Riccati step.

    That step factors ``Re = R̃ + BᵀP̂B = LLᵀ`` (``Lit`` = L⁻ᵀ, nonzeros)
    and returns ``kff = −Re⁻¹ rhs``; the scenario's value in its first
    control v (x_0 is fixed) is ``½vᵀRe v + rhsᵀv``.
    """
    ln, Lit = from_nz("Lit", ca.Sparsity.dense(nu, nu))
    kff = ca.SX.sym("kff", nu)
    Lc = inv_lower(Lit.T)
    Re = ca.mtimes(Lc, Lc.T)
    return ca.Function("sw_root_terms", [ln, kff],
                       [nz_of(ca.densify(Re)), -ca.mtimes(Re, kff)])


def root_rhs(nu: int) -> ca.Function:
    """``rhs(Re, kff) -> −Re kff`` (a scenario's linear term, again)."""
    rn, Re = from_nz("Re", ca.Sparsity.dense(nu, nu))
    kff = ca.SX.sym("kff", nu)
    return ca.Function("sw_root_rhs", [rn, kff], [-ca.mtimes(Re, kff)])
