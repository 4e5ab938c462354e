"""One Riccati factorisation of the stage-wise LQ problem, and its solves.

The interior point (`ocp.mpc.stagewise_ipm`) and its polish
(`ocp.mpc.stagewise_polish`) both factor the LQ problem once with a
barrier (or penalty) diagonal and solve it for one or two gradients: the
factorising sweep (``ric``) gives the first solution's feed-forwards, a
vector sweep (``vec``) on the same factor every further one, and on a
scenario tree the root chooses the shared first control each time.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from .stagewise_kernels import reverse_columns


class FactoredLQ:
    """The factor of one barrier diagonal ``sig`` (nb × C) and its solves.

    ``sweeps`` are the mapped kernels (`stagewise_ipm._sweeps`), ``data``
    the QP data (`stagewise_ipm.ipm_iteration`'s), ``qr, rr`` the first
    gradient (reversed in time). Each solve returns ``(dU, dX)``, the
    dynamics-feasible step from δx_0 = 0.
    """

    def __init__(self, sweeps: dict, lay: Any, tree: Any, dims: tuple,
                 flags: Any, data: list, sig: Any, qr: Any, rr: Any
                 ) -> None:
        nx, nu = dims
        A, B, _, _, _, _, _, _, Ar, Br, Qr, r_rev = data
        self.sweeps, self.tree, self.nu = sweeps, tree, nu
        self.A, self.B, self.Ar, self.Br = A, B, Ar, Br
        self.s, self.sr = ca.DM(flags).T, ca.DM(flags[::-1]).T
        self.zx, self.zu = ca.DM.zeros(nx), ca.DM.zeros(nu)
        *_, Kr, kr, self.Lr, self.Mr = sweeps["ric"](
            ca.DM.zeros(nx * (nx + 1) // 2), self.zx, ca.DM.zeros(nx, nu),
            ca.DM.zeros(nu, nu), self.zu, Ar, Br, Qr,
            reverse_columns(sig[lay.nbu:, :]),
            reverse_columns(sig[:lay.nbu, :]), qr, rr, r_rev, self.sr)
        self.K = reverse_columns(Kr)
        self.Re_s: Any = None
        self.Lroot: Any = None
        if tree.root:
            v0, self.Re_s, self.Lroot = tree.root_factor(self.Lr, kr, nu)
            kr = tree.with_root(kr, v0, nu)
        self.kr = kr

    def first(self) -> tuple:
        """The step of the gradient the factor was made with."""
        return self._forward(self.kr)

    def solve(self, qr: Any, rr: Any) -> tuple:
        """The step of another gradient (reversed in time), same factor."""
        _, _, k = self.sweeps["vec"](self.zx, self.zu, self.Ar, self.Br,
                                     self.Mr, self.Lr, qr, rr, self.sr)
        if self.tree.root:
            k = self.tree.with_root(k, self.tree.root_again(
                self.Re_s, self.Lroot, k, self.nu), self.nu)
        return self._forward(k)

    def _forward(self, kr: Any) -> tuple:
        dX, _, dU = self.sweeps["fwd"](self.zx, self.zu, self.A, self.B,
                                       self.K, reverse_columns(kr), self.s)
        return dU, dX
