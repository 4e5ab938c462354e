"""The duty-cycle QP as one certified casadi Function, for flight C code.

`certified_duty_function` is what `ocp.codegen.export_c` writes as
``duty_qp``: a test of the demand against the set the thrusters can
produce, then the structure of the Python fast path (`duty_function`:
equality rows eliminated, the slack in closed form under hard tracking,
DAQP, a KKT certificate), and a status that says which answer the caller
holds.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from adcs_common.zonotope import zonotope_facets

from .casadi_functions import duty_function, infinite_bounds
from .problem import DutyCycleQP

#: ``status`` output of `certified_duty_function`, by value.
DUTY_STATUS = ("optimal", "bound_relaxed", "infeasible", "invalid_input",
               "solver_failed")
#: Relative margin of the attainability test (a demand this close to the
#: boundary of the attainable set goes to the solver).
_ATTAIN_TOL = 1e-9


def _equality_normals(qp: DutyCycleQP) -> np.ndarray:
    """Facet normals (F, n_eq) of ``{E k : 0 <= k <= kmax}`` (any kmax > 0).

    E holds the equality rows (thrust, and the torques under hard
    tracking): a segment for one row, a zonotope for three.
    """
    E = qp.A[:qp.n_eq, :qp.nx - 1]
    if qp.n_eq == 1:
        return np.array([[1.0], [-1.0]])
    if qp.n_eq == 3:
        return zonotope_facets(E)[0]
    raise ValueError(f"{qp.n_eq} equality rows: expected 1 or 3")


def attainable_margin(qp: DutyCycleQP, e, kmax):
    """``max_f (n_f·e - d_f)`` [1, scaled]: <= 0 when E k = e has a k.

    ``d_f = n_f·E kmax/2 + |n_f E| kmax/2 = max(n_f E, 0)·kmax`` are the
    facet offsets of the zonotope ``{E k : 0 <= k <= kmax}``; the margin
    is relative to the largest offset at ``kmax = 1`` (casadi expressions
    in, out).
    """
    E = qp.A[:qp.n_eq, :qp.nx - 1]
    N = _equality_normals(qp)
    up = np.maximum(N @ E, 0.0)
    scale = 1.0 + float(np.max(up.sum(axis=1)))
    return ca.mmax(ca.DM(N) @ e - ca.DM(up) @ kmax) / scale


def certified_duty_function(qp: DutyCycleQP, plugin: str = "daqp", *,
                            viol_tol: float = 1e-6, slack_tol: float = 1e-7,
                            name: str = "duty_qp", kkt_tol: float = 1e-9,
                            attain_tol: float = _ATTAIN_TOL,
                            options: dict | None = None) -> ca.Function:
    """``duty_qp(theta[9], kmax[n]) -> (duty[n], slack, violation, status)``.

    Every call writes every output. A demand the thrusters cannot produce
    (thrust and torques outside the zonotope ``{E k : 0 <= k <= kmax}``,
    `attainable_margin`) is answered as infeasible without a solve;
    otherwise `duty_function` with ``plugin`` (DAQP: sub-microsecond in
    C) answers and its KKT certificate decides.

    Parameters
    ----------
    qp : DutyCycleQP
        From `thrusters.build_qp`.
    plugin : str
        CasADi conic plugin of the reduced QP.
    viol_tol : float
        Largest scaled constraint violation of an accepted point [1].
    slack_tol : float
        Slack above which the momentum bound counts as relaxed [1].
    name : str
        Function (C symbol) name.
    kkt_tol, attain_tol : float
        KKT residual bound of the certificate (`duty_function`) and
        relative margin of the attainability test (`attainable_margin`);
        a float export raises both (`ocp.codegen.precision.TOLERANCES`).
    options : dict, optional
        Conic options (`duty_function`).

    Returns
    -------
    casadi.Function
        Inputs ``theta = (P_T, M_X, M_Z, H[3], τ[3])`` (see
        `DutyCycleAllocator.theta`) and ``kmax`` (ones at the build
        pressure). Outputs: ``duty`` in [0, 1] per thruster, ``slack``
        (the momentum bound's relaxation, scaled by h_max), ``violation``
        (largest scaled constraint violation of the returned point) and
        ``status``, an index into `DUTY_STATUS`: 0 optimal, 1 momentum
        bound relaxed (the best the thrusters can do), 2 infeasible (no
        duties give the demanded thrust and torques), 3 invalid input
        (NaN or infinity, or a ``kmax`` not positive), 4 the solver's
        point failed its certificate. Duties are 0 unless the status is
        0 or 1.
    """
    n = qp.nx - 1
    nth = qp.Lm.shape[1]
    fast = duty_function(qp, plugin, options, viol_tol=viol_tol,
                         kkt_tol=kkt_tol, jit=False)
    # straight-line SX before and after the one conic call (cheaper in C
    # than the same arithmetic as MX nodes)
    th = ca.SX.sym("theta", nth)
    km = ca.SX.sym("kmax", n)
    valid = ca.logic_and(ca.fabs(ca.sum1(th) + ca.sum1(km)) < np.inf,
                         ca.mmin(km) > 0)
    th0 = ca.if_else(valid, th, ca.DM.zeros(nth))
    km0 = ca.if_else(valid, km, ca.DM.ones(n))
    l = ca.DM(infinite_bounds(qp.l0)) + ca.DM(qp.Lm) @ th0
    attain = attainable_margin(qp, l[:qp.n_eq], km0) <= attain_tol
    before = ca.Function(f"{name}_in", [th, km],
                         [th0, km0, ca.logic_and(valid, attain), valid])

    y = ca.SX.sym("y", n + 2)
    th0s = ca.SX.sym("theta0", nth)
    km0s = ca.SX.sym("kmax0", n)
    go = ca.SX.sym("attain")
    ok = ca.SX.sym("valid")
    solved = ca.logic_and(go, y[n + 1] <= 1.0)
    duty = ca.if_else(solved, y[:n], ca.DM.zeros(n))
    slack = ca.if_else(solved, y[n], 0.0)
    x = ca.vertcat(duty * km0s, slack)
    Ax = ca.DM(qp.A) @ x
    l = ca.DM(infinite_bounds(qp.l0)) + ca.DM(qp.Lm) @ th0s
    u = ca.DM(infinite_bounds(qp.u0)) + ca.DM(qp.Um) @ th0s
    violation = ca.mmax(ca.vertcat(ca.fmax(l - Ax, 0), ca.fmax(Ax - u, 0)))
    status = ca.if_else(
        ok, ca.if_else(solved, ca.if_else(slack > slack_tol, 1, 0),
                       ca.if_else(go, 4, 2)), 3)
    after = ca.Function(f"{name}_out", [y, th0s, km0s, go, ok],
                        [duty, slack, ca.if_else(ok, violation, 0), status])

    # the solve or its skip as a switch over before's outputs (an MX
    # if_else would make its branches Functions of theta and kmax, and
    # the solve's branch would redo `before`)
    th0b, km0b = ca.MX.sym("theta0", nth), ca.MX.sym("kmax0", n)
    solve = ca.Function(f"{name}_solve", [th0b, km0b],
                        [ca.vertcat(*fast(th0b, km0b))])
    skip = ca.Function(f"{name}_skip", [th0b, km0b],
                       [ca.vertcat(ca.DM.zeros(n), 0.0, np.inf)])
    branch = ca.Function.if_else(f"{name}_branch", solve, skip)
    theta = ca.MX.sym("theta", nth)
    kmax = ca.MX.sym("kmax", n)
    th0m, km0m, gom, okm = before(theta, kmax)
    ym = branch(gom, th0m, km0m)
    # casadi's stubs: a call of a Function with several outputs returns
    # a tuple of them, not one MX
    return ca.Function(name, [theta, kmax],  # type: ignore[call-overload]
                       after(ym, th0m, km0m, gom, okm),
                       ["theta", "kmax"],
                       ["duty", "slack", "violation", "status"])
