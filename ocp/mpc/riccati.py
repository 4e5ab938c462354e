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
                    sp_b: ca.Sparsity, mom_gain) -> dict[str, ca.Function]:
    """SX kernels of the recursion and of the forward sweep.

    ``ric(P, Q, A, B, r) -> (P_k, K, Lit)`` (P, P_k: their lower
    triangles, column by column, `ric_last` of Q_N starts the recursion;
    ``r`` the diagonal of R, ``Lit`` = L⁻ᵀ); ``acl(A, B, K) -> (A +
    BK)[:7]``; ``init(B, Lit) -> B Lit`` and ``sweep(K, Acl[:7], S) ->
    (K S, Acl S)``, each with the momentum and rate rows of its S as
    extra outputs. ``mom_gain`` (n_w,) is Δt·s: the momentum
    rows of the closed loop are ``H_{k+1} = H_k + Δt s (K S)``, which the
    sweep uses instead of the full product.
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
    # W⁻¹ y and W⁻ᵀ g without W⁻¹: the closed loop forward, its adjoint
    # backward (one stage each)
    yk, dx = ca.SX.sym("y", nu), ca.SX.sym("dx", nx)
    gk, mu = ca.SX.sym("g", nu), ca.SX.sym("mu", nx)
    du = ca.mtimes(Lits, yk) + ca.mtimes(Ks, dx)
    gt = gk + ca.mtimes(B.T, mu)
    return {
        "ric": ca.Function("ric_step", [pl, Q, A, B, r],
                           [lower_nz(Pk), ca.densify(K), ca.densify(Lit)]),
        "tril": ca.Function("ric_last", [Q], [lower_nz(ca.densify(Q))]),
        # the closed loop's first 7 rows (the sweeps of W⁻¹ only)
        "acl": ca.Function("ric_acl", [A, B, Ks],
                           [ca.densify((A + ca.mtimes(B, Ks))[:7, :])]),
        # outputs: S, then its momentum and rate rows (no slicing nodes)
        "init": ca.Function("ric_init", [B, Lits],
                            [S0, S0[7:, :], S0[4:7, :]]),
        "sweep": ca.Function("ric_sweep", [Ks, Acls, S],
                             [KS, S1, S1[7:, :], S1[4:7, :]]),
        "roll": ca.Function("ric_roll", [A, B, Ks, Lits, yk, dx],
                            [du, ca.mtimes(A, dx) + ca.mtimes(B, du)]),
        "adj": ca.Function("ric_adj", [A, B, Ks, Lits, gk, mu],
                           [ca.mtimes(Lits.T, gt),
                            ca.mtimes(Ks.T, gt) + ca.mtimes(A.T, mu)]),
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


def adjoint(kern: dict, A: list, B: list, K: list, Lit: list, g,
            c: list | None = None) -> ca.MX:
    """``W⁻ᵀ g`` (N·n_u,) by the closed loop's adjoint, in O(N).

    With ``c`` (n_x each, k = 1…N): the gradient in y of ``gᵀδu +
    Σ c_kᵀδx_k`` along the closed loop (`closed_loop`): a row's
    multipliers injected at its state.
    """
    nx, nu = B[0].shape
    N = len(A)
    mu = ca.MX.zeros(nx)
    out: list[Any] = [None] * N
    for k in range(N - 1, -1, -1):
        if c is not None:
            mu = mu + c[k]
        out[k], mu = kern["adj"](A[k], B[k], K[k], Lit[k],
                                 g[k * nu:(k + 1) * nu], mu)
    return ca.vertcat(*out)


def factor_rows(kern: dict, A: list, B: list, K: list, Lit: list,
                rate_rows: bool) -> tuple[ca.MX, ca.MX]:
    """``(W⁻¹, G)`` of the condensed QP in ``y``, from the factors (`ocp.mpc.condensed_sweeps.linearise`).

    δu = W⁻¹ y; ``G`` stacks W⁻¹ (N·n_u rows, the bounds on δu), the
    momentum deviations of the states k = 1…N (N·n_w rows), then, with
    ``rate_rows``, their rate deviations (3N rows), as functions of y:
    the QP's constraint rows. All lower block triangular, with N·n_u
    columns. The blocks are written into G, and W⁻¹ is G's top rows,
    copied column by column (no index arrays in C).
    """
    N = len(B)
    nx, nu = B[0].shape
    Acl = [kern["acl"](A[k], B[k], K[k]) for k in range(N)]
    # structural zeros above the diagonal: W⁻¹ and the rows are lower
    # block triangular
    winv = [[ca.MX(nu, nu)] * N for _ in range(N)]
    mom = [[ca.MX(nx - 7, nu)] * N for _ in range(N)]
    rate = [[ca.MX(3, nu)] * N for _ in range(N)]
    for j in range(N):
        winv[j][j] = Lit[j]
        # δx_{j+1} per unit y_j, then along the closed loop
        S, mom[j][j], rate[j][j] = kern["init"](B[j], Lit[j])
        for k in range(j + 1, N):
            winv[k][j], S, mom[k][j], rate[k][j] = kern["sweep"](
                K[k], Acl[k], S)
    grids = [(winv, nu), (mom, nx - 7)] + ([(rate, 3)] if rate_rows else [])
    G = _lower_blocks(grids, nu)
    return _top_rows(G, N * nu), G


def _top_rows(M: ca.MX, n: int) -> ca.MX:
    """The first ``n`` rows of a sparse ``M``: one contiguous run of
    nonzeros per column (a slice copy each in C)."""
    sp = M.sparsity()
    top = ca.DM(sp, 1.0)[:n, :].sparsity()
    colind, row = sp.colind(), sp.row()
    out = ca.MX(top)
    for c in range(sp.size2()):
        a, b = top.colind()[c], top.colind()[c + 1]
        if b > a:
            assert all(r < n for r in row[colind[c]:colind[c] + b - a])
            out.nz[a:b] = M.nz[colind[c]:colind[c] + b - a]
    return out


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
