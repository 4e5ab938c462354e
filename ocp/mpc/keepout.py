"""Keep-out cones in the stage-wise MPC: each cone one more QP state.

A cone (`ocp.KeepOut`) keeps a body axis b at least α from a direction
s of the reference frame:

.. math::
    c(q) = s^T R(q)\\, b - \\cos α \\le 0

(R(q) body to reference, `adcs_common.quaternion.quat_to_dcm`; theory
§5, the slews' keep-out row). The stage-wise QP (`ocp.mpc.stagewise_ipm`)
boxes components of states and controls only; a cone's row is a
function of the state whose gradient changes at every stage. One SQP
step linearises it at each planned state x̄_{k+1}, ``c(x̄) + G δx ≤ 0``
with ``G = ∂c/∂x``, and the QP carries ``y = G δx`` as an extra state:

.. math::
    δy_{k+1} = G_{k+1}(A_kδx_k + B_kδu_k + d_k),\\qquad
    δy_{k+1} \\le -c(\\bar x_{k+1}) - \\text{backoff}

(its column of A is zero, its cost zero). The cone is then a box on a
state, and the interior point, its Riccati sweeps, the polish and the
certificate handle it unchanged; each cone adds one row to every
stage's state. The MPC plans each cone widened by the most its path can
dip between two samples (`planning_cones`), and ``backoff`` [cos units]
inside that, for the linearisation's error over one step (second order
in the step); the plan's check holds the cones as given.
"""

from __future__ import annotations

from typing import Any, Sequence

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.quaternion import quat_to_dcm
from ocp.slews.setup import KeepOut

__all__ = ["CONE_FLOOR", "CONE_WIDTH", "KEEP_OUT_BACKOFF",
           "augmented_linearisation", "as_keep_out", "cone_function",
           "cone_values", "pad_cost", "plan_cone_violation",
           "planning_cone_function", "planning_cones", "qp_stage_functions",
           "smallest_cone_margin", "stage_defects"]

#: How far inside each cone's boundary the MPC plans [cos units]
#: (module doc).
KEEP_OUT_BACKOFF = 1e-4
#: Lower side of a cone's box [cos units]: below any value of c (≥ −2),
#: so it never binds.
CONE_FLOOR = -4.0
#: The scale of a cone's box in the QP [cos units] (the other boxes are
#: scaled by their bounds' widths). The robust tree's certificate is
#: sensitive to it, on the demo craft's Monte Carlo (seed 1, 5 % rate
#: margin, 20° cone): scaled by 4 (the box's width) the active rows of
#: x_1, which u_0 moves through dt² terms only, left a QP at 3e-6 (draw
#: 0, step 23); by 0.01 a far cone's slack of 377 (scaled) left one at
#: 1.9e-6 (draw 8, step 2); by 0.1, 2 loops of 200 ended on such a step
#: (draws 140 and 191, step 7, 1.2e-6 and 1.5e-6); by 1 those certify.
CONE_WIDTH = 1.0


def as_keep_out(keep_out: Any, solver: str = "stagewise"
                ) -> tuple[KeepOut, ...]:
    """The cones as a tuple (None: none); anything else is refused, and
    cones for a ``solver`` other than ``"stagewise"``."""
    if keep_out is None:
        return ()
    if solver != "stagewise":
        raise InvalidValueError(
            f"keep_out needs solver='stagewise', got {solver!r}")
    if isinstance(keep_out, KeepOut):
        return (keep_out,)
    if not isinstance(keep_out, (list, tuple)):
        raise InvalidValueError(
            "keep_out must be a KeepOut or a sequence of KeepOut, got "
            f"{type(keep_out).__name__}")
    for i, k in enumerate(keep_out):
        if not isinstance(k, KeepOut):
            raise InvalidValueError(
                f"keep_out[{i}] must be a KeepOut, got {type(k).__name__}")
    return tuple(keep_out)


def planning_cones(mpc: Any) -> tuple[KeepOut, ...]:
    """The cones the MPC plans with: each widened by its path pad [rad].

    The MPC holds a cone at the samples; between two samples dt apart the
    boresight's angle can dip by ``B dt²/8`` below the lower sample, with
    ``B = |ω̇| + |ω|²(1 + |cot α|)`` (`ocp.slews.keepout.path_margin`,
    10 % over). |ω| is bounded by ``rate_max`` (without one, by all the
    wheels' momentum in the body), |ω̇| by the wheels' torque and the
    gyroscopic term, on the smallest inertia of the MPC's plants (a robust
    MPC's scenarios).
    """
    from ocp.slews.keepout import path_margin

    wh = mpc.wheels
    plants = [(s.inertia, wh.axes if s.axes is None else s.axes)
              for s in getattr(mpc, "scenarios", ())] or [
        (mpc.model.inertia, wh.axes)]
    m = float(np.linalg.norm(np.asarray(wh.m_max, float)))
    h = float(np.linalg.norm(np.asarray(wh.h_max, float)))
    accel, rate = 0.0, 0.0
    for J, A in plants:
        j_inv = float(np.linalg.norm(np.linalg.inv(J), 2))
        a = float(np.linalg.norm(A, 2))
        w = float(mpc.rate_max if mpc.rate_max is not None
                  else j_inv * a * h)
        rate = max(rate, w)
        accel = max(accel, j_inv * (a * m + w * (
            float(np.linalg.norm(J, 2)) * w + a * h)))
    out = []
    for k in mpc.keep_out:
        pad = -path_margin(0.0, rate, accel, mpc.dt,
                           min(k.half_angle, np.pi - k.half_angle))
        if k.half_angle + pad >= np.pi:
            raise InvalidValueError(
                f"a keep-out cone of {np.rad2deg(k.half_angle):.1f}° "
                f"widened by its path pad ({np.rad2deg(pad):.2f}°) covers "
                "the sphere: shorten dt or lower rate_max")
        out.append(KeepOut(k.boresight, k.direction, k.half_angle + pad))
    return tuple(out)


def planning_cone_function(mpc: Any) -> ca.Function | None:
    """`cone_function` of the cones the MPC plans with (`planning_cones`),
    the stage-wise and robust QPs' extra states; None without a cone."""
    if not mpc.keep_out:
        return None
    return cone_function(planning_cones(mpc), mpc.model.nx)


def cone_values(cones: Sequence[KeepOut], q: Any) -> np.ndarray:
    """``c_j(q) = s_jᵀR(q)b_j − cos α_j`` (module doc) of quaternions
    ``q`` (K, 4), scalar first, as given (not normalised): (K, n_c)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.empty((q.shape[0], len(cones)))
    for k, qk in enumerate(q):
        R = quat_to_dcm(qk)
        for j, c in enumerate(cones):
            out[k, j] = (np.asarray(c.direction) @ R @ np.asarray(
                c.boresight) - np.cos(c.half_angle))
    return out


def cone_function(cones: Sequence[KeepOut], nx: int) -> ca.Function:
    """``mpc_cones(x) -> c`` (n_c,): `cone_values` of a state's
    quaternion x[:4], in SX."""
    x = ca.SX.sym("x", nx)
    R = quat_to_dcm(x[:4])
    c = [ca.mtimes(ca.mtimes(_dm(k.direction).T, R), _dm(k.boresight))
         - np.cos(k.half_angle) for k in cones]
    return ca.Function("mpc_cones", [x], [ca.vertcat(*c)], ["x"], ["c"])


def _dm(v: Any) -> ca.DM:
    """A cone's stored axis (a tuple of 3 float) as a column."""
    return ca.DM(np.asarray(v, dtype=float).reshape(3, 1))


def augmented_linearisation(F: Any, Aj: Any, Bj: Any, x1: Any,
                            cones: ca.Function) -> tuple:
    """``(d, A, B)`` of one stage's QP with the cones as states.

    ``F`` (n_x,) the SX next state of the stage, ``Aj``, ``Bj`` its
    Jacobians, ``x1`` the SX symbol of the planned next state. Returns
    the defect ``[F − x1; G(F − x1)]`` and the ((n_x + n_c) square,
    (n_x + n_c) × n_u) matrices of the module doc.
    """
    c = cones(x1)
    G = ca.jacobian(c, x1)
    nx, nc = Aj.shape[0], c.shape[0]
    d = F - x1
    A = ca.blockcat([[Aj, ca.SX(nx, nc)],
                     [ca.mtimes(G, Aj), ca.SX(nc, nc)]])
    B = ca.vertcat(Bj, ca.mtimes(G, Bj))
    return ca.vertcat(d, ca.mtimes(G, d)), A, B


def pad_cost(Q: Any, q: Any, nc: int) -> tuple:
    """A stage's Hessian and gradient with zero rows for n_c cone states."""
    return ca.diagcat(Q, ca.SX(nc, nc)), ca.vertcat(q, ca.SX.zeros(nc))


def qp_stage_functions(prefix: str, ins: list, F: Any, A: Any, B: Any,
                       stage_ins: list, Q: Any, q: Any,
                       cones: ca.Function | None
                       ) -> tuple[ca.Function, ca.Function,
                                  tuple[ca.Sparsity, ca.Sparsity,
                                        ca.Sparsity]]:
    """``(lin, stage, (sp_A, sp_B, sp_Q))``: a stage-wise QP's kernels.

    ``lin = <prefix>_lin(ins…) -> (F, A, B)`` (the stage's next state and
    Jacobians, matrices as nonzeros) without ``cones``; with them
    ``<prefix>_lin(ins…, x_next) -> (d, A, B)``, the defect and the
    matrices with the cones as states (`augmented_linearisation`).
    ``stage = <prefix>_stage(stage_ins…) -> (Q, q)``, padded for the
    cones (`pad_cost`). `stage_defects` reads ``lin``'s first output.
    """
    from .stagewise_kernels import nz_of

    if cones is None:
        lin = ca.Function(prefix + "_lin", ins, [F, nz_of(A), nz_of(B)])
    else:
        x1 = ca.SX.sym("x_next", F.shape[0])
        d, A, B = augmented_linearisation(F, A, B, x1, cones)
        lin = ca.Function(prefix + "_lin", [*ins, x1],
                          [d, nz_of(A), nz_of(B)])
        Q, q = pad_cost(Q, q, cones.size1_out(0))
    stage = ca.Function(prefix + "_stage", stage_ins, [nz_of(Q), q])
    return lin, stage, (A.sparsity(), B.sparsity(), Q.sparsity())


def stage_defects(lin_map: ca.Function, args: list, X1: Any,
                  cones: ca.Function | None) -> tuple:
    """``(D, A, B)`` of the mapped ``lin`` of `qp_stage_functions` over
    the stages: the defects ``F − X1`` (with cones, ``lin`` returns
    them, the cones' rows included) and the stages' matrices."""
    if cones is None:
        F, A, B = lin_map(*args)
        return F - X1, A, B
    return lin_map(*args, X1)


def smallest_cone_margin(cones: Sequence[KeepOut], q: Any) -> float:
    """Smallest angle [rad] of the attitudes ``q`` (K, 4) from the cones
    (`ocp.KeepOut.margin`; negative inside one, +inf with no cone)."""
    return float(min((np.min(c.margin(q)) for c in cones), default=np.inf))


def plan_cone_violation(cones: ca.Function, X: Any) -> ca.MX:
    """Largest ``max(0, c)`` over the states X (n_x × K) [cos units]."""
    return ca.fmax(0.0, ca.mmax(cones.map(X.shape[1])(X)))
