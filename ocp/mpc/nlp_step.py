"""The step Function of an NLP-solved MPC (sqpmethod, IPOPT, fatrop)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .plan import nan_unless_finite
from .problem import BOUND_TOL, QP_KKT_TOL


def build_nlp_step(self: Any, x_par, qf, tau, p) -> None:
    """Set ``self.rti_function`` and ``self.step_function`` of an NLP MPC.

    ``self`` is the `AttitudeMPC` (its ``nlpsol``, ``fallback``, shift and
    check Functions); the step Function shifts the warm start, solves,
    checks and certifies (``qp_kkt``), with the RTI fallback to the full
    SQP when the RTI step fails.
    """
    nz, us = self._nz, self._us
    z_prev = ca.MX.sym("z_prev", nz)
    lam_x_prev = ca.MX.sym("lam_x_prev", nz)
    lam_g_prev = ca.MX.sym("lam_g_prev", self._ng)
    sh = self.shift_function(x_par, z_prev, lam_x_prev, lam_g_prev)
    sol = self.nlpsol(x0=sh[0], p=p, lbx=self.lbz, ubx=self.ubz,
                      lbg=0, ubg=0, lam_x0=sh[1], lam_g0=sh[2])
    zo, lxo, lgo = sol["x"], sol["lam_x"], sol["lam_g"]
    names = (["x", "qf", "tau", "z_prev", "lam_x_prev", "lam_g_prev"],
             ["u", "z", "lam_x", "lam_g", "cost", "violation",
              "first_violation", "defect", "qp_kkt"])
    # RTI: the one SQP step's QP point, certified (a converged SQP's
    # last step is its QP's point too)
    kkt, = nan_unless_finite(zo, self.qp_kkt_function(sh[0], zo, lxo, lgo,
                                                      p))
    #: ``step_function`` without the RTI fallback: what `step` calls
    #: (through a bound buffer) with ``rti=True``.
    self.rti_function = ca.Function(
        "mpc_rti_single",
        [x_par, qf, tau, z_prev, lam_x_prev, lam_g_prev],
        [zo[us[0]], zo, lxo, lgo, *self.check_function(zo, p), kkt],
        *names)
    if self.fallback is not None:
        # evaluated only when the RTI step fails its check
        a = [ca.MX.sym(n, s.sparsity()) for n, s in
             (("z0", z_prev), ("lx0", lam_x_prev), ("lg0", lam_g_prev),
              ("p", p), ("z", z_prev), ("lx", lam_x_prev),
              ("lg", lam_g_prev))]
        fb = self.fallback(x0=a[0], p=a[3], lbx=self.lbz, ubx=self.ubz,
                           lbg=0, ubg=0, lam_x0=a[1], lam_g0=a[2])
        full = ca.Function("mpc_full", a,
                           [fb["x"], fb["lam_x"], fb["lam_g"]])
        keep = ca.Function("mpc_keep", a, [a[4], a[5], a[6]])
        pick = ca.Function.if_else("mpc_pick", full, keep)
        # the step is not its QP's solution, or leaves a bound: the
        # full SQP from the same warm start
        bad = ca.logic_not(ca.logic_and(
            self.check_function(zo, p)[2] <= BOUND_TOL, kkt <= QP_KKT_TOL))
        zo, lxo, lgo = pick(bad, sh[0], sh[1], sh[2], p, zo, lxo, lgo)
        # the full SQP's plan is not one QP step from the warm start
        kkt = ca.if_else(bad, np.nan, kkt)
    chk = self.check_function(zo, p)
    kkt, = nan_unless_finite(zo, kkt)
    self.step_function = ca.Function(
        "mpc_step",
        [x_par, qf, tau, z_prev, lam_x_prev, lam_g_prev],
        [zo[us[0]], zo, lxo, lgo, *chk, kkt], *names)

