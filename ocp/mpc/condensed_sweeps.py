"""The condensed SQP's passes over the horizon: one kernel call a stage.

`ocp.mpc.condensed` linearises the plan forwards (RK4 Jacobians, the
defects carried along) and then runs three recursions backwards: the
gradient's costate, the Riccati recursion (`ocp.mpc.riccati`) and the
adjoint that forms W⁻ᵀg. Each pass's stage is one SX kernel with its
parts inlined (the same operations as called one by one), so the
generated C makes one call per stage forwards and one backwards where it
made six (flash: each call site costs about 200 bytes on a Cortex-M).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .riccati import lower_symbol, riccati_kernels


def sweep_kernels(mpc: Any, kern: dict) -> dict[str, Any]:
    """The passes' stage kernels, from `condensed._kernels`' and the
    Riccati kernels (``"rk"``, `riccati_kernels`).

    ``fwd(x, u, τ, x₊, e) -> (A, B, e₊)``: the stage's Jacobians and
    ``e₊ = A e + (F(x, u, τ) − x₊)``;
    ``bwd(P, λ, μ, x, q_f, e, A, B, u) -> (P_k, K, Lit, (W⁻ᵀg)_k, μ_k,
    λ_k, g_k)``: the stage's cost Hessian and gradient at x, its gradient
    in δu ``g_k = 2 w_m u / m_max² + Bᵀλ``, the Riccati step (R's
    diagonal ``2 w_m / m_max² + ρ``, a constant), the adjoint
    step and the costate ``λ_k = Q e + q + Aᵀλ``.
    """
    model, wh, w = mpc.model, mpc.wheels, mpc.weights
    nx, nu = model.nx, model.nu
    lin, stage = kern["lin"], kern["stage"]
    rk = riccati_kernels(stage.sparsity_out(0), lin.sparsity_out(1),
                         lin.sparsity_out(2),
                         mpc.dt * np.asarray(wh.scale * wh.active, float),
                         mpc.rate_max is not None)
    x, x1, e = (ca.SX.sym(n, nx) for n in ("x", "x1", "e"))
    u, tau, qf = ca.SX.sym("u", nu), ca.SX.sym("tau", 3), ca.SX.sym("qf", 4)
    F, A, B = lin(x, u, tau)
    fwd = ca.Function("cond_fwd", [x, u, tau, x1, e],
                      [A, B, ca.mtimes(A, e) + (F - x1)])
    pl, _ = lower_symbol("P", nx)
    lam, mu = ca.SX.sym("lam", nx), ca.SX.sym("mu", nx)
    As = ca.SX.sym("A", lin.sparsity_out(1))
    Bs = ca.SX.sym("B", lin.sparsity_out(2))
    m2 = ca.DM(np.asarray(wh.m_max, dtype=float) ** 2)
    r = ca.DM(2.0 * w.torque / m2 + mpc.regularization)
    g = 2.0 * w.torque * u / m2 + ca.mtimes(Bs.T, lam)
    Q, q, _ = stage(x, qf, 1.0, 1.0)
    Pk, K, Lit = rk["ric"](pl, Q, As, Bs, r)
    gy, mu_k = rk["adj"](As, Bs, K, Lit, g, mu)
    lam_k = ca.mtimes(Q, e) + q + ca.mtimes(As.T, lam)
    bwd = ca.Function("cond_bwd", [pl, lam, mu, x, qf, e, As, Bs, u],
                      [Pk, K, Lit, gy, mu_k, lam_k, g])
    return {"fwd": fwd, "bwd": bwd, "rk": rk}


def linearise(mpc: Any, sk: dict, kern: dict, z, qf, tau) -> tuple:
    """The plan's QP in y: ``(A, B, e, K, Lit, W⁻ᵀg, g)``.

    ``A, B, K, Lit`` (k = 0…N−1) are lists of the stages' matrices, ``e``
    (k = 0…N) the defects carried along (δx for δu = 0, e_0 = 0), ``W⁻ᵀg``
    and the gradient ``g`` in δu (N·n_u,) vectors.
    """
    w, N = mpc.weights, mpc.horizon
    nx = mpc.model.nx
    xs, us = mpc._xs, mpc._us
    A, B, e = [], [], [ca.MX.zeros(nx)]
    for k in range(N):
        Ak, Bk, ek = sk["fwd"](z[xs[k]], z[us[k]], tau, z[xs[k + 1]], e[k])
        A.append(Ak)
        B.append(Bk)
        e.append(ek)
    QN, qN, _ = kern["stage"](z[xs[N]], qf, 0.0, w.terminal)
    P = sk["rk"]["tril"](QN)
    lam = ca.mtimes(QN, e[N]) + qN
    mu = ca.MX.zeros(nx)
    K: list[Any] = [None] * N
    Lit: list[Any] = [None] * N
    gy: list[Any] = [None] * N
    g: list[Any] = [None] * N
    # stage 0 has no state cost: its P_0 and λ_0 (which would add it)
    # are not used, and K_0, Lit_0, (W⁻ᵀg)_0 do not depend on it
    for k in range(N - 1, -1, -1):
        P, K[k], Lit[k], gy[k], mu, lam, g[k] = sk["bwd"](
            P, lam, mu, z[xs[k]], qf, e[k], A[k], B[k], z[us[k]])
    return A, B, e, K, Lit, ca.vertcat(*gy), ca.vertcat(*g)
