"""Polish of the stage-wise interior point's answer on its active set.

An interior point ends near the QP's solution with every active box's
slack small but not zero, and its multipliers become inaccurate when a
state box is active: the barrier's curvature λ/s grows past 1e12 and
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

The caller (`stagewise_cascade`) polishes up to three times, each a step of
an active-set method on the guess before it: on λ > s; then either
without the rows whose multiplier came out with the wrong sign
(`reduced_active`: dependent boxes, a torque bound and the rate bound it
drives) or, when the first polish could not meet its equalities (an
inconsistent guess), on the clearly active boxes (`clear_active`); and,
only when neither met `POLISH_ACCEPT`, on the second's guess less its
wrong-signed rows and with the boxes its point breaks (`next_active`),
and once more so when that point still misses `POLISH_ACCEPT`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .stagewise_kernels import reverse_columns
from .stagewise_lq import FactoredLQ

#: The augmented Lagrangian's penalty [scaled, 1].
POLISH_RHO = 1e8
#: KKT residual [scaled, 1] up to which the polished point is preferred to
#: the interior point's (it is the active set's exact solution).
POLISH_ACCEPT = 1e-8
#: How many times its slack a box's multiplier must be for the box to be
#: clearly active (`clear_active`) [1].
POLISH_CLEAR = 1e4
#: A box held as an equality counts as met within this [scaled, 1].
POLISH_TIGHT = 1e-9


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
    _, _, Q, q, g, r, lo, hi, *_ = data
    C = tree.C
    act_l, act_u = active if active is not None else (
        ca.if_else(Ll > Sl, 1.0, 0.0), ca.if_else(Lu > Su, 1.0, 0.0))
    act = act_l + act_u
    target = act_l * lo + act_u * hi
    lam = act * (Lu - Ll)
    sig = lay.sigma(POLISH_RHO * act)
    qmul = kern["qmul"].map(C)

    def gradient(dU, dX, lam):
        beta = lam + POLISH_RHO * act * (lay.values(dU, dX) - target)
        gx, gu = lay.lift(qmul(Q, dX) + q, r * dU + g, beta)
        return reverse_columns(gx), reverse_columns(gu)

    lq = FactoredLQ(sweeps, lay, tree, (nx, nu), flags, data, sig,
                    *gradient(dU, dX, lam))
    for k in range(2):
        dUn, dXn = lq.first() if k == 0 else lq.solve(*gradient(dU, dX, lam))
        dU, dX = dU + dUn, dX + dXn
        lam = lam + POLISH_RHO * act * (lay.values(dU, dX) - target)
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
    tight = POLISH_TIGHT
    act_l = ca.if_else(ca.fabs(Sl) <= tight, 1.0, 0.0) * ca.if_else(
        Lu > 0, 0.0, 1.0)
    act_u = ca.if_else(ca.fabs(Su) <= tight, 1.0, 0.0) * ca.if_else(
        Ll > 0, 0.0, 1.0)
    return act_l, act_u


def next_active(point: list, active: tuple) -> tuple:
    """The active-set method's step from a polished point: the masks
    ``active`` it was polished on, less the rows whose multiplier came out
    with the wrong sign, plus the boxes it breaks."""
    _, _, Sl, Su, Ll, Lu = point
    act_l, act_u = active
    return (ca.fmax(act_l * ca.if_else(Lu > 0, 0.0, 1.0),
                    ca.if_else(Sl < -POLISH_TIGHT, 1.0, 0.0)),
            ca.fmax(act_u * ca.if_else(Ll > 0, 0.0, 1.0),
                    ca.if_else(Su < -POLISH_TIGHT, 1.0, 0.0)))


def clear_active(point: list) -> tuple:
    """The active masks of an interior point's clearly active boxes.

    A box whose multiplier is `POLISH_CLEAR` times its slack or more.
    The default test (λ > s) also takes the boxes that an interior point
    has not yet decided, where slack and multiplier are both small: in a
    scenario tree, the rate boxes at x_1 of several scenarios are all
    functions of the shared u_0, nearly parallel, and near a cruise at
    the rate bound all nearly active. Held as equalities together they
    are inconsistent (their slacks differ by 1e-5), and the polish can
    meet none of them; only the tightest is active at the optimum.
    """
    _, _, Sl, Su, Ll, Lu = point
    return (ca.if_else(Ll > POLISH_CLEAR * Sl, 1.0, 0.0),
            ca.if_else(Lu > POLISH_CLEAR * Su, 1.0, 0.0))


def broken(point: list) -> ca.MX:
    """How far [scaled, 1] a point breaks its worst box (0 if none)."""
    return -ca.fmin(0.0, ca.fmin(ca.mmin(point[2]), ca.mmin(point[3])))
