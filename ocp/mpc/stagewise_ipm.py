"""A Riccati interior point for the MPC's stage-wise QP (loops over stages).

The QP of one SQP iteration of `ocp.mpc.stagewise`, in the deviations
δu_k (k = 0…N−1) and δx_k (k = 1…N) from the plan:

.. math::
    \\min\\ Σ_k ½δx_k^TQ_kδx_k + q_k^Tδx_k + ½δu_k^TRδu_k + g_k^Tδu_k
    \\quad δx_{k+1} = A_kδx_k + B_kδu_k + d_k,\\ δx_0 = 0,
    \\quad lo_k ≤ v_k ≤ hi_k,

with ``v_k`` the boxed components of (δu_k, δx_{k+1}) scaled by their
bounds' widths (torque, momentum and rate bounds are boxes). Mehrotra's
predictor–corrector (Nocedal & Wright, *Numerical Optimization*, 2nd
ed., Alg. 16.4) on the slacks and multipliers of the boxes; every
iterate keeps the dynamics exactly, so each Newton system is the LQ
problem of `ocp.mpc.stagewise_kernels`, solved by one Riccati factor
(the predictor) and one more backward sweep (the corrector). Cost and
generated code grow linearly in N: the sweeps are CasADi ``mapaccum`` of
one stage's kernel, and the interior-point iterations are ``if_else``
calls side by side in chunks (`IPM_CHUNK`) so that a converged solve
skips the rest.

The solve stops when its KKT residual (`IPM_TOL`) is met: the dual
residual (the costate's reduced gradient, relative to ``1 + |g|``), the
boxes' primal residual and every complementarity product ``s·λ``. The
first two are linear in the iterate, so a step of length α scales them
by 1 − α: they are computed at the start and carried, and the residual
that the solve returns (its certificate, ``qp_kkt``) is recomputed in
full at the point returned. Exact arithmetic would keep the two equal;
near the end of a solve with state boxes active over many stages (a
rate bound in a cruise), the barrier's curvature λ/s passes 1e12 and
each Riccati step's rounding grows with it, so the residual recomputed
at each iterate can rise while the carried one falls. Once the carried
residual is below `IPM_TRACK`, the solve therefore recomputes it at
every iterate (one costate sweep) and returns the best iterate it saw,
or the polish cascade (`ocp.mpc.stagewise_cascade`) of its last
iterate, whose active set is the clearest, or, only when that and the
best iterate both miss `POLISH_ACCEPT`, of its best iterate.

The Riccati step subtracts ``WᵀW`` (W = L⁻¹Mᵀ, `stagewise_kernels`),
which stays positive semidefinite in rounding: formed as ``MK`` through
Re⁻¹, a curvature of 1e10 on a controllable state left P_k indefinite by
1e2–1e5 and the next stages' factors NaN.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import casadi as ca
import numpy as np

from .stagewise_boxes import BoxLayout, to_boundary, box_kernels
from .stagewise_kernels import (reverse_columns, root_kernel, root_rhs,
                                root_solve, root_terms)
from .stagewise_lq import FactoredLQ
from .stagewise_cascade import (cascade, cascade_function, passing,
                               polish_more)
from .stagewise_polish import POLISH_ACCEPT

#: KKT residual [scaled, 1] at which the interior point stops.
IPM_TOL = 1e-9
#: Interior-point iterations allowed per QP (a multiple of `IPM_CHUNK`).
IPM_MAX_ITER = 40
#: Iterations per chunk of the solve (`ipm_solve`).
IPM_CHUNK = 5
#: Calls per level of a sweep's ``mapaccum`` tower (CasADi's default is
#: 10): at N = 20 one level, whose accumulators no level above copies
#: through; the generated code stays bounded in N.
SWEEP_BASE = 20
#: Entries of the solve's loop state before the iteration count and the
#: residual: the iterate (6 arrays), the carried residuals rd, rp, the best
#: iterate so far (6) and its residual (`ipm_iteration`).
STATE_LEN = 15
#: Carried KKT residual [scaled, 1] below which each iterate's residual is
#: recomputed, for the best iterate (`ipm_iteration`).
IPM_TRACK = 1e-5
#: Fraction of the way to a box's boundary that one step may go.
IPM_TAU = 0.995
#: The initial slacks' floor and barrier parameter [scaled, 1].
IPM_SLACK0, IPM_MU0 = 0.1, 10.0
#: A solve whose certificate ends above this [scaled, 1] resumes (a branch
#: the generated C skips otherwise): up to `IPM_RESUME_ITER` more
#: iterations to ``tol · IPM_RESUME_TOL``, then the polish again. The
#: carried residual can pass ``tol`` while the recomputed one stays near
#: 1e-6 (rounding, on trees with many active boxes). In the robust
#: Monte Carlo with a keep-out cone (200 draws) 3 loops ended on such a
#: refused step without the resume, 1 with it; on the M7 it costs the
#: stage-wise step 94 kB of work and 9.7 kB of flash.
IPM_RESUME, IPM_RESUME_TOL, IPM_RESUME_ITER = 1e-7, 1e-2, 10


class Tree:
    """The shape of the QP: S scenarios of N stages, rooted or not.

    ``S = 1, root = False`` is the nominal MPC (a chain). With ``root``
    the scenarios share their first control: each scenario's first stage
    is an ordinary Riccati step, whose factor and feed-forward give the
    scenario's terms in that control (x_0 is fixed); the root sums them
    and chooses the shared control (`root_factor`), which every first
    stage then applies (`with_root`). Data have S·N columns,
    scenario-major.
    """

    def __init__(self, N: int, S: int = 1, root: bool = False) -> None:
        self.N, self.S, self.root = int(N), int(S), bool(root)
        self.C = self.N * self.S

    def sweep(self, f: ca.Function, name: str, n_acc: int) -> ca.Function:
        """``f`` accumulated over each scenario's N stages, the S mapped."""
        acc = f.mapaccum(name, self.N, n_acc,
                         {"base": min(self.N, SWEEP_BASE)})
        return acc if self.S == 1 else acc.map(self.S)

    def root_factor(self, Lr, kr, nu: int) -> tuple:
        """``(v, Re_s, Lroot)`` from a Riccati sweep's reversed outputs.

        Each scenario's first stage was an unblocked Riccati step: its
        factor and feed-forward give the scenario's terms in the shared
        control (`stagewise_kernels.root_terms`), summed into the root's
        QP, whose solution is v; ``Re_s`` (n_u² × S) and the root's factor
        serve a second right-hand side (`root_again`).
        """
        Lit = ca.reshape(Lr, nu * nu, self.C)[:, self.N - 1::self.N]
        kff = ca.reshape(kr, nu, self.C)[:, self.N - 1::self.N]
        Re_s, rhs_s = root_terms(nu).map(self.S)(Lit, kff)
        v, Lroot = root_kernel(nu)(ca.sum2(Re_s), ca.sum2(rhs_s))
        return v, Re_s, Lroot

    def root_again(self, Re_s, Lroot, kr, nu: int) -> ca.MX:
        """v of another right-hand side (the corrector's feed-forwards)."""
        kff = ca.reshape(kr, nu, self.C)[:, self.N - 1::self.N]
        rhs = ca.sum2(root_rhs(nu).map(self.S)(Re_s, kff))
        return root_solve(nu)(Lroot, rhs)

    def root_mask(self, nu: int) -> np.ndarray:
        """(n_u × C) 1 in the columns of the scenarios' first stages.

        In reversed time (the sweeps' order) a scenario's first stage is
        its last column, ``N - 1`` of each block of N; 0 elsewhere.
        """
        mask = np.zeros((nu, self.C))
        mask[:, self.N - 1::self.N] = 1.0
        return mask

    def with_root(self, kr, v, nu: int) -> ca.MX:
        """The reversed feed-forwards with each first stage's set to v.

        With x_0 fixed a first stage applies its feed-forward: v there
        makes every scenario apply the shared control.
        """
        M = ca.DM(self.root_mask(nu))
        return kr * (1.0 - M) + ca.mtimes(v, ca.DM.ones(1, self.C)) * M

    def root_residual(self, rho_r, nu: int) -> ca.MX:
        """The reduced gradients: the root's the sum of the scenarios'
        first stages', the other stages' their own (reversed, n_u × C)."""
        first = ca.sum2(ca.reshape(rho_r, nu, self.C)[:, self.N - 1::self.N])
        return ca.vertcat(ca.vec(rho_r * ca.DM(1.0 - self.root_mask(nu))),
                          first)


def _sweeps(kern: dict, tree: Tree) -> dict:
    return {"ric": tree.sweep(kern["ric"], "sw_ric_N", 5),
            "vec": tree.sweep(kern["vec"], "sw_vec_N", 2),
            "fwd": tree.sweep(kern["fwd"], "sw_fwd_N", 2),
            "costate": tree.sweep(kern["costate"], "sw_costate_N", 2)}


def ipm_iteration(kern: dict, lay: BoxLayout, tree: Tree, nx: int, nu: int,
                  flags: np.ndarray) -> ca.Function:
    """``sw_ipm_iter(state…, n, kkt, data…) -> (state…, n + 1, kkt)``:
    one Mehrotra step.

    The state is ``(dU (n_u × C), dX (n_x × C), Sl, Su, Ll, Lu (nb × C),
    rd, rp, best…, best_kkt)`` (C = S·N columns, `Tree`; rd, rp the
    carried dual and primal residuals; best the six arrays of the iterate
    whose recomputed residual, best_kkt, is the smallest so far), ``n``
    the iterations made so far and ``kkt`` the last carried residual
    (`ipm_solve`'s loop carries both; it stops on it); the data ``(A, B, Q
    (nonzeros × C), q (n_x × C), g, r (n_u × C), lo, hi (nb × C), Ar, Br,
    Qr, rr)`` (``r`` the diagonal of the control Hessian per stage; the
    last four reversed in time). The ``kkt`` returned is the new point's
    KKT residual (module doc). ``flags`` (C,) are 1 where a stage chooses
    its control and 0 where it holds the one before it (move blocking; a
    tree's root stages).
    """
    nb, C = lay.nb, tree.C
    sym = ca.MX.sym
    dU, dX = sym("dU", nu, C), sym("dX", nx, C)
    Sl, Su, Ll, Lu = (sym(n, nb, C) for n in ("Sl", "Su", "Ll", "Lu"))
    sp = {n: kern["ric"].sparsity_in(i) for n, i in
          (("a", 5), ("b", 6), ("q", 7))}
    A, B, Q = (sym(n, sp[n].nnz(), C) for n in ("a", "b", "q"))
    Ar, Br, Qr = (sym(n + "r", sp[n].nnz(), C) for n in ("a", "b", "q"))
    q, g, r, rr_ = (sym(n, k, C) for n, k in
                    (("q", nx), ("g", nu), ("r", nu), ("rr", nu)))
    lo, hi = sym("lo", nb, C), sym("hi", nb, C)
    rd, rp = sym("rd"), sym("rp")
    best = [sym("b" + v.name(), v.sparsity()) for v in
            (dU, dX, Sl, Su, Ll, Lu)] + [sym("b_kkt")]
    state = [dU, dX, Sl, Su, Ll, Lu, rd, rp, *best]
    count = [sym("n"), sym("kkt")]
    data = [A, B, Q, q, g, r, lo, hi, Ar, Br, Qr, rr_]
    sw = _sweeps(kern, tree)
    m = 2.0 * nb * C

    V = lay.values(dU, dX)
    rpl, rpu = V - lo - Sl, hi - V - Su
    mu = (ca.sum1(ca.sum2(Sl * Ll)) + ca.sum1(ca.sum2(Su * Lu))) / m
    sig = lay.sigma(Ll / Sl + Lu / Su)
    gx = kern["qmul"].map(C)(Q, dX) + q
    gu = r * dU + g

    def sweep_in(beta, gx=gx, gu=gu):
        qt, rt = lay.lift(gx, gu, beta)
        return reverse_columns(qt), reverse_columns(rt)

    def box_steps(dU_, dX_):
        dv = lay.values(dU_, dX_)
        return dv + rpl, rpu - dv

    qr, rrt = sweep_in(Ll * rpl / Sl - Lu * rpu / Su)
    lq = FactoredLQ(sw, lay, tree, (nx, nu), flags, data, sig, qr, rrt)
    dSl_a, dSu_a = box_steps(*lq.first())
    dLl_a = -Ll - Ll * dSl_a / Sl
    dLu_a = -Lu - Lu * dSu_a / Su
    box = {k: f.map(C) for k, f in box_kernels(nb).items()}
    vs = [Sl, Su, Ll, Lu]
    ds_a = [dSl_a, dSu_a, dLl_a, dLu_a]
    a_aff = to_boundary(box["ratio"], vs, ds_a, 1.0)
    mu_aff = ca.sum2(box["mu"](*vs, *ds_a, a_aff)) / m
    smu = (mu_aff / mu) ** 3 * mu
    cl, cu = dSl_a * dLl_a, dSu_a * dLu_a
    beta = (Ll * rpl - smu + cl) / Sl - (Lu * rpu - smu + cu) / Su
    ddU, ddX = lq.solve(*sweep_in(beta))
    dSl, dSu = box_steps(ddU, ddX)
    dLl = -Ll + (smu - cl - Ll * dSl) / Sl
    dLu = -Lu + (smu - cu - Lu * dSu) / Su
    ds = [dSl, dSu, dLl, dLu]
    alpha = to_boundary(box["ratio"], vs, ds, IPM_TAU)
    *boxes, comp = box["step"](*vs, *ds, alpha)
    new = [dU + alpha * ddU, dX + alpha * ddX, *boxes]
    # a QP's stationarity and box residuals are linear in the iterate:
    # a step α scales both by 1 − α (no costate sweep per iteration)
    new += [(1.0 - alpha) * rd, (1.0 - alpha) * rp]
    kkt = ca.fmax(ca.mmax(comp), ca.fmax(new[6], new[7]))
    # a step that leaves the floating-point range (a slack or multiplier
    # driven to 0 or inf at the end of the solve) is not taken: the
    # iterate stays and the solve stops (its residual is recomputed and
    # reported at the point returned)
    total = sum(ca.sum1(ca.sum2(v)) for v in new[:6])
    ok = ca.logic_and(total == total, ca.fabs(total) < 1e300)
    new = [ca.if_else(ok, v, v0) for v, v0 in zip(new, state)]
    kkt = ca.if_else(ok, kkt, 0.0)
    # the carried residuals stop the solve; the iterate returned is the
    # one whose recomputed residual is the smallest: near the end a
    # barrier curvature λ/s past 1e12 makes each Riccati step's rounding
    # grow, and on the rate-bounded trees the recomputed residual rose
    # from 1e-7 to 1e-5–1e-3 in the last steps while the carried one fell.
    # Recomputed (one costate sweep) only once the carried residual is
    # below IPM_TRACK: the generated C skips it before
    track = _tracker(kern, lay, tree, (nx, nu), flags, state[8:], data)
    new += list(track(kkt < IPM_TRACK, *new[:6], *best, *data))
    return ca.Function("sw_ipm_iter", state + count + data,
                       new + [count[0] + 1, kkt])


def _tracker(kern: dict, lay: BoxLayout, tree: Tree, dims: tuple,
             flags: np.ndarray, best: list, data: list) -> ca.Function:
    """``track(c, point…, best…, best_kkt, data…) -> (best…, best_kkt)``:
    when ``c``, the point if its recomputed residual is below
    ``best_kkt``; otherwise (and when ``c`` is false) the best unchanged.
    """
    sym = ca.MX.sym
    point = [sym(v.name()[1:], v.sparsity()) for v in best[:6]]
    b = [sym(v.name(), v.sparsity()) for v in best]
    d = [sym(v.name(), v.sparsity()) for v in data]
    true = point_residual(kern, lay, tree, dims, point, d, ca.DM(flags[::-1]).T)
    better = true < b[6]
    run = ca.Function("sw_ipm_track", point + b + d,
                      [ca.if_else(better, v, w) for v, w in
                       zip(point + [true], b)])
    keep = passing("sw_ipm_keep", point + b + d, lambda a: a[6:13])
    return ca.Function.if_else("sw_ipm_best", run, keep)


def kkt_residual(kern: dict, lay: BoxLayout, tree: Tree, dims: tuple,
                 state, data, flags_r) -> tuple[ca.MX, ...]:
    """The KKT residual of an iterate (module doc): its dual, primal and
    complementarity parts, scaled, ≥ 0; then how far it breaks its worst
    box (≥ 0) and the sum of its entries (NaN or infinite with them).

    ``dims`` is ``(n_x, n_u)``, ``flags_r`` the flags reversed in time (a
    held control's gradient joins its block's, the root's sums the
    scenarios').
    """
    nx, nu = dims
    dU, dX, Sl, Su, Ll, Lu = state
    A, B, Q, q, g, r, lo, hi, Ar, Br, Qr, _ = data
    lam = Lu - Ll
    gx, gu = lay.lift(kern["qmul"].map(tree.C)(Q, dX) + q, r * dU + g, lam)
    _, racc, rho = _sweeps(kern, tree)["costate"](
        ca.DM.zeros(nx), ca.DM.zeros(nu), Ar, Br, reverse_columns(gx),
        reverse_columns(gu), flags_r)
    if tree.root:
        rho = tree.root_residual(rho, nu)
    return residual_parts(lay, rho, state, lo, hi, q, g)


def residual_parts(lay: BoxLayout, rho, state, lo, hi, q,
                   g) -> tuple[ca.MX, ...]:
    """`kkt_residual`'s parts from the inputs' reduced gradient ``rho``
    (the costate sweep's, n_u × C) and the iterate ``state``: the dual
    residual max |rho| relative to 1 + max |q|, |g|, then the boxes'
    primal residual, complementarity, violation and the entries' sum."""
    rows = lay.residual_rows(list(state), lo, hi, q, g)
    primal, comp, brk, scale = (ca.mmax(rows[i, :]) for i in (0, 1, 2, 4))
    dual = ca.mmax(ca.fabs(rho)) / (1.0 + scale)
    return dual, primal, comp, brk, ca.sum2(rows[3, :])


def combined_residual(dual, primal, comp, brk, total) -> ca.MX:
    """One certificate of `kkt_residual`'s parts: their largest, +inf
    where ``total`` (the point's entries' sum) is NaN or infinite (the
    maxima skip NaNs)."""
    res = ca.fmax(ca.fmax(dual, brk), ca.fmax(primal, comp))
    finite = ca.logic_and(total == total, ca.fabs(total) < ca.inf)
    return ca.if_else(finite, res, ca.inf)


def point_residual(kern: dict, lay: BoxLayout, tree: Tree, dims: tuple,
                   point: list, data: list, flags_r) -> ca.MX:
    """The KKT residual of a point, boxes broken included (scaled); +inf
    for a point with a NaN or an infinity (the maxima skip NaNs)."""
    return combined_residual(*kkt_residual(kern, lay, tree, dims, point,
                                           data, flags_r))


def ipm_solve(kern: dict, lay: BoxLayout, tree: Tree, nx: int, nu: int,
              max_iter: int = IPM_MAX_ITER, tol: float = IPM_TOL,
              flags: np.ndarray | None = None) -> ca.Function:
    """``sw_ipm(dU0, dX0, A, B, Q, q, g, r, lo, hi) -> (dU, dX, lam, n, kkt)``.

    Solves the QP (module doc) of the `Tree` from the dynamics-feasible
    point ``(dU0, dX0)``; ``lam`` (nb × C) are the boxes' multipliers
    ``λ_u − λ_l`` in scaled units, ``n`` the iterations made, ``kkt`` the
    residual at the point returned (above ``tol`` when ``max_iter``
    iterations did not reach it). The unconstrained optimum comes first
    (one factor, no barrier): when it keeps every box it is returned, with
    zero multipliers, ``n`` = 0 and its residual, and the interior point
    does not run. ``flags`` (C,): 1 where a stage chooses
    its control, 0 where it holds the one before (move blocking, a tree's
    root stages; default: every stage chooses); the start must hold them.
    """
    flags = np.ones(tree.C) if flags is None else np.asarray(flags, float)
    it = ipm_iteration(kern, lay, tree, nx, nu, flags)
    # fresh symbols: a call on the Function's own inputs would inline it
    args = [ca.MX.sym(it.name_in(i), it.sparsity_in(i))
            for i in range(it.n_in())]
    data = args[STATE_LEN + 2:]
    # a skipped chunk passes its state through
    done = passing("sw_done", args, lambda a: a[:STATE_LEN + 2])
    # chunks of IPM_CHUNK iterations, one after another in the chunk (a
    # converged iterate skips the rest), the chunks one after another,
    # each skipped once converged: every nesting level of Functions
    # reserves its arguments in the work vector, so the calls stay side
    # by side, two levels deep
    depth = min(IPM_CHUNK, max_iter)
    step = ca.Function.if_else("sw_ipm_step", done, it)

    def chunks(tol: float, iters: int, suffix: str = "") -> Callable:
        cur: Any = it(*args)
        for _ in range(depth - 1):
            cur = step(cur[STATE_LEN + 1] <= tol, *cur, *data)
        chunk = ca.Function("sw_ipm_chunk" + suffix, args, cur)
        skip = ca.Function.if_else("sw_ipm_skip" + suffix, done, chunk)

        def loop(*a: Any) -> list:
            # the chunks, called in the caller's own graph (one level less)
            cur, dat = list(a[:STATE_LEN + 2]), a[STATE_LEN + 2:]
            for _ in range(0, iters, depth):
                # the last chunk may run past iters by less than one chunk
                cur = skip(cur[STATE_LEN + 1] <= tol, *cur, *dat)
            return cur
        return loop

    loop = chunks(tol, max_iter)
    resume = chunks(tol * IPM_RESUME_TOL, IPM_RESUME_ITER, "_more")

    sym = ca.MX.sym
    C = tree.C
    dU0, dX0 = sym("dU0", nu, C), sym("dX0", nx, C)
    A, B, Q, q, g, r, lo, hi = (data[i] for i in range(8))
    rev = [reverse_columns(M) for M in (A, B, Q, r)]
    data = [A, B, Q, q, g, r, lo, hi, *rev]
    sr = ca.DM(flags[::-1]).T
    sweeps = _sweeps(kern, tree)
    dims = (nx, nu)
    # the unconstrained optimum first: one factor without barrier, one
    # step from the start (the QP is quadratic); when it keeps every box
    # it is the solution, with zero multipliers, and the interior point
    # is not run (the hold steps of a closed loop)
    zero = ca.DM.zeros(lay.nb, C)
    gx0 = kern["qmul"].map(C)(Q, dX0) + q
    lq = FactoredLQ(sweeps, lay, tree, dims, flags, data, zero,
                    reverse_columns(gx0), reverse_columns(r * dU0 + g))
    ddU, ddX = lq.first()
    dUf, dXf = dU0 + ddU, dX0 + ddX
    Vf = lay.values(dUf, dXf)
    inside = ca.mmax(ca.vertcat(ca.vec(lo - Vf), ca.vec(Vf - hi))) <= 0
    kkt_f = point_residual(kern, lay, tree, dims,
                      [dUf, dXf, Vf - lo, hi - Vf, zero, zero], data, sr)
    # the branches: fresh symbols of (dU0, dX0, data…, dUf, dXf, kkt_f)
    bi = [sym(f"i{k}", v.sparsity()) for k, v in
          enumerate([dU0, dX0, *data, dUf, dXf, kkt_f])]
    interior = ca.Function("sw_ipm_interior", bi, _interior(
        loop, resume, kern, lay, tree, dims, flags, sweeps, sr, bi[0],
        bi[1], bi[2:14]))
    free = passing("sw_ipm_free", bi, lambda a: [
        a[14], a[15], ca.MX.zeros(lay.nb, C), ca.MX(0.0), a[16]])
    branch = ca.Function.if_else("sw_ipm_first", free, interior)
    dU, dX, lam, count, kkt = branch(inside, dU0, dX0, *data, dUf, dXf,
                                     kkt_f)
    names = ["dU0", "dX0", "A", "B", "Q", "q", "g", "r", "lo", "hi"]
    return ca.Function("sw_ipm", [dU0, dX0, *data[:8]],
                       [dU, dX, lam, count, kkt], names,
                       ["dU", "dX", "lam", "iterations", "kkt"])


def _interior(loop: Callable[..., list], resume: Callable[..., list],
              kern: dict, lay: BoxLayout, tree: Tree, dims: tuple,
              flags: np.ndarray, sweeps: dict, sr, dU0, dX0,
              data: list) -> list:
    """``[dU, dX, lam, n, kkt]`` of the interior point from (dU0, dX0)
    and its polish on the active set, the one with the smaller residual
    (`ipm_solve`); a certificate above `IPM_RESUME` resumes the interior
    point (``resume``: the chunks to a tighter tolerance) and polishes
    again (`_resumed`)."""
    nx, nu = dims
    A, B, Q, q, g, r, lo, hi = data[:8]
    V0 = lay.values(dU0, dX0)
    Sl = ca.fmax(V0 - lo, IPM_SLACK0)
    Su = ca.fmax(hi - V0, IPM_SLACK0)
    start = [dU0, dX0, Sl, Su, IPM_MU0 / Sl, IPM_MU0 / Su]
    rd0, rp0, comp0, *_ = kkt_residual(kern, lay, tree, dims, start, data,
                                      sr)
    kkt0 = ca.fmax(ca.fmax(rd0, rp0), comp0)
    out = loop(*start, rd0, rp0, *start, kkt0, 0.0, 1.0, *data)
    # the certificate: the residual recomputed at the point returned, the
    # interior point's best iterate or the polish (from its last iterate,
    # whose active set is the clearest) on the active set, the smaller
    ipm_point, best = list(out[:6]), list(out[8:14])
    res = partial(point_residual, kern, lay, tree, dims, flags_r=sr)
    kkt_last = res(ipm_point, data)
    last = kkt_last <= out[14]
    best = [ca.if_else(last, a, b) for a, b in zip(ipm_point, best)]
    kkt, count = ca.if_else(last, kkt_last, out[14]), out[15]
    more = polish_more(kern, lay, tree, dims, flags, sweeps, res, data)
    pol, kkt_p = cascade(kern, lay, tree, dims, flags, sweeps, res, more,
                         ipm_point, data, kkt)
    # the cascade again from the best iterate, only when it is not the
    # last one and neither it nor the cascade from the last met
    # POLISH_ACCEPT (a branch in C): the last iterate's active set is the
    # clearer, the best's multipliers the more accurate, and either can
    # be the one that succeeds
    again = cascade_function(kern, lay, tree, dims, flags, sweeps, res,
                             more, data)
    *polb, kkt_b = again(ca.logic_and(ca.logic_not(last),
                                      ca.fmin(kkt, kkt_p) > POLISH_ACCEPT),
                         *best, kkt, *data)
    take = kkt_b < kkt_p                      # a NaN kkt_b is not taken
    pol = [ca.if_else(take, a, b) for a, b in zip(polb, pol)]
    kkt_p = ca.if_else(take, kkt_b, kkt_p)
    # the polish is the active set's exact solution: kept unless its
    # residual is worse than both the interior point's and POLISH_ACCEPT
    better = kkt_p <= ca.fmax(kkt, POLISH_ACCEPT)
    point = [ca.if_else(better, a, b) for a, b in zip(pol, best)]
    kkt = ca.fmin(kkt, kkt_p)
    resumed = _resumed(resume, res, again, out, point, data)
    *point, count, kkt = resumed(kkt > IPM_RESUME, *out[:STATE_LEN + 2],
                                 *point, count, kkt, *data)
    dU, dX, _, _, Ll, Lu = point
    return [dU, dX, Lu - Ll, count, kkt]


def _resumed(resume: Callable[..., list], res: Callable, again: ca.Function,
             out: list, point: list, data: list) -> ca.Function:
    """``more(c, state…, point…, n, kkt, data…) -> (point…, n, kkt)``:
    when ``c``, the interior point resumed from its loop state (more
    iterations to a tighter tolerance), its best or last iterate and
    that iterate's polish cascade, whichever has the smallest residual,
    against the given point; otherwise the given point (a branch the
    generated C skips)."""
    sym = ca.MX.sym
    st = [sym(f"s{i}", v.sparsity()) for i, v in enumerate(
        out[:STATE_LEN + 2])]
    pt = [sym(f"p{i}", v.sparsity()) for i, v in enumerate(point)]
    n, k0 = sym("n"), sym("kkt")
    d = [sym(f"d{i}", v.sparsity()) for i, v in enumerate(data)]
    cur = resume(*st[:STATE_LEN], st[STATE_LEN], 1.0, *d)
    last, best = list(cur[:6]), list(cur[8:14])
    kkt_last = res(last, d)
    take_last = kkt_last <= cur[14]
    it_pt = [ca.if_else(take_last, a, b) for a, b in zip(last, best)]
    kkt_it = ca.fmin(kkt_last, cur[14])
    *pol, kkt_p = again(kkt_it > POLISH_ACCEPT, *last, kkt_it, *d)
    use_pol = kkt_p < kkt_it                  # a NaN kkt_p is not taken
    new = [ca.if_else(use_pol, a, b) for a, b in zip(pol, it_pt)]
    kkt_new = ca.if_else(use_pol, kkt_p, kkt_it)
    keep = kkt_new < k0
    args = [*st, *pt, n, k0, *d]
    run = ca.Function("sw_ipm_resumed", args, [
        *[ca.if_else(keep, a, b) for a, b in zip(new, pt)],
        ca.if_else(keep, cur[STATE_LEN], n), ca.fmin(kkt_new, k0)])
    skip = passing("sw_ipm_done", args, lambda a: a[STATE_LEN + 2:
                                                   STATE_LEN + 10])
    return ca.Function.if_else("sw_ipm_more", run, skip)
