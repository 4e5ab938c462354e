"""Which MPC solver runs by default, and the certificate of an SQP step.

An SQP step is a QP's point; `qp_kkt_function` measures how far the
point and multipliers a solver returned are from that QP's KKT
conditions, so a step reported as taken is that QP's solution
(`ocp.mpc.condensed_qp.kkt_residual` does the same for the condensed QP).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ocp.models.rigid import SpacecraftModel

from adcs_common.exceptions import SolverNotFound

from .condensed import condensed_qp_plugin
from .problem import QP_SOLVERS, available_mpc_solvers


#: Horizons above this take ``"stagewise"`` by default: the condensed
#: step grows as N² and the stage-wise one as N; measured side by side in
#: C on the demo slew they cross between N = 20 (condensed 0.13 ms,
#: stage-wise 0.21 ms) and N = 50 (0.68 ms, 0.52 ms), at about N = 40
#: (docs/benchmarks.md, long horizons).
LONG_HORIZON = 40


def default_mpc_solver(model: SpacecraftModel, horizon: int = 20) -> str:
    """The MPC solver `AttitudeMPC` takes when none is named.

    For a wheel-only model, ``"condensed"`` up to `LONG_HORIZON` stages
    and ``"stagewise"`` beyond (the same SQP and QP; the faster one at
    that horizon, measured). On the 80-step saturated slew each of the
    condensed SQP's 160 RTI and SQP steps was its QP's exact solution and
    its converged plans equal IPOPT's to 3.3e-6, while sqpmethod + qrqp
    returned a step that was not its QP's solution in 2 of 160 (off by up
    to 0.083 m_max, bounds kept); it is also faster in C
    (docs/benchmarks.md). ``"sqpmethod"`` for a model with thrusters (the
    toolbox's own SQPs handle wheels only).
    """
    if model.thrusters is None and "condensed" in available_mpc_solvers():
        return "stagewise" if horizon > LONG_HORIZON else "condensed"
    return "sqpmethod"


def resolve_qp_solver(solver: str, qp_solver: str | None) -> str:
    """`AttitudeMPC`'s ``qp_solver`` for ``solver``: the one given, or
    the default (qrqp; for ``"condensed"`` daqp where the casadi wheel has
    it, `ocp.mpc.condensed.condensed_qp_plugin`), checked.

    Raises
    ------
    SolverNotFound
        A conic that is not code-generatable here, or qrqp for
        ``"condensed"`` (it fails the condensed QP's certificate: KKT
        0.72 after 3.5 s).
    """
    if qp_solver is None:
        qp_solver = "qrqp" if solver != "condensed" else (
            condensed_qp_plugin())
    conics = tuple(q for q in QP_SOLVERS if ca.has_conic(q) and not (
        solver == "condensed" and q == "qrqp")) + (
        ("pqp",) if solver == "condensed" else ())
    if solver in ("sqpmethod", "condensed") and qp_solver not in conics:
        raise SolverNotFound(
            f"{solver}:{qp_solver}", tuple(f"{solver}:{q}" for q in conics),
            "qp_solver must be a code-generatable conic (the condensed "
            "QP needs daqp: qrqp fails its certificate)")
    return qp_solver


def qp_kkt_function(mpc: Any, z, p, r, gv, f) -> ca.Function:
    """``qp_kkt(z0, z1, lam_x, lam_g, p)``: is z1 the SQP QP's point?

    The Gauss–Newton QP at ``z0`` is ``min ½ dzᵀ H dz + ∇fᵀ dz`` subject
    to ``g + J_g dz = 0`` and the bounds on ``z0 + dz``, with ``H = 2
    J_rᵀ J_r + ρ I`` (``r`` the residuals, ``ρ`` the MPC's
    regularisation). Its KKT residual at ``dz = z1 - z0`` with the
    returned multipliers (CasADi's signs: ``∇f + H dz + J_gᵀ λ_g + λ_x =
    0``, ``λ_x > 0`` only at an upper bound): the largest of stationarity
    (relative to ``1 + |∇f|_∞``), the linearised constraints' residual
    and complementarity (relative to ``1 + |λ_x|_∞``) [1]. Products only
    (``jtimes``): no Hessian is formed.

    Parameters
    ----------
    mpc : AttitudeMPC
        Its ``nz``, ``ng``, bounds and ``regularization``.
    z, p : casadi.MX
        The decision vector and parameter symbols ``r``, ``gv`` and ``f``
        are built on.
    r, gv, f : casadi.MX
        Least-squares residuals, dynamics rows and cost.
    """
    dz = ca.MX.sym("dz", mpc.nz)
    lx = ca.MX.sym("lam_x", mpc.nz)
    lg = ca.MX.sym("lam_g", mpc.ng)
    z1 = ca.MX.sym("z1", mpc.nz)
    jr_dz = ca.jtimes(r, z, dz)
    h_dz = 2 * ca.jtimes(r, z, jr_dz, True) + mpc.regularization * dz
    grad = ca.gradient(f, z)
    stat = grad + h_dz + ca.jtimes(gv, z, lg, True) + lx
    lin = gv + ca.jtimes(gv, z, dz)
    big = 1e10                 # an absent bound: any multiplier is wrong
    ub = ca.DM(np.minimum(mpc.ubz, big))
    lb = ca.DM(np.maximum(mpc.lbz, -big))
    lam = 1.0 + ca.mmax(ca.fabs(lx))
    comp = ca.mmax(ca.vertcat(ca.fmax(lx, 0) * ca.fabs(ub - z1),
                              ca.fmax(-lx, 0) * ca.fabs(z1 - lb)))
    kkt = ca.fmax(ca.mmax(ca.fabs(stat)) / (1.0 + ca.mmax(ca.fabs(grad))),
                  ca.fmax(ca.mmax(ca.fabs(lin)), comp / lam))
    inner = ca.Function("qp_kkt_at", [z, dz, z1, lx, lg, p], [kkt])
    z0 = ca.MX.sym("z0", mpc.nz)
    return ca.Function("mpc_qp_kkt", [z0, z1, lx, lg, p],
                       [inner(z0, z1 - z0, z1, lx, lg, p)],
                       ["z0", "z1", "lam_x", "lam_g", "p"], ["qp_kkt"])
