"""Polish of the stage-wise interior point's answer on its active set.

An interior point ends near the QP's solution with every active box's
slack small but not zero, and its multipliers become inaccurate when a
state box is active: the barrier's curvature λ/s grows past 1e14 and
amplifies the rounding of each step (`ocp.mpc.stagewise_ipm`). The
polish takes the boxes the interior point found active (λ > s) as
equalities and solves the QP on them by two augmented-Lagrangian steps,
``min f(w) + λᵀ(C_A w − b_A) + ½ρ|C_A w − b_A|²`` with ρ = `POLISH_RHO`,
each one Riccati solve on the same factor; the multipliers are updated
``λ ← λ + ρ (C_A w − b_A)`` between them. Started from the interior
point's multipliers it reaches the active set's exact solution to
rounding (the method of OSQP's polish, Stellato et al. 2020, §5.2, on
the stage-wise QP). The caller keeps the point whose KKT residual is the
smaller, so a wrong active set costs nothing but the time.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .stagewise_kernels import reverse_columns

#: The augmented Lagrangian's penalty [scaled, 1].
POLISH_RHO = 1e8
#: KKT residual [scaled, 1] up to which the polished point is preferred to
#: the interior point's (it is the active set's exact solution).
POLISH_ACCEPT = 1e-8


def polish(kern: dict, lay, tree, dims: tuple, flags: np.ndarray,
           point: list, data: list, sweeps: dict,
           active: tuple | None = None) -> tuple:
    """``(dU, dX, Sl, Su, Ll, Lu)``: the polished point and multipliers.

    ``point`` is the interior point's ``(dU, dX, Sl, Su, Ll, Lu)``,
    ``data`` its QP data (`ipm_iteration`'s), ``sweeps`` its mapped
    kernels (`stagewise_ipm._sweeps`); ``active`` the 0/1 masks of the
    lower and upper boxes taken as equalities (default: λ > s). The
    slacks returned are the boxes' distances (negative where a box is
    broken); the multipliers are those of the augmented Lagrangian, split
    by sign.
    """
    nx, nu = dims
    dU, dX, Sl, Su, Ll, Lu = point
    A, B, Q, q, g, r, lo, hi, Ar, Br, Qr, rr_ = data
    C = tree.C
    s, sr = ca.DM(flags).T, ca.DM(flags[::-1]).T
    zx, zu = ca.DM.zeros(nx), ca.DM.zeros(nu)
    act_l, act_u = active if active is not None else (
        ca.if_else(Ll > Sl, 1.0, 0.0), ca.if_else(Lu > Su, 1.0, 0.0))
    act = act_l + act_u
    target = act_l * lo + act_u * hi
    lam = act * (Lu - Ll)
    sig = ca.mtimes(lay.sigma_scale, POLISH_RHO * act)
    qmul = kern["qmul"].map(C)

    def gradient(dU, dX, lam):
        beta = lam + POLISH_RHO * act * (lay.values(dU, dX) - target)
        gx = qmul(Q, dX) + q + ca.mtimes(lay.Ex.T, beta)
        gu = r * dU + g + ca.mtimes(lay.Eu.T, beta)
        return reverse_columns(gx), reverse_columns(gu)

    qr, rr = gradient(dU, dX, lam)
    *_, Kr, kr, Lr, Mr = sweeps["ric"](
        ca.DM.zeros(nx * (nx + 1) // 2), zx, ca.DM.zeros(nx, nu),
        ca.DM.zeros(nu, nu), zu, Ar, Br, Qr,
        reverse_columns(sig[lay.nbu:, :]), reverse_columns(sig[:lay.nbu, :]),
        qr, rr, rr_, sr)
    K = reverse_columns(Kr)
    Re_s: Any = None
    Lroot: Any = None
    if tree.root:
        v0, Re_s, Lroot = tree.root_factor(Lr, kr, nu)
        kr = tree.with_root(kr, v0, nu)

    def step(dU, dX, kr_):
        dXn, _, dUn = sweeps["fwd"](zx, zu, A, B, K, reverse_columns(kr_), s)
        dU, dX = dU + dUn, dX + dXn
        return dU, dX, lam_of(dU, dX)

    def lam_of(dU, dX):
        return POLISH_RHO * act * (lay.values(dU, dX) - target)

    dU, dX, dl = step(dU, dX, kr)
    lam = lam + dl
    qr, rr = gradient(dU, dX, lam)
    _, _, kr2 = sweeps["vec"](zx, zu, Ar, Br, Mr, Lr, qr, rr, sr)
    if tree.root:
        kr2 = tree.with_root(kr2, tree.root_again(Re_s, Lroot, kr2, nu), nu)
    dU, dX, dl = step(dU, dX, kr2)
    lam = lam + dl
    V = lay.values(dU, dX)
    return (dU, dX, V - lo, hi - V, ca.fmax(-lam, 0.0),
            ca.fmax(lam, 0.0))


def reduced_active(point: list) -> tuple:
    """The active masks of a polished point less its wrong-signed rows.

    A box held as an equality whose multiplier came out with the wrong
    sign (a lower bound pushing up, an upper one pushing down) is not
    active at the optimum; with dependent boxes (a torque bound and the
    rate bound it drives) one of the pair is such a row. The active-set
    method's step: drop it and solve again.
    """
    _, _, Sl, Su, Ll, Lu = point
    tight = 1e-9
    act_l = ca.if_else(ca.fabs(Sl) <= tight, 1.0, 0.0) * ca.if_else(
        Lu > 0, 0.0, 1.0)
    act_u = ca.if_else(ca.fabs(Su) <= tight, 1.0, 0.0) * ca.if_else(
        Ll > 0, 0.0, 1.0)
    return act_l, act_u
