"""[3]: spacecraft with four wheels from Lagrange's equations.

Kulik, Gordin, Reznikova, "Nonlinear model of the spacecraft with four
reaction wheels" ([3], theory §3). Generalised coordinates
``q = (γ, ψ, ϑ, φ_1..φ_4)``: the Euler–Krylov angles of the body (roll γ
about X, yaw ψ about Y, pitch ϑ about Z, eq. 1) and the rotor angles
relative to the body. The kinetic energy (eqs. 4–9, centre-of-mass
velocity V = 0)

.. math::
    2T = ω^T I ω + \\sum_i \\big[(ω + \\dot φ_i a_i)^T I_{M,i}
         (ω + \\dot φ_i a_i) + m_i |ω \\times r_i|^2\\big],\\quad
    I_{M,i} = I_{t,i}(1 - a_i a_i^T) + I_{s,i} a_i a_i^T

is differentiated by CasADi (automatic differentiation) in Lagrange's
equations of the second kind (eqs. 11–12):

.. math::
    \\frac{d}{dt}\\frac{\\partial T}{\\partial \\dot q}
    - \\frac{\\partial T}{\\partial q} = Q,\\quad
    Q = (E(q)^T τ_{ext},\\; m_1, \\dots, m_4),

``E`` the matrix of eq. (1) (``ω = E \\dot q_{1:3}``) and ``m_i`` the
motor torques. The result equals the Newton–Euler model of
`ocp.models.rigid.rigid_spacecraft` with
:math:`J = I + \\sum_i [I_{t,i}(1 - a_ia_i^T) + m_i(|r_i|^2 - r_ir_i^T)]`
and :math:`H_{w,i} = I_{s,i}(a_i\\cdot ω + \\dot φ_i)`.

Wheel 17M71 (NPC Polyus): ±4.27 N·m·s at ±3500 rpm (366.5 rad/s), so
:math:`I_s = 4.27/366.5 = 0.01165` kg·m², torque 0.034 N·m. Not given by
the paper and assumed here: transverse inertia :math:`I_t = I_s/2` (thin
disc), rotor mass 3 kg (it only matters with offsets r_i, zero in the
paper's run).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike
from adcs_common.results import ResultMixin

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_nonnegative,
    check_positive,
)
from allocation import WheelArray, min_norm_gains

from ocp.models.angles import body_rates_from_angle_rates, quat_from_ek
from ocp.models.rigid import SpacecraftModel, check_inertia, rigid_spacecraft

__all__ = [
    "FOUR_WHEEL_INERTIA",
    "FourWheelRun",
    "FourWheelCraft",
    "four_wheel_run",
    "four_wheel_craft",
]

#: Body inertia of [3] [kg·m²] (products of inertia zero).
FOUR_WHEEL_INERTIA = np.diag([86.215, 85.070, 113.565])
#: 17M71 wheel: momentum [N·m·s], speed [rad/s], torque [N·m].
WHEEL_17M71 = {"h_max": 4.27, "speed_max": 3500 * 2 * np.pi / 60,
               "m_max": 0.034}


@dataclass(frozen=True, eq=False)
class FourWheelCraft:
    """The [3] spacecraft: body, four wheels, both models.

    Attributes
    ----------
    body_inertia : numpy.ndarray (3, 3)
        Inertia of the body without the rotors, I [kg·m²].
    wheels : WheelArray
        Spin axes a_i and limits (17M71 by default).
    spin_inertia, transverse_inertia, mass : numpy.ndarray (4,)
        Rotor I_s, I_t [kg·m²] and mass m_i [kg].
    offsets : numpy.ndarray (3, 4)
        Rotor centres r_i from the centre of mass [m].
    lagrange : casadi.Function
        ``lagrange(x, u, tau) -> (xdot)``, ``x = (q, q̇)`` (14), ``u`` the
        motor torques (4), ``tau`` the external torque (3) [N·m].
    kinetic_energy : casadi.Function
        ``T(q, qdot) -> (T)`` [J].
    newton_euler : SpacecraftModel
        The equivalent quaternion model with ``J`` as in the module doc.
    """

    body_inertia: np.ndarray
    wheels: WheelArray
    spin_inertia: np.ndarray
    transverse_inertia: np.ndarray
    mass: np.ndarray
    offsets: np.ndarray
    lagrange: ca.Function
    kinetic_energy: ca.Function
    newton_euler: SpacecraftModel

    @property
    def inertia(self) -> np.ndarray:
        """Newton–Euler inertia J (3, 3) [kg·m²] (rotor spin excluded)."""
        return self.newton_euler.inertia

    def to_newton_euler(self, x: ArrayLike) -> np.ndarray:
        """Map a Lagrange state (q, q̇) (14,) to ``(quat, ω, H_w)`` (11,)."""
        x = as_vector(x, 14, "x")
        ang, rates = x[:3], x[7:10]
        w = body_rates_from_angle_rates(ang, rates)
        h = self.spin_inertia * (self.wheels.axes.T @ w + x[10:14])
        return np.concatenate([quat_from_ek(ang), w, h])


def _skew_sq(r: np.ndarray) -> np.ndarray:
    return float(r @ r) * np.eye(3) - np.outer(r, r)


def four_wheel_craft(*, body_inertia: ArrayLike = FOUR_WHEEL_INERTIA,
                       wheels: WheelArray | None = None,
                       spin_inertia: ArrayLike | None = None,
                       transverse_inertia: ArrayLike | None = None,
                       mass: ArrayLike = 3.0,
                       offsets: ArrayLike | None = None) -> FourWheelCraft:
    """Build the [3] spacecraft (Lagrange and Newton–Euler models).

    Parameters
    ----------
    body_inertia : array_like (3, 3) or (3,)
        Body inertia I [kg·m²] (default the paper's diagonal).
    wheels : WheelArray, optional
        Default: three wheels on the axes plus the paper's skewed one
        (45° angles, axis (0.5, 0.5, -0.7071)) with 17M71 limits.
    spin_inertia : float or array_like (4,), optional
        I_s [kg·m²]; default ``h_max / speed_max`` of the 17M71.
    transverse_inertia : float or array_like (4,), optional
        I_t [kg·m²]; default ``I_s / 2`` (assumed, thin disc).
    mass : float or array_like (4,)
        Rotor masses [kg] (assumed 3 kg).
    offsets : array_like (3, 4), optional
        Rotor centres r_i [m]; zero in the paper's run.

    Returns
    -------
    FourWheelCraft
    """
    I_body = check_inertia(body_inertia, "body_inertia")
    if wheels is None:
        wheels = WheelArray.orthogonal_plus_skew(
            h_max=WHEEL_17M71["h_max"], m_max=WHEEL_17M71["m_max"])
    n = wheels.n_wheels
    Is = (np.full(n, WHEEL_17M71["h_max"] / WHEEL_17M71["speed_max"])
          if spin_inertia is None else as_vector(spin_inertia, n,
                                                  "spin_inertia"))
    check_positive(Is, "spin_inertia")
    It = (Is / 2.0 if transverse_inertia is None
          else as_vector(transverse_inertia, n, "transverse_inertia"))
    check_nonnegative(It, "transverse_inertia")
    mass = as_vector(mass, n, "mass")
    check_nonnegative(mass, "mass")
    r = (np.zeros((3, n)) if offsets is None
         else as_finite_array(offsets, "offsets", (3, n)))
    A = np.array(wheels.axes)

    # --- kinetic energy ([3] eqs. 4-9) and Lagrange's equations
    q = ca.SX.sym("q", 3 + n)
    qd = ca.SX.sym("qdot", 3 + n)
    w = body_rates_from_angle_rates(q[:3], qd[:3])  # eq. (1)
    T = 0.5 * ca.dot(w, ca.DM(I_body) @ w)
    for i in range(n):
        a = ca.DM(A[:, i])
        IM = It[i] * (np.eye(3) - np.outer(A[:, i], A[:, i])) \
            + Is[i] * np.outer(A[:, i], A[:, i])
        wi = w + qd[3 + i] * a
        T += 0.5 * ca.dot(wi, ca.DM(IM) @ wi)
        v = ca.cross(w, ca.DM(r[:, i]))
        T += 0.5 * mass[i] * ca.dot(v, v)
    u = ca.SX.sym("u", n)
    tau = ca.SX.sym("tau", 3)
    E = ca.jacobian(w, qd[:3])  # ω = E(q) q̇_{1:3}
    Q = ca.vertcat(E.T @ tau, ca.DM(wheels.scale * wheels.active) * u)
    dTdqd = ca.gradient(T, qd)
    M = ca.jacobian(dTdqd, qd)
    rhs = Q - ca.jacobian(dTdqd, q) @ qd + ca.gradient(T, q)
    qdd = ca.solve(M, rhs)
    x = ca.vertcat(q, qd)
    lag = ca.Function("lagrange", [x, u, tau], [ca.vertcat(qd, qdd)],
                      ["x", "u", "tau"], ["xdot"])
    Tf = ca.Function("kinetic_energy", [q, qd], [T], ["q", "qdot"], ["T"])
    J = I_body + sum(It[i] * (np.eye(3) - np.outer(A[:, i], A[:, i]))
                     + mass[i] * _skew_sq(r[:, i]) for i in range(n))
    ne = rigid_spacecraft(J, wheels)
    return FourWheelCraft(I_body, wheels, Is, It, mass, r, lag, Tf, ne)


def _step_disturbance(axis: int, amplitude: float
                      ) -> Callable[[float], np.ndarray]:
    def tau(t: float) -> np.ndarray:
        out = np.zeros(3)
        out[axis] = amplitude
        return out
    return tau


@dataclass(frozen=True, eq=False, repr=False)
class FourWheelRun(ResultMixin):
    """Trajectories of a [3] simulation.

    Attributes
    ----------
    t : numpy.ndarray (K + 1,)
        Time [s].
    angles : numpy.ndarray (K + 1, 3)
        Roll γ, yaw ψ, pitch ϑ [rad].
    w : numpy.ndarray (K + 1, 3)
        Body rates [rad/s].
    wheel_speed : numpy.ndarray (K + 1, 4)
        Rotor speeds relative to the body φ̇_i [rad/s].
    wheel_momentum : numpy.ndarray (K + 1, 4)
        H_w,i = I_s (a_i·ω + φ̇_i) [N·m·s].
    disturbance : numpy.ndarray (K, 3)
        External torque held over each interval [N·m].
    wheel_torque : numpy.ndarray (K + 1, 4)
        Motor torques of the stabilisation law at the samples [N·m]
        (zeros in open loop).
    extras : dict
        Settings (controller, tolerances, integrator).
    """

    t: np.ndarray
    angles: np.ndarray
    w: np.ndarray
    wheel_speed: np.ndarray
    wheel_momentum: np.ndarray
    disturbance: np.ndarray
    wheel_torque: np.ndarray
    extras: dict = field(default_factory=dict)

    def plot(self, axes: Any | None = None) -> Any:
        """Angles [deg], body rates, wheel speeds (the paper's figs. 6-8).

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        if axes is None:
            fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 8))
        else:
            fig = axes[0].figure
        axes[0].plot(self.t, np.rad2deg(self.angles))
        axes[0].legend(["γ roll", "ψ yaw", "ϑ pitch"], loc="best")
        axes[0].set_ylabel("angles [deg]")
        axes[1].plot(self.t, self.w)
        axes[1].legend(["ωx", "ωy", "ωz"], loc="best")
        axes[1].set_ylabel("body rates [rad/s]")
        axes[2].plot(self.t, self.wheel_speed)
        axes[2].legend([f"RW{i + 1}" for i in range(
            self.wheel_speed.shape[1])], loc="best")
        axes[2].set_ylabel("wheel speeds [rad/s]")
        axes[2].set_xlabel("t [s]")
        return fig


def four_wheel_run(spacecraft: FourWheelCraft | None = None, *,
                t_final: float = 150.0, dt: float = 0.5,
                disturbance: Callable[[float], np.ndarray] | None = None,
                disturbance_axis: int = 0, amplitude: float = 1e-2,
                controller: str = "none", natural_frequency: float = 0.05,
                damping: float = 0.9, x0: ArrayLike | None = None,
                reltol: float = 0.01,
                abstol: float = 1e-6) -> FourWheelRun:
    """Reproduce the [3] run: response to disturbance torques.

    The paper integrates its Lagrange model for 150 s with Gear's method
    (ode15s, relative tolerance 0.01, absolute 1e-6) under disturbance
    torques up to ±1e-2 N·m per axis (its fig. 5, lost in extraction);
    its angles stay within ±80° and the wheel speeds within ±366 rad/s.
    Here the Lagrange model is integrated by CVODES (BDF, the same family)
    with the same default tolerances. The default disturbance is a step of
    ``amplitude`` on ``disturbance_axis`` (assumed: with free wheels a
    1e-2 N·m step turns the body by 74.8° about X in 150 s, inside the
    paper's ±80°).

    Parameters
    ----------
    spacecraft : FourWheelCraft, optional
        Default `four_wheel_craft()`.
    t_final, dt : float
        Duration and output / disturbance-sampling step [s].
    disturbance : callable, optional
        ``tau(t) -> (3,)`` [N·m], sampled at interval midpoints and held.
    disturbance_axis : {0, 1, 2}
        Axis of the default step disturbance.
    amplitude : float
        Size of the default step [N·m].
    controller : {"none", "pd"}
        ``"none"``: free wheels (m = 0), the open-loop response;
        ``"pd"``: stabilisation by the wheels, body torque
        ``-J(2ω_n² θ + 2ζω_n ω)`` (θ the angles) allocated by the
        minimum-norm law and scaled into ``|m_i| <= m_max``.
    natural_frequency, damping : float
        ω_n [rad/s] and ζ of the ``"pd"`` law.
    x0 : array_like (14,), optional
        Initial Lagrange state (angles, rotor angles, their rates); rest
        by default.
    reltol, abstol : float
        CVODES tolerances (paper's by default).

    Returns
    -------
    FourWheelRun
    """
    sc = four_wheel_craft() if spacecraft is None else spacecraft
    t_final = as_finite_scalar(t_final, "t_final")
    check_positive(t_final, "t_final")
    dt = as_finite_scalar(dt, "dt")
    check_positive(dt, "dt")
    if t_final / dt > 1e7:
        raise InvalidValueError(
            f"t_final / dt = {t_final / dt:.3g} samples: at most 1e7")
    if controller not in ("none", "pd"):
        raise InvalidValueError(
            f"controller must be 'none' or 'pd', got {controller!r}")
    if disturbance is None:
        if disturbance_axis not in (0, 1, 2):
            raise InvalidValueError(
                f"disturbance_axis must be 0, 1 or 2, got "
                f"{disturbance_axis!r}")
        disturbance = _step_disturbance(
            disturbance_axis, as_finite_scalar(amplitude, "amplitude"))
    n = sc.wheels.n_wheels
    nq = 3 + n
    x0 = np.zeros(2 * nq) if x0 is None else as_vector(x0, 2 * nq, "x0")
    xs = ca.MX.sym("x", 2 * nq)
    tau = ca.MX.sym("tau", 3)
    if controller == "pd":
        J = sc.inertia
        wn = as_finite_scalar(natural_frequency, "natural_frequency")
        zeta = as_finite_scalar(damping, "damping")
        check_positive(wn, "natural_frequency")
        check_positive(zeta, "damping")
        w_b = body_rates_from_angle_rates(xs[:3], xs[nq:nq + 3])
        torque = -ca.DM(J) @ (2 * wn ** 2 * xs[:3] + 2 * zeta * wn * w_b)
        m_cmd = -ca.DM(min_norm_gains(sc.wheels)) @ torque  # -A m = τ
        mmax = ca.DM(sc.wheels.m_max)
        m = m_cmd / ca.fmax(1.0, ca.mmax(ca.fabs(m_cmd) / mmax))
    else:
        m = ca.MX.zeros(n)
    law = ca.Function("law", [xs], [m])
    ode = sc.lagrange(xs, m, tau)
    F = ca.integrator("four_wheel", "cvodes", {"x": xs, "p": tau, "ode": ode},
                      0.0, dt, {"reltol": float(reltol),
                                "abstol": float(abstol)})
    k = int(np.ceil(t_final / dt - 1e-9))
    t = dt * np.arange(k + 1)
    taus = np.array([as_vector(disturbance(ti + dt / 2), 3, "disturbance")
                     for ti in t[:-1]])
    out = F.mapaccum("run", k)(x0=x0, p=taus.T)
    X = np.column_stack([x0, np.asarray(out["xf"])]).T
    angles = X[:, :3]
    rates = X[:, nq:nq + 3]
    w = np.array([body_rates_from_angle_rates(a, r)
                  for a, r in zip(angles, rates)])
    wheel_speed = X[:, nq + 3:]
    hw = sc.spin_inertia * (w @ sc.wheels.axes + wheel_speed)
    mt = np.asarray(law.map(k + 1)(X.T)).T
    return FourWheelRun(t=t, angles=angles, w=w, wheel_speed=wheel_speed,
                      wheel_momentum=hw, disturbance=taus, wheel_torque=mt,
                      extras={"controller": controller, "reltol": reltol,
                              "abstol": abstol, "integrator": "cvodes"})
