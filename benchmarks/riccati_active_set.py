"""A primal active set on the stage-wise QP, its working set eliminated in
the Riccati recursion: the numpy twin of a flight solver to come.

The QP is the condensed step's, kept stage by stage (`ocp.mpc.stagewise`'s
``stagewise_qp_function``): in the deviations δu_k (k = 0…N−1) and δx_k
(k = 1…N) from the plan,

    min Σ_k ½δx_{k+1}ᵀQ_kδx_{k+1} + q_kᵀδx_{k+1} + ½δu_kᵀRδu_k + g_kᵀδu_k
    s.t. δx_{k+1} = A_kδx_k + B_kδu_k + d_k,  δx_0 = 0,
         lo_k ≤ E_u δu_k + E_x δx_{k+1} ≤ hi_k   (torque, momentum, rate
         boxes, scaled by their widths).

The textbook primal active set (Nocedal & Wright, Numerical Optimization,
2nd ed., algorithm 16.3) walks from a feasible start through working
sets; here each working set's equality QP is solved by one backward
Riccati recursion in which a stage's working boxes are equality rows on
(δx_k, δu_k), eliminated through δu_k where they constrain it, and the
rest passed back as rows on δx_k (the constraint-to-go of Laine & Tomlin,
"Efficient computation of feedback control for equality-constrained
LQR", ICRA 2019). The multipliers follow in one forward sweep. A box that
joins or leaves at stage k changes stages 0…k of the recursion only.

No Gram matrix of the working set is formed: a warm working set of 70
momentum rows costs one recursion, as an empty one does, and memory is
O(N) (what `memory_reals` counts). This twin is dense per stage (n_x × n_x
blocks) and counts what the C solver will do: recursions, the stages
they refactor, iterations. No flight code is built on it yet.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: A stage's rows on δu_k whose singular value is below this (relative
#: to the largest row norm) constrain no input: they pass back.
RANK_TOL = 1e-9
#: A passed-back row whose norm is below this (relative to its norm
#: before the stage) depends on the rows before it.
DEP_TOL = 1e-9


@dataclass(frozen=True)
class StageQP:
    """One stage-wise QP (N stages, n_x states, n_u inputs, n_b boxes).

    A (N, n_x, n_x), B (N, n_x, n_u), d (N, n_x): the dynamics; Q (N,
    n_x, n_x), q (N, n_x): the cost of δx_{k+1}; R (n_u,): the diagonal
    input weight, g (N, n_u); Eu (n_b, n_u), Ex (n_b, n_x): the boxes'
    rows (each one entry, 1/width); lo, hi (N, n_b); fixed (n_u,) bool:
    inputs held at ``u0`` (a failed wheel); u0 (N, n_u), x0 (N, n_x): the
    dynamics-feasible start (δx_1…δx_N)."""

    A: np.ndarray
    B: np.ndarray
    d: np.ndarray
    Q: np.ndarray
    q: np.ndarray
    R: np.ndarray
    g: np.ndarray
    Eu: np.ndarray
    Ex: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    fixed: np.ndarray
    u0: np.ndarray
    x0: np.ndarray

    @property
    def dims(self) -> tuple[int, int, int, int]:
        """``(N, n_x, n_u, n_b)``."""
        N, nx, nu = self.B.shape
        return N, nx, nu, self.Eu.shape[0]

    def values(self, U: np.ndarray, X: np.ndarray) -> np.ndarray:
        """The boxes' values (N, n_b) at δu (N, n_u), δx_1…δx_N (N, n_x)."""
        return U @ self.Eu.T + X @ self.Ex.T

    def rollout(self, U: np.ndarray) -> np.ndarray:
        """δx_1…δx_N (N, n_x) of the inputs U (N, n_u)."""
        X = np.zeros((U.shape[0], self.A.shape[1]))
        x = np.zeros(self.A.shape[1])
        for k in range(U.shape[0]):
            x = self.A[k] @ x + self.B[k] @ U[k] + self.d[k]
            X[k] = x
        return X


@dataclass
class _Stage:
    """What the recursion keeps of stage k: what it took from stage k + 1
    (the cost-to-go at δx_{k+1}, its stage cost in, and the rows passed
    back to δx_{k+1}), the input law δu_k = K δx_k + k, the rows' SVD on
    δu_k for the multipliers, and what it hands to stage k − 1."""

    P_in: np.ndarray
    p_in: np.ndarray
    H_in: np.ndarray
    K: np.ndarray
    k: np.ndarray
    Q: np.ndarray            # the kept rows: C_u[acc] = RᵀQᵀ (`_split`)
    R: np.ndarray
    acc: list[int]
    dep: list[int]           # the others: C_u[dep] = beta C_u[acc]
    beta: np.ndarray
    M: np.ndarray            # H_out = M (their parts on δx_k)
    n_own: int               # fixed inputs and working boxes (first rows)
    P_out: np.ndarray
    p_out: np.ndarray
    H_out: np.ndarray
    h_out: np.ndarray


class Dependent(Exception):
    """The working set's rows are linearly dependent (a row passed back
    to δx_0, which is fixed, or one that vanishes)."""


def _rows(qp: StageQP, k: int, W: dict[tuple[int, int], int],
          H: np.ndarray, h: np.ndarray) -> tuple:
    """Stage k's equality rows on (δx_k, δu_k): its fixed inputs, its
    working boxes at their bound (in box order), then the rows passed
    back to δx_{k+1} (``H δx_{k+1} = h``), each through the dynamics.
    Returns ``(Cx, Cu, c)``."""
    N, nx, nu, nb = qp.dims
    Cx, Cu, c = [], [], []
    for i in np.flatnonzero(qp.fixed):
        Cx.append(np.zeros(nx))
        Cu.append(np.eye(nu)[i])
        c.append(qp.u0[k, i])
    for b in sorted(b for (s, b) in W if s == k):
        bound = qp.hi[k, b] if W[(k, b)] > 0 else qp.lo[k, b]
        Cx.append(qp.Ex[b] @ qp.A[k])
        Cu.append(qp.Eu[b] + qp.Ex[b] @ qp.B[k])
        c.append(bound - qp.Ex[b] @ qp.d[k])
    for j in range(H.shape[0]):
        Cx.append(H[j] @ qp.A[k])
        Cu.append(H[j] @ qp.B[k])
        c.append(h[j] - H[j] @ qp.d[k])
    if not c:
        return np.zeros((0, nx)), np.zeros((0, nu)), np.zeros(0)
    return np.array(Cx), np.array(Cu), np.array(c)


def _split(Cu: np.ndarray) -> tuple:
    """The rows of C_u (r × n_u) in order by modified Gram–Schmidt: a row
    whose part normal to the rows kept before it is above `RANK_TOL` of
    its norm (or of 1) is kept, the others are combinations of the kept
    ones. Returns ``(acc, Q, R, dep, beta)``: the kept rows' indices, an
    orthonormal basis Q (n_u × ρ) of their span with C_u[acc] = RᵀQᵀ (R
    upper triangular), the other rows' indices and their coefficients:
    C_u[dep] = beta C_u[acc]."""
    nu = Cu.shape[1]
    acc, dep, cols, coef = [], [], [], []
    Q = np.zeros((nu, 0))
    for i, row in enumerate(Cu):
        a = Q.T @ row
        res = row - Q @ a
        norm = float(np.linalg.norm(res))
        if len(acc) < nu and norm > RANK_TOL * max(1.0, np.linalg.norm(row)):
            acc.append(i)
            cols.append(np.r_[a, norm])
            Q = np.column_stack([Q, res / norm])
        else:
            dep.append(i)
            coef.append(a)
    rho = len(acc)
    R = np.zeros((rho, rho))
    for j, col in enumerate(cols):
        R[:j + 1, j] = col
    # C_u[i] = Q a = C_u[acc]ᵀ (R⁻¹ a) for a dependent row, on the rows
    # kept before it (R's leading block)
    beta = np.zeros((len(dep), rho))
    for i, a in enumerate(coef):
        beta[i, :a.size] = np.linalg.solve(R[:a.size, :a.size], a)
    return acc, Q, R, dep, beta


def _complement(Q: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the complement of Q's columns (n × ρ,
    orthonormal): the unit vectors in order, Gram–Schmidt against Q."""
    n = Q.shape[0]
    for e in np.eye(n):
        if Q.shape[1] == n:
            break
        res = e - Q @ (Q.T @ e)
        norm = float(np.linalg.norm(res))
        if norm > 0.5:              # some unit vector leaves ≥ 1/√n
            Q = np.column_stack([Q, res / norm])
    return Q


def _stage(qp: StageQP, k: int, W: dict[tuple[int, int], int],
           P: np.ndarray, p: np.ndarray, H: np.ndarray, h: np.ndarray
           ) -> _Stage:
    """One step of the recursion, from stage k + 1's cost-to-go and rows."""
    nx = qp.B.shape[1]
    A, B, d = qp.A[k], qp.B[k], qp.d[k]
    Cx, Cu, c = _rows(qp, k, W, H, h)
    acc, Qa, Ra, dep, beta = _split(Cu)
    # on the kept rows Rᵀ Qᵀ δu = c − Cx δx: δu = Fx δx + f0 + V2 w
    Fx = -Qa @ np.linalg.solve(Ra.T, Cx[acc]) if acc else \
        np.zeros((Qa.shape[0], nx))
    f0 = Qa @ np.linalg.solve(Ra.T, c[acc]) if acc else np.zeros(Qa.shape[0])
    V2 = _complement(Qa)[:, len(acc):]
    R = np.diag(qp.R)
    Muu, Mux = R + B.T @ P @ B, B.T @ P @ A
    mu = qp.g[k] + B.T @ (P @ d + p)
    K, kk = Fx, f0
    if V2.shape[1]:
        red = V2.T @ Muu @ V2
        K = Fx - V2 @ np.linalg.solve(red, V2.T @ (Muu @ Fx + Mux))
        kk = f0 - V2 @ np.linalg.solve(red, V2.T @ (Muu @ f0 + mu))
    Acl = A + B @ K
    P_out = Acl.T @ P @ Acl + K.T @ R @ K
    p_out = Acl.T @ (P @ (B @ kk + d) + p) + K.T @ (R @ kk + qp.g[k])
    if k > 0:
        P_out, p_out = P_out + qp.Q[k - 1], p_out + qp.q[k - 1]
    # the other rows less their kept parts are rows on δx_k alone, passed
    # back made orthonormal (Gram–Schmidt in order: H_out = M Hb)
    Hb = Cx[dep] - beta @ Cx[acc]
    hb = c[dep] - beta @ c[acc]
    M = np.zeros((len(dep), len(dep)))
    H_out = np.zeros((len(dep), nx))
    for i in range(len(dep)):
        a = H_out[:i] @ Hb[i]
        res = Hb[i] - a @ H_out[:i]
        norm = float(np.linalg.norm(res))
        if k == 0 or norm <= DEP_TOL * max(1.0, np.abs(Cx[dep[i]]).max()):
            raise Dependent(k)       # on δx_0 (fixed), or on rows before
        M[i, i] = 1.0 / norm
        M[i, :i] = -(a @ M[:i, :i]) / norm
        H_out[i] = res / norm
    return _Stage(P_in=P, p_in=p, H_in=H, K=K, k=kk, Q=Qa, R=Ra, acc=acc,
                  dep=dep, beta=beta, M=M, n_own=c.size - H.shape[0],
                  P_out=P_out, p_out=p_out, H_out=H_out, h_out=M @ hb)


def factor(qp: StageQP, W: dict[tuple[int, int], int],
           stages: list[_Stage] | None = None, top: int | None = None
           ) -> list[_Stage]:
    """The backward recursion of the working set ``W`` ({(stage, box):
    side ±1}). With a previous recursion's ``stages`` and ``top``, only
    stages ``top``…0 are factored again (a change at stage ``top`` moves
    those alone). Raises `Dependent` where the rows are dependent."""
    N, nx = qp.dims[:2]
    out = list(stages) if stages is not None and top is not None else \
        [None] * N
    start = N - 1 if stages is None or top is None else top
    if start == N - 1:
        P, p, H, h = qp.Q[N - 1], qp.q[N - 1], np.zeros((0, nx)), np.zeros(0)
    else:
        nxt = out[start + 1]
        P, p, H, h = nxt.P_out, nxt.p_out, nxt.H_out, nxt.h_out
    for k in range(start, -1, -1):
        st = _stage(qp, k, W, P, p, H, h)
        out[k] = st
        P, p, H, h = st.P_out, st.p_out, st.H_out, st.h_out
    return out  # type: ignore[return-value]


def forward(qp: StageQP, stages: list[_Stage]) -> tuple:
    """``(U, X)``: the working set's optimum, δx_0 = 0 rolled forward."""
    N, nx, nu, _ = qp.dims
    U, X = np.zeros((N, nu)), np.zeros((N, nx))
    x = np.zeros(nx)
    for k, st in enumerate(stages):
        U[k] = st.K @ x + st.k
        x = qp.A[k] @ x + qp.B[k] @ U[k] + qp.d[k]
        X[k] = x
    return U, X


def multipliers(qp: StageQP, stages: list[_Stage], W: dict, U: np.ndarray,
                X: np.ndarray) -> dict[tuple[int, int], float]:
    """The working boxes' multipliers at the working set's optimum (U, X)
    (positive at an upper bound), in one forward sweep: at stage k the
    rows' multipliers ν solve C_uᵀν = −(Rδu_k + g_k + B_kᵀλ_{k+1}), λ the
    costate, up to the rows passed back to δx_k, whose multipliers stage
    k − 1 fixed."""
    n_fixed = int(np.count_nonzero(qp.fixed))
    out: dict[tuple[int, int], float] = {}
    eta = np.zeros(0)
    for k, st in enumerate(stages):
        rho = qp.R * U[k] + qp.g[k] + qp.B[k].T @ (st.P_in @ X[k] + st.p_in)
        nu_ = np.zeros(st.n_own + st.H_in.shape[0])
        nu_[st.dep] = st.M.T @ eta
        nu_[st.acc] = np.linalg.solve(st.R, st.Q.T @ -rho) - \
            st.beta.T @ nu_[st.dep]
        for i, b in enumerate(sorted(b for (s, b) in W if s == k)):
            out[(k, b)] = float(nu_[n_fixed + i])
        eta = nu_[st.n_own:]
    return out


def _step_size(qp: StageQP, V: np.ndarray, dV: np.ndarray, W: dict
               ) -> tuple[float, tuple[int, int] | None, int]:
    """The ratio test: the largest α ≤ 1 keeping every box outside W from
    the values V (N, n_b) along dV, and the box that blocks it."""
    alpha, block, side = 1.0, None, 0
    scale = max(float(np.abs(dV).max()), 1e-300)
    for (k, b) in zip(*np.nonzero(np.abs(dV) > 1e-9 * scale)):
        if (k, b) in W:
            continue
        v = dV[k, b]
        room = ((qp.hi[k, b] if v > 0 else qp.lo[k, b]) - V[k, b]) / v
        if room < alpha:
            alpha, block, side = max(room, 0.0), (int(k), int(b)), \
                1 if v > 0 else -1
    return alpha, block, side


def solve(qp: StageQP, working: dict[tuple[int, int], int] | None = None,
          max_iter: int = 1000, tol: float = 1e-10) -> dict:
    """The QP from its start (``qp.u0``, ``qp.x0``: it must keep every
    box) and the warm boxes ``working`` ({(stage, box): side}; those not
    at their bound at the start, or dependent on those before them in
    stage order, are left out).

    Each iteration solves the working set's equality QP by one recursion
    (`factor`, from the stage the last change was made at) and a forward
    sweep; a step to it blocked by a box adds the box, a step below
    ``tol`` (in box widths) takes the multipliers (`multipliers`) and
    drops the most wrong-signed. Every iterate keeps the boxes, so a
    solve stopped at ``max_iter`` is a feasible point of lower cost.
    Returns ``U``, ``X``, ``optimal``, ``iterations``, the last
    ``working`` set, its multipliers ``lam`` (zero unless optimal),
    ``factored`` (stages refactored, all recursions), ``dependent``
    (boxes left out of a working set as dependent) and ``passed_back``
    (the most rows any recursion passed back to one stage's δx_k).
    """
    N = qp.dims[0]
    U, X = qp.u0.copy(), qp.x0.copy()
    V = qp.values(U, X)
    W: dict[tuple[int, int], int] = {}
    dependent, parked = 0, set()
    for key in sorted(working or {}, key=lambda kb: (kb[0], kb[1])):
        s = working[key]                      # type: ignore[index]
        bound = qp.hi[key] if s > 0 else qp.lo[key]
        if abs(V[key] - bound) > 1e-9 * (1 + abs(bound)):
            continue
        W[key] = s
    factored = N
    try:
        stages = factor(qp, W)
    except Dependent:
        # a dependent warm set is left out whole (one recursion more, where
        # trying its boxes one at a time cost one each: 2.8 M instructions
        # for a step at N = 8 on the M7, capped at 8, over 200 loops)
        W, stages = {}, factor(qp, {})
        dependent += 1
        factored += N
    back = 0
    for it in range(1, max_iter + 1):
        back = max(back, max(st.H_out.shape[0] for st in stages))
        Us, Xs = forward(qp, stages)
        dU, dX = Us - U, Xs - X
        dV = qp.values(dU, dX)
        if np.max(np.abs(dV), initial=0.0) <= tol * (1 + np.max(np.abs(V))):
            lam = multipliers(qp, stages, W, Us, Xs)
            wrong = {key: -lam[key] * s for key, s in W.items()}
            worst = max(wrong, key=wrong.get) if wrong else None
            if worst is None or wrong[worst] <= tol * (1 + max(
                    abs(v) for v in lam.values())):
                return {"U": Us, "X": Xs, "optimal": True, "iterations": it,
                        "working": W, "lam": lam, "factored": factored,
                        "dependent": dependent, "passed_back": back}
            del W[worst]
            parked.clear()
            stages = factor(qp, W, stages, worst[0])
            factored += worst[0] + 1
            continue
        alpha, block, side = _step_size(qp, V, dV, {**W, **dict.fromkeys(
            parked, 0)})
        U, X, V = U + alpha * dU, X + alpha * dX, V + alpha * dV
        if block is None:
            continue
        try:
            stages = factor(qp, {**W, block: side}, stages, block[0])
            W[block] = side
        except Dependent:
            # at its bound already, held there by the set: out of the
            # ratio test until a box leaves
            dependent += 1
            parked.add(block)
        factored += block[0] + 1
    return {"U": U, "X": X, "optimal": False, "iterations": max_iter,
            "working": W, "lam": {}, "factored": factored,
            "dependent": dependent, "passed_back": back}


def stage_qp_function(mpc) -> Callable[[np.ndarray, np.ndarray], StageQP]:
    """``(z, p) -> StageQP``: the stage-wise QP that ``mpc`` (an
    `AttitudeMPC`) poses at the plan z (x_0 the measured state) with the
    parameters ``p = (x, q_f, τ)`` (`ocp.mpc.stagewise`'s
    ``stagewise_qp_function``, its matrices made dense)."""
    from ocp.mpc.condensed import _kernels
    from ocp.mpc.keepout import planning_cone_function
    from ocp.mpc.stagewise import _nz_kernels, box_layout, \
        stagewise_qp_function

    nx, nu = mpc.model.nx, mpc.model.nu
    _, _, sp_a, sp_b, sp_q = _nz_kernels(_kernels(mpc), nx, nu,
                                         planning_cone_function(mpc))
    lay = box_layout(mpc)
    f = stagewise_qp_function(mpc)
    lo_u, hi_u = mpc.model.control_bounds()
    fixed = ~(np.asarray(hi_u) > np.asarray(lo_u))
    Eu, Ex = (np.array(ca_dense(M)) for M in (lay.Eu, lay.Ex))

    def dense(nz: np.ndarray, sp) -> np.ndarray:
        out = np.zeros((nz.shape[1], *sp.shape))
        rows, cols = sp.get_triplet()
        out[:, rows, cols] = nz.T
        return out

    def pose(z: np.ndarray, p: np.ndarray) -> StageQP:
        dU0, dX0, A, B, Q, q, g, r, lo, hi = (np.array(v) for v in f(z, p))
        A, B, Q = dense(A, sp_a), dense(B, sp_b), dense(Q, sp_q)
        U0, X0 = dU0.T, dX0.T
        prev = np.vstack([np.zeros((1, X0.shape[1])), X0[:-1]])
        d = X0 - np.einsum("kij,kj->ki", A, prev) - np.einsum(
            "kij,kj->ki", B, U0)
        return StageQP(A=A, B=B, d=d, Q=Q, q=q.T, R=r[:, 0].copy(), g=g.T,
                       Eu=Eu, Ex=Ex, lo=lo.T, hi=hi.T, fixed=fixed, u0=U0,
                       x0=X0)
    return pose


def ca_dense(M) -> np.ndarray:
    """A CasADi DM as a dense numpy array."""
    import casadi as ca
    return np.array(ca.densify(M))


def dense_qp(qp: StageQP) -> tuple:
    """``(H, f, C, lo, hi)``: the QP in δu alone (N·n_u, stage-major), its
    states eliminated (δx = G δu + c) and its boxes as rows, with the
    fixed inputs as rows lo = hi: for dense reference solvers."""
    N, nx, nu, nb = qp.dims
    n = N * nu
    G, c = np.zeros((N * nx, n)), np.zeros(N * nx)
    Gx, x = np.zeros((nx, n)), np.zeros(nx)
    for k in range(N):
        Gx = qp.A[k] @ Gx
        Gx[:, k * nu:(k + 1) * nu] += qp.B[k]
        x = qp.A[k] @ x + qp.d[k]
        G[k * nx:(k + 1) * nx], c[k * nx:(k + 1) * nx] = Gx, x
    Qb = np.zeros((N * nx, N * nx))
    for k in range(N):
        Qb[k * nx:(k + 1) * nx, k * nx:(k + 1) * nx] = qp.Q[k]
    H = G.T @ Qb @ G + np.diag(np.tile(qp.R, N))
    f = G.T @ (Qb @ c + qp.q.ravel()) + qp.g.ravel()
    Cx = np.kron(np.eye(N), qp.Ex)
    C = np.kron(np.eye(N), qp.Eu) + Cx @ G
    lo, hi = qp.lo.ravel() - Cx @ c, qp.hi.ravel() - Cx @ c
    fix = np.flatnonzero(np.tile(qp.fixed, N))
    C = np.vstack([C, np.eye(n)[fix]])
    u = qp.u0.ravel()[fix]
    return H, f, C, np.r_[lo, u], np.r_[hi, u]
