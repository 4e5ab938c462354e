"""The condensed MPC Hessian's factor from a Riccati recursion.

For the condensed QP of `ocp.mpc.condensed` (controls δu only, states
δx_{k+1} = A_k δx_k + B_k δu_k, δx_0 = 0, stage costs ½δxᵀQ_kδx and
½δuᵀRδu) the backward recursion

.. math::
    P_N = Q_N,\\quad R^e_k = R + B_k^T P_{k+1} B_k = L_k L_k^T,\\quad
    K_k = -(R^e_k)^{-1} B_k^T P_{k+1} A_k,\\quad
    P_k = Q_k + A_k^T P_{k+1} A_k + (B_k^T P_{k+1} A_k)^T K_k

writes the Hessian as a sum of squares,
:math:`δu^T H δu = Σ_k \\|L_k^T(δu_k - K_k δx_k)\\|^2 = \\|y\\|^2`, so
``y = W δu`` with W block lower triangular, and its inverse runs the
closed loop :math:`δu_k = L_k^{-T} y_k + K_k δx_k`,
:math:`δx_{k+1} = (A_k + B_k K_k) δx_k + B_k L_k^{-T} y_k`. In ``y`` the
QP has the Hessian I: DAQP then factors nothing, and the rows of every
constraint (bounds on δu, momentum and rate rows) are those of
``W⁻¹`` and of the closed-loop state sensitivities, all from one
forward sweep per column (about 0.2 Mflop at N = 20, n_x = 11, n_u = 4,
in straight-line kernels).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np


def chol_lower(M: ca.SX) -> ca.SX:
    """Lower Cholesky factor of a small symmetric positive-definite SX."""
    n = M.shape[0]
    L = ca.SX.zeros(n, n)
    for j in range(n):
        s = M[j, j] - sum((L[j, k] ** 2 for k in range(j)), ca.SX(0))
        L[j, j] = ca.sqrt(s)
        for i in range(j + 1, n):
            L[i, j] = (M[i, j] - sum((L[i, k] * L[j, k] for k in range(j)),
                                     ca.SX(0))) / L[j, j]
    return L


def inv_lower(L: ca.SX) -> ca.SX:
    """Inverse of a small lower-triangular SX by forward substitution."""
    n = L.shape[0]
    X = ca.SX.zeros(n, n)
    for j in range(n):
        X[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, n):
            X[i, j] = -sum((L[i, k] * X[k, j] for k in range(j, i)),
                           ca.SX(0)) / L[i, i]
    return X


def lower_symbol(name: str, n: int) -> tuple[ca.SX, ca.SX]:
    """``(v, P)``: a symbol of a symmetric n × n matrix's lower triangle
    (column by column, `lower_nz`'s order) and the matrix it fills."""
    low = ca.Sparsity.lower(n)
    v = ca.SX.sym(name, low.nnz())
    return v, ca.tril2symm(ca.SX(low, v))


def lower_nz(M: ca.SX) -> ca.SX:
    """The lower triangle of a symmetric M, column by column."""
    n = M.shape[0]
    return ca.vertcat(*[M[i, j] for j in range(n) for i in range(j, n)])


def _symmetric(Q, A, PA, M) -> ca.SX:
    """``Q + AᵀPA − MᵀM`` (= Q + AᵀPA + (BᵀPA)ᵀK), lower triangle formed,
    mirrored: the recursion's P stays exactly symmetric at half the
    products."""
    n = A.shape[1]
    Pk = ca.SX.zeros(n, n)
    Qd = ca.densify(Q)
    for j in range(n):
        for i in range(j, n):
            v = Qd[i, j] + ca.dot(A[:, i], PA[:, j]) - ca.dot(M[:, i], M[:, j])
            Pk[i, j] = v
            Pk[j, i] = v
    return Pk


def riccati_kernels(sp_q: ca.Sparsity, sp_a: ca.Sparsity,
                    sp_b: ca.Sparsity, mom_gain, rate_rows: bool = False
                    ) -> dict[str, ca.Function]:
    """SX kernels of the recursion and of the forward sweep.

    ``ric(P, Q, A, B, r) -> (P_k, K, Lit)`` (P, P_k: their lower
    triangles, column by column, `ric_last` of Q_N starts the recursion;
    ``r`` the diagonal of R, ``Lit`` = L⁻ᵀ); ``init(A, B, K, Lit) -> (S,
    blk, Acl)`` the response S = B Lit of δx_{k+1} to y_k, the diagonal
    block of the QP's rows and the closed loop's first 7 rows (A +
    BK)[:7]; ``sweep(K, Acl[:7], S) -> (Acl S, blk)`` one stage on.
    A block ``blk`` holds a stage's rows of the QP (`factor_rows`): δu_k
    (K S, or Lit on the diagonal), then the momentum and (with
    ``rate_rows``) rate rows of δx_{k+1}; ``adj(A, B, K, Lit, g, μ) ->
    ((W⁻ᵀg)_k, μ_k)`` a step of the closed loop's adjoint and
    ``adj_rows(A, B, K, Lit, L_k, μ)`` the same for a stage's row
    multipliers (`row_adjoint`). ``mom_gain`` (n_w,) is Δt·s:
    the momentum rows of the closed loop are ``H_{k+1} = H_k + Δt s (K
    S)``, which the sweep uses instead of the full product.
    """
    nx, nu = sp_b.size1(), sp_b.size2()
    # P is symmetric: its lower triangle crosses the boundary
    pl, P = lower_symbol("P", nx)
    Q = ca.SX.sym("Q", sp_q)
    A = ca.SX.sym("A", sp_a)
    B = ca.SX.sym("B", sp_b)
    r = ca.SX.sym("r", nu)
    # the momentum rows are exact constants ((0 I) and Δt·s, checked by
    # `ocp.mpc.condensed`): written as such, their products vanish
    nw = nx - 7
    Ac = ca.vertcat(A[:7, :], ca.horzcat(ca.SX.zeros(nw, 7), ca.SX.eye(nw)))
    Bc = ca.vertcat(B[:7, :], ca.SX(ca.DM(np.diag(mom_gain))))
    PA = ca.mtimes(P, Ac)
    PB = ca.mtimes(P, Bc)
    BPA = ca.mtimes(Bc.T, PA)
    Re = ca.diag(r) + ca.mtimes(Bc.T, PB)
    Lit = inv_lower(chol_lower(Re)).T
    M = ca.mtimes(Lit.T, BPA)           # L⁻¹BᵀPA: K = -L⁻ᵀM
    K = -ca.mtimes(Lit, M)
    Pk = _symmetric(Q, Ac, PA, M)
    Ks = ca.SX.sym("K", nu, nx)
    Acls = ca.SX.sym("Acl", 7, nx)
    Lits = ca.SX.sym("Lit", nu, nu)
    S = ca.SX.sym("S", nx, nu)
    S0 = ca.densify(ca.mtimes(B, Lits))
    KS = ca.mtimes(Ks, S)
    S1 = ca.vertcat(ca.mtimes(Acls, S),
                    S[7:, :] + ca.mtimes(ca.diag(ca.DM(mom_gain)),
                                         KS[:nx - 7, :]))

    def block(top, Sn):
        return ca.densify(ca.vertcat(top, Sn[7:, :],
                                     *([Sn[4:7, :]] if rate_rows else [])))

    # W⁻¹ y and W⁻ᵀ g without W⁻¹: the closed loop forward, its adjoint
    # backward (one stage each)
    yk, dx = ca.SX.sym("y", nu), ca.SX.sym("dx", nx)
    gk, mu = ca.SX.sym("g", nu), ca.SX.sym("mu", nx)
    du = ca.mtimes(Lits, yk) + ca.mtimes(Ks, dx)

    def adj(g, m):
        gt = g + ca.mtimes(B.T, m)
        return [ca.mtimes(Lits.T, gt),
                ca.mtimes(Ks.T, gt) + ca.mtimes(A.T, m)]

    # a stage's multipliers of the QP's rows (`factor_rows`' order): the
    # bounds' enter as g, the momentum and rate rows' at δx_{k+1}
    h = nu + nw + (3 if rate_rows else 0)
    Lk = ca.SX.sym("L", h)
    c = ca.vertcat(ca.SX.zeros(4), Lk[nu + nw:] if rate_rows
                   else ca.SX.zeros(3), Lk[nu:nu + nw])
    return {
        "ric": ca.Function("ric_step", [pl, Q, A, B, r],
                           [lower_nz(Pk), ca.densify(K), ca.densify(Lit)]),
        "tril": ca.Function("ric_last", [Q], [lower_nz(ca.densify(Q))]),
        "init": ca.Function("ric_init", [A, B, Ks, Lits],
                            [S0, block(Lits, S0), ca.densify(
                                (A + ca.mtimes(B, Ks))[:7, :])]),
        "sweep": ca.Function("ric_sweep", [Ks, Acls, S],
                             [S1, block(KS, S1)]),
        "roll": ca.Function("ric_roll", [A, B, Ks, Lits, yk, dx],
                            [du, ca.mtimes(A, dx) + ca.mtimes(B, du)]),
        "adj": ca.Function("ric_adj", [A, B, Ks, Lits, gk, mu], adj(gk, mu)),
        "adj_rows": ca.Function("ric_adj_rows", [A, B, Ks, Lits, Lk, mu],
                                adj(Lk[:nu], mu + c)),
    }


def closed_loop(kern: dict, A: list, B: list, K: list, Lit: list, y
                ) -> tuple[ca.MX, list]:
    """``(δu, δx)``: ``δu = W⁻¹ y`` (N·n_u,) and the states δx_1…δx_N
    (n_x, each) it makes from δx_0 = 0, in O(N) (no W⁻¹)."""
    nx, nu = B[0].shape
    dx = ca.MX.zeros(nx)
    du, xs = [], []
    for k in range(len(A)):
        duk, dx = kern["roll"](A[k], B[k], K[k], Lit[k],
                               y[k * nu:(k + 1) * nu], dx)
        du.append(duk)
        xs.append(dx)
    return ca.vertcat(*du), xs


def row_adjoint(kern: dict, A: list, B: list, K: list, Lit: list, L
                ) -> ca.MX:
    """``Gᵀλ`` (N·n_u,): the gradient in y of the QP's rows weighted by
    their multipliers ``L`` (`factor_rows`' order, a stage's h rows
    each), by the closed loop's adjoint in O(N): the bounds' multipliers
    enter as the gradient in δu, the momentum and rate rows' at their
    state δx_{k+1}.
    """
    nx = B[0].shape[0]
    N = len(A)
    h = L.numel() // N
    mu = ca.MX.zeros(nx)
    out: list[Any] = [None] * N
    for k in range(N - 1, -1, -1):
        out[k], mu = kern["adj_rows"](A[k], B[k], K[k], Lit[k],
                                      L[k * h:(k + 1) * h], mu)
    return ca.vertcat(*out)


def factor_rows(kern: dict, A: list, B: list, K: list, Lit: list,
                rate_rows: bool) -> tuple[ca.MX, ca.MX]:
    """``(W⁻¹, G)`` of the condensed QP in ``y``, from the factors
    (`ocp.mpc.condensed_sweeps.linearise`).

    δu = W⁻¹ y; ``G`` holds the QP's rows as functions of y, stage by
    stage: for k = 0…N−1, the bounds' rows of δu_k (those of W⁻¹), the
    momentum deviations of δx_{k+1} and, with ``rate_rows``, its rate
    deviations (`condensed_qp.RowLayout`). Both lower block triangular,
    with N·n_u columns; a stage's rows against a column block are one
    block, written at once, and W⁻¹ is copied from G column by column
    (strided copies in C, no index arrays).
    """
    N = len(B)
    nx, nu = B[0].shape
    h = nu + nx - 7 + (3 if rate_rows else 0)
    blocks = [[ca.MX(h, nu)] * N for _ in range(N)]
    first = [kern["init"](A[j], B[j], K[j], Lit[j]) for j in range(N)]
    for j in range(N):
        # δx_{j+1} per unit y_j, then along the closed loop
        S, blocks[j][j], _ = first[j]
        for k in range(j + 1, N):
            S, blocks[k][j] = kern["sweep"](K[k], first[k][2], S)
    G = _lower_blocks([(blocks, h)], nu)
    return _bound_rows(G, N, h, nu), G


def _bound_rows(G: ca.MX, N: int, h: int, nu: int) -> ca.MX:
    """W⁻¹ from G (`factor_rows`): the first n_u of each stage's h rows,
    one strided copy per column."""
    colind = G.sparsity().colind()
    sp = ca.kron(ca.DM(ca.Sparsity.lower(N), 1.0),
                 ca.DM.ones(nu, nu)).sparsity()
    W = ca.MX(sp)
    for c in range(N * nu):
        src = [colind[c] + k * h + i for k in range(N - c // nu)
               for i in range(nu)]
        W.nz[sp.colind()[c]:sp.colind()[c + 1]] = G.nz[src]
    return W


def _lower_blocks(grids: list, w: int) -> ca.MX:
    """Stack the lower block-triangular matrices of ``grid[k][j]`` (k ≥
    j, blocks h × w) of each ``(grid, h)`` of ``grids``.

    Written block by block into one matrix (in-place copies in generated
    C); MX concatenation would go through transposes there.
    """
    N = len(grids[0][0])
    sp = ca.vertcat(*[ca.kron(ca.DM(ca.Sparsity.lower(N), 1.0),
                              ca.DM.ones(h, w)) for _, h in grids])
    M = ca.MX(sp.sparsity())
    top = 0
    for grid, h in grids:
        for j in range(N):
            for k in range(j, N):
                M[top + k * h:top + (k + 1) * h,
                  j * w:(j + 1) * w] = grid[k][j]
        top += N * h
    return M
