"""The boxes of the stage-wise MPC QP and the interior point's box work.

`BoxLayout` says which components of a stage's control and state carry
boxes (torque, momentum and rate bounds), scaled by their widths, with
the selections as per-stage SX kernels mapped over the stages;
`box_kernels` are one stage's element-wise interior-point operations on
its boxes (the step to the boundary, the complementarity), used by
`ocp.mpc.stagewise_ipm`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np


class BoxLayout:
    """Which components carry boxes, their widths and selection matrices.

    ``v = Eu δu + Ex δx`` (nb,) are the boxed components, each divided by
    its bound's width (so a feasible v spans [lo, lo + 1]).
    """

    def __init__(self, nx: int, nu: int, free: np.ndarray,
                 width_u: np.ndarray, bx: list[int],
                 width_x: np.ndarray) -> None:
        self.bu = [int(i) for i in np.flatnonzero(free)]
        self.bx = list(bx)
        self.nbu, self.nbx = len(self.bu), len(self.bx)
        self.nb = self.nbu + self.nbx
        wu = np.asarray(width_u, dtype=float)[self.bu]
        wx = np.asarray(width_x, dtype=float)
        eu = np.zeros((self.nb, nu))
        ex = np.zeros((self.nb, nx))
        for j, i in enumerate(self.bu):
            eu[j, i] = 1.0 / wu[j]
        for j, i in enumerate(self.bx):
            ex[self.nbu + j, i] = 1.0 / wx[j]
        self.Eu = ca.DM(ca.sparsify(ca.DM(eu)))
        self.Ex = ca.DM(ca.sparsify(ca.DM(ex)))
        inv2 = np.r_[1.0 / wu ** 2, 1.0 / wx ** 2]
        self.sigma_scale = ca.DM(ca.sparsify(ca.DM(np.diag(inv2))))
        self.width = np.r_[wu, wx]
        # one stage's selections as SX kernels, mapped over the columns:
        # a loop in C with no cleared products (the same operations as
        # the selection matrices: each row or column holds one entry)
        du, dx, b = ca.SX.sym("du", nu), ca.SX.sym("dx", nx), \
            ca.SX.sym("b", self.nb)
        m = ca.SX.sym("m", self.nb)
        gx, gu = ca.SX.sym("gx", nx), ca.SX.sym("gu", nu)
        self._kernels = {
            "values": ca.Function("sw_values", [du, dx],
                                  [ca.mtimes(self.Eu, du)
                                   + ca.mtimes(self.Ex, dx)]),
            "lift": ca.Function("sw_lift", [gx, gu, b],
                                [gx + ca.mtimes(self.Ex.T, b),
                                 gu + ca.mtimes(self.Eu.T, b)]),
            "sigma": ca.Function("sw_sigma", [m],
                                 [ca.mtimes(self.sigma_scale, m)]),
            "residual": _residual_kernel(self, nx, nu)}
        self._mapped: dict[tuple[str, int], ca.Function] = {}

    def _map(self, name: str, C: int) -> ca.Function:
        if (name, C) not in self._mapped:
            self._mapped[name, C] = self._kernels[name].map(C)
        return self._mapped[name, C]

    def values(self, dU, dX):
        """The scaled boxed components (nb × C) of controls and states."""
        return self._map("values", dU.shape[1])(dU, dX)

    def lift(self, gx, gu, beta) -> tuple:
        """``(gx + Exᵀβ, gu + Euᵀβ)``: a box term added to the gradients."""
        return self._map("lift", beta.shape[1])(gx, gu, beta)

    def sigma(self, M):
        """The barrier diagonals in unscaled units: M (nb × C) / width²."""
        return self._map("sigma", M.shape[1])(M)

    def residual_rows(self, point: list, lo, hi, q, g):
        """(5 × C) per stage: the largest box residual, complementarity
        product and broken box, the sum of the point's entries and the
        largest |q|, |g| (`_residual_kernel`)."""
        return self._map("residual", q.shape[1])(*point, lo, hi, q, g)


def _residual_kernel(lay: BoxLayout, nx: int, nu: int) -> ca.Function:
    """One stage's part of a point's KKT residual, reduced in SX.

    ``(du, dx, Sl, Su, Ll, Lu, lo, hi, q, g) -> [max |v − lo − Sl|,
    |hi − v − Su|; max s·λ; max(0, −s); Σ entries; max |q|, |g|]``: the
    maxima as branches, where an MX ``mmax`` over the whole horizon calls
    a function per element (5 % of a robust step's instructions).
    """
    nb = lay.nb
    du, dx = ca.SX.sym("du", nu), ca.SX.sym("dx", nx)
    Sl, Su, Ll, Lu, lo, hi = (ca.SX.sym(n, nb) for n in
                              ("Sl", "Su", "Ll", "Lu", "lo", "hi"))
    q, g = ca.SX.sym("q", nx), ca.SX.sym("g", nu)
    v = ca.mtimes(lay.Eu, du) + ca.mtimes(lay.Ex, dx)

    def largest(xs):
        out = xs[0]
        for x in xs[1:]:
            out = _smax(out, x)
        return out

    primal = largest([ca.fabs(e) for e in ca.vertsplit(
        ca.vertcat(v - lo - Sl, hi - v - Su))])
    comp = largest(ca.vertsplit(ca.vertcat(Sl * Ll, Su * Lu)))
    brk = largest([ca.SX(0.0)] + [-e for e in ca.vertsplit(
        ca.vertcat(Sl, Su))])
    total = ca.sum1(ca.vertcat(du, dx, Sl, Su, Ll, Lu))
    scale = largest([ca.fabs(e) for e in ca.vertsplit(ca.vertcat(q, g))])
    return ca.Function("sw_residual", [du, dx, Sl, Su, Ll, Lu, lo, hi, q, g],
                       [ca.vertcat(primal, comp, brk, total, scale)])


def _smax(a, b):
    """max(a, b) of SX scalars as a branch (no libm call in C)."""
    return ca.if_else(a > b, a, b)


def box_kernels(nb: int) -> dict[str, ca.Function]:
    """One stage's element-wise interior-point work on its nb boxes.

    ``ratio(Sl, Su, Ll, Lu, dSl, dSu, dLl, dLu) -> max(−dv / v)`` over
    the four pairs (the step to the boundary, `to_boundary`);
    ``mu(…, a) -> Σ (v + a dv)·(w + a dw)`` over both complementarity
    pairs; ``step(…, a) -> (Sl, Su, Ll, Lu) + a (dSl, …), max s·λ``.
    Mapped over the stages: one loop, no temporaries per operation.
    """
    vs = [ca.SX.sym(n, nb) for n in ("Sl", "Su", "Ll", "Lu")]
    ds = [ca.SX.sym("d" + n, nb) for n in ("Sl", "Su", "Ll", "Lu")]
    a = ca.SX.sym("a")
    worst = ca.SX(-1e300)
    for v, d in zip(vs, ds):
        for i in range(nb):
            worst = _smax(worst, -d[i] / v[i])
    new = [v + a * d for v, d in zip(vs, ds)]
    prod = ca.vertcat(new[0] * new[2], new[1] * new[3])
    comp = prod[0]
    for i in range(1, 2 * nb):
        comp = _smax(comp, prod[i])
    return {"ratio": ca.Function("sw_ratio", vs + ds, [worst]),
            "mu": ca.Function("sw_mu", vs + ds + [a], [ca.sum1(prod)]),
            "step": ca.Function("sw_step", vs + ds + [a], new + [comp])}


def to_boundary(ratio: ca.Function, vs: list, ds: list, tau: float
                 ) -> ca.MX:
    """Largest α ≤ 1 with ``v + α dv ≥ (1 − τ) v`` for every pair (v > 0).

    ``α = 1 / max(1, max(−dv / v) / τ)``.
    """
    return 1.0 / ca.fmax(1.0, ca.mmax(ratio(*vs, *ds)) / tau)
