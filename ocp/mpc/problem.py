"""What an MPC is made of: solver names, cost weights, the step record."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from adcs_common.quaternion import quat_conj, quat_mul
from adcs_common.results import ResultMixin
from adcs_common.exceptions import (
    InfeasibleError,
    InvalidValueError,
)
from adcs_common.validation import (
    as_finite_scalar,
    check_nonnegative,
)


#: Conic plugins accepted by ``solver="sqpmethod"`` (code-generatable).
QP_SOLVERS = ("qrqp", "daqp")


#: NLP solver names -> CasADi nlpsol plugin.
NLP_PLUGINS = {"ipopt": "ipopt", "sqpmethod": "sqpmethod",
                "fatrop": "fatrop"}


#: Largest bound violation [scaled, 1] accepted on a returned plan.
BOUND_TOL = 1e-6


#: Largest dynamics defect accepted on a converged (non-RTI) plan.
DEFECT_TOL = 1e-6


#: Largest KKT residual [relative, 1] of an SQP step's QP point accepted as
#: that QP's solution (`MPCStep.qp_kkt`).
QP_KKT_TOL = 1e-6


#: Every MPC solver name: the NLP plugins, ``"condensed"`` (the toolbox's
#: Gauss–Newton SQP on the condensed QP, `ocp.mpc.condensed`) and
#: ``"stagewise"`` (the same SQP on the stage-wise QP, solved by a Riccati
#: interior point, `ocp.mpc.stagewise`).
MPC_SOLVERS = (*NLP_PLUGINS, "condensed", "stagewise")

#: The toolbox's own SQPs (wheel-only models; no CasADi nlpsol).
OWN_SQP_SOLVERS = ("condensed", "stagewise")


def available_mpc_solvers() -> tuple[str, ...]:
    """MPC solver names whose CasADi plugin loads on this installation."""
    names = []
    conic = any(ca.has_conic(q) for q in QP_SOLVERS)
    for name in MPC_SOLVERS:
        try:
            ok = name in OWN_SQP_SOLVERS or ca.has_nlpsol(NLP_PLUGINS[name])
        except RuntimeError:
            ok = False
        if ok and (name not in ("sqpmethod", "condensed") or conic):
            names.append(name)
    return tuple(names)


@dataclass(frozen=True)
class MPCWeights:
    """Weights of the MPC cost (all dimensionless, see module doc).

    Attributes
    ----------
    attitude : float
        :math:`w_q` on :math:`\\|\\mathrm{vec}(q_f^*\\otimes q)\\|^2
        = \\sin^2(θ/2)` [1].
    rate : float
        :math:`w_ω` on :math:`\\|ω\\|^2` [s²/rad²].
    torque : float
        :math:`w_m` on :math:`\\|m / m_{max}\\|^2` [1].
    momentum : float
        :math:`w_H` on :math:`\\|H / h_{max}\\|^2` [1] (keeps the wheels
        near zero momentum in holds).
    terminal : float
        Factor :math:`c_N` on the last stage's attitude and rate terms.
    propellant : float
        :math:`w_p` on the thruster duties weighted by propellant rate
        (linear; only with a thruster set) [1].
    """

    attitude: float = 100.0
    rate: float = 100.0
    torque: float = 0.01
    momentum: float = 0.001
    terminal: float = 10.0
    propellant: float = 0.1

    def __post_init__(self) -> None:
        """Check that every weight is finite and non-negative."""
        for name in ("attitude", "rate", "torque", "momentum", "terminal",
                     "propellant"):
            value = as_finite_scalar(getattr(self, name), name)
            check_nonnegative(value, name)
        if self.attitude <= 0:
            raise InvalidValueError(
                f"attitude weight must be positive, got {self.attitude}")


@dataclass(frozen=True, eq=False, repr=False)
class MPCStep(ResultMixin):
    """The outcome of one MPC step.

    Attributes
    ----------
    u : numpy.ndarray, shape (nu,)
        First command, to hold over ``dt``: motor torques m [N·m], then
        the thruster duties [1] when the model has thrusters.
    plan : numpy.ndarray, shape (nz,)
        The optimised decision vector (the next step's warm start).
    cost : float
        Cost of the plan [1].
    violation : float
        Largest bound violation of the plan, scaled by the bound [1].
    first_violation : float
        The same over the applied command ``u`` and the state after it.
    defect : float
        Largest dynamics defect of the plan (non-zero after a single RTI
        step) [state units].
    solve_time : float
        Wall time of the NLP solver call [s] (shift and checks excluded).
    iterations : int
        SQP/IPOPT iterations (-1 when the solver does not report them).
    status : str
        The solver's return status (the toolbox's SQPs: ``"rti_step"``,
        ``"converged"`` or ``"iteration_limit"``, with ``":qp_capped"``
        appended when the last QP stopped at its cap, a feasible point
        of lower cost that is not the QP's optimum, `ocp.mpc.primal_qp`).
    qp_kkt : float
        Optimality certificate of the last SQP step: the KKT residual of
        its QP's point (stationarity, row violation, complementarity;
        relative) [1]. Zero at the QP's solution; NaN for IPOPT and
        fatrop, whose steps are not QPs. A step above `QP_KKT_TOL` is not
        that QP's solution: the RTI of ``"sqpmethod"`` then falls back to
        the full SQP, and `AttitudeMPC.step` refuses it otherwise.
    """

    u: np.ndarray
    plan: np.ndarray
    cost: float
    violation: float
    first_violation: float
    defect: float
    solve_time: float
    iterations: int
    status: str
    qp_kkt: float = float("nan")


def torque_residual(u, weights: MPCWeights, m_max: np.ndarray):
    """Least-squares residual of a stage's wheel torques (n_w,).

    ``√w_m · m / m_max`` for the first n_w = len(m_max) controls of ``u``
    (SX, MX or numpy; the thrusters' duties follow them).
    """
    return np.sqrt(weights.torque) * u[:len(m_max)] / ca.DM(m_max)


def dynamics_sign(solver: str) -> float:
    """Sign of the MPC's dynamics rows ``sign · (x_{k+1} − F(x_k, u_k))``.

    fatrop's structure detection needs x_{k+1} − F; qrqp was measured to
    fail more often on that sign (its active-set steps on this QP depend
    on the row signs), so every other solver gets F − x_{k+1}.
    """
    return 1.0 if solver == "fatrop" else -1.0


def momentum_residual(x, weights: MPCWeights, h_max: np.ndarray,
                      factor=1.0):
    """Least-squares residual of a state's wheel momenta (n_w,).

    ``√(factor · w_H) · H / h_max`` for the state ``x`` (SX, MX or numpy,
    n_x); ``factor`` may be symbolic (the condensed kernels pass 0 or 1).
    """
    return ca.sqrt(factor * weights.momentum) * x[7:] / ca.DM(h_max)


def pointing_residuals(x, qf, weights: MPCWeights, factor=1.0):
    """Least-squares residuals of a state's attitude and rate (6,).

    ``√(c · w_q) · vec(q_f* ⊗ q)`` and ``√(c · w_ω) · ω`` for the state
    ``x`` and target ``qf``, ``c = factor`` (`MPCWeights.terminal` on the
    last stage).
    """
    qe = quat_mul(quat_conj(qf), x[:4])
    return ca.vertcat(ca.sqrt(factor * weights.attitude) * qe[1:],
                      ca.sqrt(factor * weights.rate) * x[4:7])


def check_reachable(mpc: Any, x: np.ndarray) -> None:
    """Raise `InfeasibleError` when x_1 cannot meet the state bounds
    (or x lies inside one of the MPC's keep-out cones).

    ``mpc`` is the `AttitudeMPC` (its wheels, dt, rate bound and model).
    """
    wh = mpc.wheels
    h = x[7:]
    m_hi = np.where(wh.active, wh.m_max, 0.0)
    gap = np.abs(h) - m_hi * mpc.dt - wh.h_max
    if np.any(gap > 1e-12):
        i = int(np.argmax(gap))
        raise InfeasibleError(
            f"x: wheel {i} momentum {h[i]:.4g} N·m·s cannot return "
            f"inside h_max = {wh.h_max[i]:.4g} within one step of "
            f"{mpc.dt:g} s at m_max = {m_hi[i]:.4g} N·m: the MPC "
            "horizon is infeasible", problem=x)
    if mpc.rate_max is not None:
        excess = np.max(np.abs(x[4:7])) - mpc.rate_max
        # the reachable change of rate in one step
        J = mpc.model.inertia
        reach = np.linalg.norm(wh.working_axes * m_hi, axis=0).sum()
        if mpc.model.thrusters is not None:
            reach += np.linalg.norm(
                mpc.model.thrusters.torque_matrix(), axis=0).sum()
        dmax = mpc.dt * reach / np.linalg.eigvalsh(J).min()
        if excess > dmax:
            raise InfeasibleError(
                f"x: body rate {np.max(np.abs(x[4:7])):.4g} rad/s "
                f"exceeds rate_max = {mpc.rate_max:.4g} rad/s by more "
                f"than one step can remove ({dmax:.3g} rad/s): the MPC "
                "horizon is infeasible", problem=x)
    for i, cone in enumerate(getattr(mpc, "keep_out", ())):
        margin = float(cone.margin(x[:4]))
        if margin < 0.0:
            raise InfeasibleError(
                f"x: the boresight lies {np.rad2deg(-margin):.3g}° inside "
                f"keep_out[{i}] (a cone of {np.rad2deg(cone.half_angle):.3g}"
                "°): the attitude one step ahead cannot leave it, the MPC "
                "horizon is infeasible", problem=x)
