"""Closed-form slew laws flight software uses (theory §4).

* `eigenaxis_slew`: rest-to-rest bang–coast–bang rotation about the
  eigenaxis, limited by the actuators' capability along it.
* `quaternion_feedback_slew`: PD on the quaternion error vector with
  gyroscopic compensation, simulated in closed loop (CVODES) through a
  wheel allocator with per-wheel torque saturation.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linprog

from adcs_common.exceptions import InfeasibleError, InvalidValueError
from adcs_common.validation import as_finite_scalar, as_vector, check_positive
from allocation import WheelArray, min_norm_gains

from ocp.spacecraft.definition import (Spacecraft, slew_parts,
                                      spacecraft_parts)

from adcs_common.quaternion import as_unit_quaternion
from adcs_common.quaternion import quat_conj, quat_mul, rotation_between
from ocp.models.rigid import SpacecraftModel, check_inertia, rigid_spacecraft
from ocp.models.trajectory import SlewTrajectory

__all__ = [
    "EigenaxisSlew",
    "eigenaxis_slew",
    "quaternion_feedback_slew",
]


def _unit_quat(q, name: str) -> np.ndarray:
    return as_unit_quaternion(q, name)


def _wheel_pattern(wheels: WheelArray, demand: np.ndarray
                   ) -> tuple[np.ndarray, float]:
    """Wheel pattern ``p`` with ``A p = demand`` (two LPs, see doc).

    Stage 1: ``s* = min s`` s.t. ``A p = demand``, ``|p_i| <= s m_max_i``
    (``1/s*`` is the radial extent of the torque zonotope along
    ``demand``). Stage 2: among those, minimise ``max_i |p_i| / h_max_i``.

    Returns ``(p, s*)``.
    """
    A = wheels.working_axes * (wheels.scale * wheels.active)
    n = wheels.n_wheels
    fixed = [(0.0, 0.0) if not a else (None, None) for a in wheels.active]
    c = np.r_[np.zeros(n), 1.0]
    # |p_i| - s * lim_i <= 0 for both signs
    def box(lim):
        eye = np.eye(n)
        return np.block([[eye, -lim[:, None]], [-eye, -lim[:, None]]])
    A_eq = np.hstack([A, np.zeros((3, 1))])
    res = linprog(c, A_ub=box(wheels.m_max), b_ub=np.zeros(2 * n),
                  A_eq=A_eq, b_eq=demand, bounds=fixed + [(0, None)],
                  method="highs")
    if res.status != 0:
        wheels.require_full_rank()      # rank < 3: say so, not HiGHS
        raise InfeasibleError(
            "wheels: the working wheels cannot produce a torque along the "
            f"eigenaxis (linprog: {res.message})", problem=demand)
    s_star = float(res.x[-1])
    bounds = [(0.0, 0.0) if not a else (-s_star * mm * (1 + 1e-9),
                                         s_star * mm * (1 + 1e-9))
              for a, mm in zip(wheels.active, wheels.m_max)]
    res2 = linprog(c, A_ub=box(wheels.h_max), b_ub=np.zeros(2 * n),
                   A_eq=A_eq, b_eq=demand, bounds=bounds + [(0, None)],
                   method="highs")
    p = res2.x[:n] if res2.status == 0 else res.x[:n]
    return p, s_star


@dataclass(frozen=True, eq=False)
class EigenaxisSlew:
    """Rest-to-rest bang–coast–bang eigenaxis slew (closed form).

    The body turns by ``angle`` about the fixed body axis ``axis``:
    :math:`ω = \\dot θ e`. The angular acceleration is ``±alpha`` over
    ``t_accel`` at each end, with a coast at ``rate`` in between:

    .. math::
        ω_p = \\min(ω_{max}, \\sqrt{α θ_f}),\\quad
        t_a = ω_p / α,\\quad t_c = θ_f/ω_p - ω_p/α,\\quad
        T = 2 t_a + t_c

    (bang–bang, :math:`T = 2\\sqrt{θ_f/α}`, when the rate limit is not
    reached).

    Attributes
    ----------
    axis : numpy.ndarray (3,)
        Unit eigenaxis e in body axes.
    angle : float
        Slew angle θ_f [rad].
    alpha : float
        Angular acceleration magnitude α [rad/s²].
    rate_max : float
        Rate limit ω_max [rad/s] (inf when none).
    t_accel, t_coast, T : float
        Acceleration and coast durations and slew time [s].
    q0 : numpy.ndarray (4,)
        Initial attitude.
    qf : numpy.ndarray (4,)
        Final attitude.
    inertia : numpy.ndarray (3, 3)
        J [kg·m²].
    wheel_pattern : numpy.ndarray (N,) or None
        p with ``m(t) = θ̈(t) p`` and ``H_w(t) = θ̇(t) p`` [kg·m²];
        ``A p = -J e``.
    """

    axis: np.ndarray
    angle: float
    alpha: float
    rate_max: float
    t_accel: float
    t_coast: float
    T: float
    q0: np.ndarray
    qf: np.ndarray
    inertia: np.ndarray
    wheel_pattern: np.ndarray | None

    @property
    def peak_rate(self) -> float:
        """Largest eigenaxis rate ω_p [rad/s]."""
        return self.alpha * self.t_accel

    def profile(self, t: ArrayLike) -> tuple[np.ndarray, np.ndarray,
                np.ndarray]:
        """Angle θ [rad], rate θ̇ [rad/s], acceleration θ̈ [rad/s²] at ``t``.

        θ̈ is taken from the right at the switch times (ZOH convention).
        """
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.T)
        a, ta, tc, T = self.alpha, self.t_accel, self.t_coast, self.T
        wp = a * ta
        t2 = ta + tc
        th = np.where(
            t < ta, 0.5 * a * t ** 2,
            np.where(t < t2, 0.5 * a * ta ** 2 + wp * (t - ta),
                     self.angle - 0.5 * a * (T - t) ** 2))
        rate = np.where(t < ta, a * t,
                        np.where(t < t2, wp, a * (T - t)))
        acc = np.where(t < ta, a, np.where(t < t2, 0.0,
                                           np.where(t < T, -a, 0.0)))
        return th, rate, acc

    def trajectory(self, n: int = 100) -> SlewTrajectory:
        """Sample the slew on a grid holding the three switch times.

        Parameters
        ----------
        n : int
            Approximate number of intervals.
        """
        ta, tc, T = self.t_accel, self.t_coast, self.T
        pieces = [(0.0, ta), (ta, ta + tc), (ta + tc, T)]
        grids = []
        for lo, hi in pieces:
            if hi - lo <= 1e-12 * T:
                continue
            k = max(1, int(round(n * (hi - lo) / T)))
            grids.append(np.linspace(lo, hi, k + 1)[:-1])
        t = np.r_[np.concatenate(grids), T]
        th, rate, acc = self.profile(t)
        dq = np.column_stack([np.cos(th / 2),
                              np.outer(np.sin(th / 2), self.axis)])
        q = np.array([quat_mul(self.q0, d) for d in dq])
        w = np.outer(rate, self.axis)
        acc = acc[:-1]
        J = self.inertia
        e = self.axis
        if self.wheel_pattern is None:
            # u = θ̈ Je + θ̇² e×Je; the gyroscopic part varies inside an
            # interval off principal axes: it is taken at the midpoint.
            rate_mid = self.profile(0.5 * (t[:-1] + t[1:]))[1]
            torque = (np.outer(acc, J @ e)
                      + np.outer(rate_mid ** 2, np.cross(e, J @ e)))
            m = h = None
        else:
            m = np.outer(acc, self.wheel_pattern)
            h = np.outer(rate, self.wheel_pattern)
            torque = np.outer(acc, J @ e)  # -A m = θ̈ J e
        return SlewTrajectory(
            method="eigenaxis", T=self.T, t=t, q=q, w=w, torque=torque,
            wheel_torque=m, wheel_momentum=h, qf=self.qf,
            status="closed_form", success=True,
            extras={"alpha": self.alpha, "rate_max": self.rate_max,
                    "t_accel": ta, "t_coast": tc})


def eigenaxis_slew(inertia: ArrayLike | Spacecraft, q0: ArrayLike, qf: ArrayLike, *,
                   wheels: WheelArray | None = None,
                   torque_max: ArrayLike | None = None,
                   rate_max: float | None = None
                   ) -> EigenaxisSlew:
    """Rest-to-rest bang–coast–bang eigenaxis slew under actuator limits.

    Definition of the limits (body eigenaxis e, rotation angle θ_f):

    * **Wheels** (initial wheel momenta zero, so the body momentum
      :math:`Jω + A H_w` stays zero and the gyroscopic term vanishes):
      the body needs :math:`A m = -θ̈\\, J e`. The acceleration bound is
      :math:`α = ρ_{Z_m}(Je)/\\|Je\\|`, where :math:`ρ_Z(d)` is the radial
      extent (largest t with :math:`t\\,d/\\|d\\|` in Z) of the torque
      zonotope :math:`Z_m = A\\,\\mathrm{diag}(m_{max})[-1, 1]^N` of the
      working wheels — the zonotope support of ``A·diag(m_max)`` in the
      direction reached, "mapped through the inertia" by :math:`Je`. It is
      found with the wheel pattern p (``A p = -J e``) minimising
      :math:`\\max_i |p_i|/m_{max,i}` (an LP, :math:`α = 1/\\max_i
      |p_i|/m_{max,i}`). The wheels then follow :math:`m = θ̈ p`,
      :math:`H_w = θ̇ p`, and the coast starts when the first wheel
      reaches its momentum bound:
      :math:`ω_{max} = \\min_i h_{max,i}/|p_i|` (among patterns of
      maximal α, p is chosen to make this largest; it equals the radial
      extent of the momentum zonotope when ``h_max ∝ m_max``).
    * **Torque box** :math:`|u_k| \\le u_{max,k}`: the body needs
      :math:`u = θ̈ Je + θ̇^2 e \\times Je`; α is the largest value keeping
      every axis inside its bound at the peak rate (exact on principal
      axes, where :math:`e\\times Je = 0`).

    Parameters
    ----------
    inertia : array_like (3, 3) or (3,), or ocp.spacecraft.Spacecraft
        J [kg·m²], or a `Spacecraft` (its wheels are used).
    q0, qf : array_like (4,)
        Initial and final attitude (scalar-first); the shorter rotation is
        taken.
    wheels : WheelArray, optional
        Wheel array (give this or ``torque_max``).
    torque_max : float or array_like (3,), optional
        Per-axis body torque bound [N·m].
    rate_max : float, optional
        Extra bound on the eigenaxis rate [rad/s].

    Returns
    -------
    EigenaxisSlew

    Raises
    ------
    InvalidValueError
        Bad arguments (both or neither actuator given, non-positive
        bounds, zero quaternions).
    InfeasibleError
        The actuators cannot turn the body about the eigenaxis.
    RankError
        They cannot, and the working wheels span fewer than 3 axes (the
        message gives the rank and the failed wheels, 1-based).
    """
    inertia, wheels, rate_max = slew_parts(inertia, wheels, rate_max)
    J = check_inertia(inertia)
    q0 = _unit_quat(q0, "q0")
    qf = _unit_quat(qf, "qf")
    if (wheels is None) == (torque_max is None):
        raise InvalidValueError(
            "give exactly one of wheels and torque_max")
    wcap = np.inf
    if rate_max is not None:
        wcap = as_finite_scalar(rate_max, "rate_max")
        check_positive(wcap, "rate_max")
    e, theta = rotation_between(q0, qf)
    if np.dot(q0, qf) < 0:
        qf = -qf
    Je = J @ e
    pattern = None
    if wheels is not None:
        pattern, s_star = _wheel_pattern(wheels, -Je)
        alpha = 1.0 / s_star
        with np.errstate(divide="ignore"):
            wcap = min(wcap, float(np.min(wheels.h_max / np.abs(pattern))))
    else:
        assert torque_max is not None     # exactly one of the two
        umax = as_vector(torque_max, 3, "torque_max")
        check_positive(umax, "torque_max")
        g = np.abs(np.cross(e, Je))
        aJe = np.abs(Je)
        with np.errstate(divide="ignore"):
            alpha = float(np.min(umax / (aJe + theta * g)))
            if alpha * theta > wcap ** 2:
                room = umax - wcap ** 2 * g
                if np.any(room <= 0):
                    raise InfeasibleError(
                        "rate_max: the gyroscopic torque at this rate "
                        "exceeds the torque box", problem=wcap)
                alpha = float(np.min(room / aJe))
    if theta == 0.0:
        return EigenaxisSlew(e, 0.0, alpha, wcap, 0.0, 0.0, 0.0, q0, qf, J,
                             pattern)
    if wcap ** 2 >= alpha * theta:  # bang-bang
        wp = float(np.sqrt(alpha * theta))
        tc = 0.0
    else:
        wp = wcap
        tc = theta / wp - wp / alpha
    ta = wp / alpha
    return EigenaxisSlew(axis=e, angle=theta, alpha=alpha, rate_max=wcap,
                         t_accel=ta, t_coast=tc, T=2 * ta + tc, q0=q0,
                         qf=qf, inertia=J, wheel_pattern=pattern)


def _feedback_step(model: SpacecraftModel, qf: np.ndarray, kp: np.ndarray,
                   kd: np.ndarray, dt: float, options: dict | None
                   ) -> ca.Function:
    """One sample of the closed loop: ``step(x, tau) -> (xf, u)``."""
    x = ca.MX.sym("x", model.nx)
    tau = ca.MX.sym("tau", 3)
    q, w = x[:4], x[4:7]
    qe = quat_mul(ca.DM(quat_conj(qf)), q)  # error, body frame
    qv = ca.sign(qe[0] + 1e-300) * qe[1:]
    J = ca.DM(model.inertia)
    if model.wheels is None:
        u_cmd = -ca.DM(kp) @ qv - ca.DM(kd) @ w + ca.cross(w, J @ w)
        assert model.torque_max is not None   # a wheel-less model's bound
        umax = ca.DM(model.torque_max)
        sigma = ca.fmax(1.0, ca.mmax(ca.fabs(u_cmd) / umax))
        u = u_cmd / sigma
    else:
        wh = model.wheels
        A = ca.DM(wh.axes)
        h = x[7:]
        # array torque demand M = A m: J ω̇ = -Kp qv - Kd ω (eq. of the law)
        M = ca.DM(kp) @ qv + ca.DM(kd) @ w - ca.cross(w, J @ w + A @ h)
        m_cmd = ca.DM(min_norm_gains(wh)) @ M
        mmax = ca.DM(wh.m_max)
        sigma = ca.fmax(1.0, ca.mmax(ca.fabs(m_cmd) / mmax))
        m = m_cmd / sigma
        hmax = ca.DM(wh.h_max)
        # a wheel at its momentum bound cannot be pushed further
        m = ca.if_else(h >= hmax, ca.fmin(m, 0), m)
        m = ca.if_else(h <= -hmax, ca.fmax(m, 0), m)
        u = m
    F = model.integrator(dt, "cvodes", options)
    xf = F(x0=x, p=ca.vertcat(u, tau))["xf"]
    return ca.Function("feedback_step", [x, tau], [xf, u],
                       ["x", "tau"], ["xf", "u"])


def quaternion_feedback_slew(inertia: ArrayLike | Spacecraft, q0: ArrayLike,
                             qf: ArrayLike, *,
                             wheels: WheelArray | None = None,
                             torque_max: ArrayLike | None = None,
                             natural_frequency: float,
                             damping: float = 0.9, t_final: float,
                             dt: float = 0.1, settle_angle: float = 1e-3,
                             options: dict | None = None) -> SlewTrajectory:
    """Quaternion-error PD slew with gyroscopic compensation, closed loop.

    The law (Wie, *Space Vehicle Dynamics and Control*, §7.3) asks for

    .. math::
        J\\dot ω = -K_p\\,\\mathrm{sign}(q_{e,0})\\,q_{e,v} - K_d ω,\\quad
        q_e = q_f^{*} \\otimes q,\\quad
        K_p = 2ω_n^2 J,\\; K_d = 2ζω_n J,

    i.e. the array torque :math:`A m = K_p q_{e,v} + K_d ω - ω\\times(Jω +
    A H_w)`, allocated by the minimum-norm law ([1] eq. 5) and
    scaled down as a whole when a wheel would exceed ``m_max`` (direction
    kept); a wheel at ``h_max`` cannot be pushed further. With a torque
    box the body torque :math:`-K_p q_{e,v} - K_d ω + ω\\times Jω` is
    scaled into the box. The controller is sampled every ``dt`` (ZOH) and
    the plant integrated by CVODES.

    Parameters
    ----------
    inertia, q0, qf, wheels, torque_max
        As `eigenaxis_slew` (initial rates and wheel momenta zero).
    natural_frequency : float
        ω_n [rad/s] of the small-angle closed loop.
    damping : float
        ζ [1].
    t_final : float
        Simulated time [s].
    dt : float
        Controller sample time [s].
    settle_angle : float
        The slew time T is the first time after which the error angle
        stays below this [rad].
    options : dict, optional
        CVODES options, forwarded untouched.

    Returns
    -------
    SlewTrajectory
        ``status`` is ``"settled"`` (``T`` the settling time) or
        ``"not_settled"`` (``T`` NaN, ``success`` False).
    """
    inertia, wheels, _ = spacecraft_parts(inertia, wheels)
    J = check_inertia(inertia)
    q0 = _unit_quat(q0, "q0")
    qf = _unit_quat(qf, "qf")
    wn = as_finite_scalar(natural_frequency, "natural_frequency")
    if not 0.0 < wn <= 1e3:
        raise InvalidValueError(
            f"natural_frequency must lie in (0, 1e3] rad/s, got {wn!r}")
    zeta = as_finite_scalar(damping, "damping")
    check_positive(zeta, "damping")
    t_final = as_finite_scalar(t_final, "t_final")
    check_positive(t_final, "t_final")
    dt = as_finite_scalar(dt, "dt")
    check_positive(dt, "dt")
    model = rigid_spacecraft(J, wheels, torque_max=torque_max)
    kp = 2.0 * wn ** 2 * J
    kd = 2.0 * zeta * wn * J
    step = _feedback_step(model, qf, kp, kd, dt, options)
    k = int(np.ceil(t_final / dt))
    sim = step.mapaccum("closed_loop", k)
    x0 = model.state(q0)
    out = sim(x0, np.zeros((3, k)))
    X = np.column_stack([x0, np.asarray(out[0])]).T
    U = np.asarray(out[1]).T
    t = dt * np.arange(k + 1)
    err = 2 * np.arccos(np.clip(np.abs(X[:, :4] @ qf), 0.0, 1.0))
    outside = np.flatnonzero(err >= settle_angle)
    if len(outside) == 0:
        T = 0.0
    elif outside[-1] < k:
        T = float(t[outside[-1] + 1])
    else:
        T = float("nan")
    settled = bool(np.isfinite(T))
    has_wheels = wheels is not None
    return SlewTrajectory(
        method="quaternion_feedback", T=T, t=t, q=X[:, :4], w=X[:, 4:7],
        torque=model.body_control_torque(U.T).T,
        wheel_torque=U if has_wheels else None,
        wheel_momentum=X[:, 7:] if has_wheels else None, qf=qf,
        status="settled" if settled else "not_settled", success=settled,
        extras={"natural_frequency": wn, "damping": zeta, "dt": dt,
                "settle_angle": settle_angle})
