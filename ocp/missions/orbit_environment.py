"""Orbit environment of [2] (theory §3): gravity gradient, dipole field.

Orbit frame (theory §3): X1 along the velocity, X3 along the radius vector,
X2 completing the right-handed triad (along the orbit normal r × v); on a
circular orbit it turns at :math:`ω_0 = \\sqrt{μ/r^3}` about X2. The
attitude quaternion ``q`` maps body vectors to the orbit frame and ``ω``
is the absolute body rate (body axes), so the rate relative to the orbit
frame is :math:`ω_{rel} = ω - R(q)^T ω_0 e_2`.

* Gravity gradient: :math:`M_{gr} = 3ω_0^2\\, E_3 \\times J E_3`,
  :math:`E_3 = R(q)^T e_3` the local vertical in body axes.
* Direct-dipole field in orbit axes (u the argument of latitude,
  :math:`B_0 = μ_e / r^3`): :math:`B_1 = B_0 \\sin i \\cos u`,
  :math:`B_2 = B_0 \\cos i`, :math:`B_3 = -2 B_0 \\sin i \\sin u`.
* Magnetic torque :math:`M = m \\times B` (coil dipole m [A·m²]).
* Damping law ("−Bdot"): :math:`m = -k\\, \\dot B_{body}`, each coil
  saturated at its dipole limit; a failed coil gives zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike
from adcs_common.results import ResultMixin

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_positive,
)

from adcs_common.quaternion import Vector, quat_rate, quat_to_dcm
from ocp.models.rigid import check_inertia

__all__ = [
    "EARTH_DIPOLE",
    "EARTH_MU",
    "BdotRun",
    "OrbitModel",
    "bdot_detumble",
    "orbit_wheel_law",
    "simulate_wheel_law",
    "dipole_field_orbit",
    "gravity_gradient_torque",
    "orbit_model",
    "orbit_rate",
]

#: Earth's gravitational parameter μ [m³/s²].
EARTH_MU = 3.986004418e14
#: Earth's dipole constant μ_e = (μ0/4π)·7.94e22 A·m² [T·m³].
EARTH_DIPOLE = 7.94e15


def orbit_rate(radius: float, mu: float = EARTH_MU) -> float:
    """Circular orbit rate :math:`ω_0 = \\sqrt{μ/r^3}` [rad/s]."""
    r = as_finite_scalar(radius, "radius")
    if not 1e3 <= r <= 1e12:
        raise InvalidValueError(
            f"radius must lie in [1e3, 1e12] m, got {radius!r}")
    return float(np.sqrt(mu / r ** 3))


def gravity_gradient_torque(inertia: ArrayLike, e3_body: Vector,
                            w0: float) -> Any:
    """Gravity-gradient torque :math:`3ω_0^2 E_3 \\times J E_3` [N·m].

    Works on numpy arrays and CasADi symbols.

    Parameters
    ----------
    inertia : array_like (3, 3)
        J [kg·m²].
    e3_body : shape (3,)
        Unit local vertical (radius direction) in body axes.
    w0 : float
        Orbit rate [rad/s].
    """
    if isinstance(e3_body, (ca.SX, ca.MX)):
        e3s: Any = e3_body       # SX or MX (the result is of that kind)
        J = ca.DM(np.asarray(inertia, dtype=float))
        return 3 * w0 ** 2 * ca.cross(e3s, J @ e3s)
    e3 = as_finite_array(e3_body, "e3_body", (3,))
    w0 = as_finite_scalar(w0, "w0")
    if not 0.0 <= w0 <= 1.0:
        raise InvalidValueError(f"w0 must lie in [0, 1] rad/s, got {w0!r}")
    return 3 * w0 ** 2 * np.cross(e3, as_finite_array(inertia, "inertia",
                                                       (3, 3)) @ e3)


def dipole_field_orbit(u: ArrayLike, inclination: float, radius: float,
                       dipole: float = EARTH_DIPOLE) -> Any:
    """Direct-dipole field in orbit axes [T] ([2], theory §3).

    Parameters
    ----------
    u : float, array or CasADi symbol
        Argument of latitude [rad].
    inclination : float
        Orbit inclination i [rad].
    radius : float
        Orbit radius [m].
    dipole : float
        μ_e [T·m³].

    Returns
    -------
    (3,) or (3, K) array, or CasADi column
    """
    b0 = dipole / radius ** 3
    si, ci = np.sin(inclination), np.cos(inclination)
    if isinstance(u, (ca.SX, ca.MX)):
        return ca.vertcat(b0 * si * ca.cos(u), b0 * ci + 0 * u,
                          -2 * b0 * si * ca.sin(u))
    u = np.asarray(u, dtype=float)
    return np.array([b0 * si * np.cos(u), b0 * ci * np.ones_like(u),
                     -2 * b0 * si * np.sin(u)])


@dataclass(frozen=True, eq=False)
class OrbitModel:
    """Rigid spacecraft on a circular orbit with coils (no wheels).

    Attributes
    ----------
    inertia : numpy.ndarray (3, 3)
        J [kg·m²].
    radius, inclination, w0, u0 : float
        Orbit radius [m], inclination [rad], rate [rad/s] and argument of
        latitude at t = 0 [rad].
    dynamics : casadi.Function
        ``dynamics(x, m, tau, t) -> (xdot)`` with ``x = (q, ω)``, ``m``
        the coil dipole [A·m²] (body), ``tau`` other torques [N·m].
    field_body : casadi.Function
        ``field_body(x, t) -> (B, Bdot)``: field in body axes [T] and its
        time derivative seen by the body [T/s].
    wheel_dynamics : casadi.Function
        ``wheel_dynamics(x, hdot, m, tau, t) -> (xdot)`` with
        ``x = (q, ω, H)`` (10), H the total wheel momentum in body axes
        [N·m·s] (three orthogonal pairs, Chibis-M) and ``hdot`` its body
        derivative: :math:`Jω̇ = -ω×(Jω + H) - \\dot H + M_{gr} + m×B + τ`.
    """

    inertia: np.ndarray
    radius: float
    inclination: float
    w0: float
    u0: float
    dynamics: ca.Function
    field_body: ca.Function
    wheel_dynamics: ca.Function

    def relative_rate(self, x: ArrayLike) -> np.ndarray:
        """Rate relative to the orbit frame, (3,) or (K, 3) [rad/s]."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        out = np.array([xi[4:7] - quat_to_dcm(xi[:4]).T @ [0, self.w0, 0]
                        for xi in x])
        return out[0] if out.shape[0] == 1 else out


def orbit_model(inertia: ArrayLike, *, radius: float = 6_850e3,
                inclination: float = np.deg2rad(51.7), u0: float = 0.0,
                dipole: float = EARTH_DIPOLE) -> OrbitModel:
    """Build the orbit model of [2] (Chibis-M orbit by default).

    Parameters
    ----------
    inertia : array_like (3, 3) or (3,)
        J [kg·m²] (Chibis-M before boom deployment: diag(1.02, 1.51, 1.73)).
    radius : float
        Circular orbit radius [m] (6850 km).
    inclination : float
        Inclination [rad] (51.7°).
    u0 : float
        Argument of latitude at t = 0 [rad].
    dipole : float
        Earth's dipole constant [T·m³].
    """
    J = check_inertia(inertia)
    w0 = orbit_rate(radius)
    inc = as_finite_scalar(inclination, "inclination")
    x = ca.SX.sym("x", 7)
    m = ca.SX.sym("m", 3)
    tau = ca.SX.sym("tau", 3)
    t = ca.SX.sym("t")
    q, w = x[:4], x[4:7]
    R = quat_to_dcm(q)  # orbit <- body
    w_rel = w - R.T @ ca.DM([0.0, w0, 0.0])
    e3 = R.T @ ca.DM([0.0, 0.0, 1.0])
    u = u0 + w0 * t
    B_orb = dipole_field_orbit(u, inc, radius, dipole)
    B = R.T @ B_orb
    torque = gravity_gradient_torque(J, e3, w0) + ca.cross(m, B) + tau
    Jinv = ca.DM(np.linalg.inv(J))
    wdot = Jinv @ (-ca.cross(w, ca.DM(J) @ w) + torque)
    xdot = ca.vertcat(quat_rate(q, w_rel), wdot)
    dyn = ca.Function("orbit_dynamics", [x, m, tau, t], [xdot],
                      ["x", "m", "tau", "t"], ["xdot"])
    # dB/dt seen by the body: d/dt (R^T B_orb) along the motion
    xdot0 = dyn(x, ca.DM.zeros(3), ca.DM.zeros(3), t)
    Bdot = ca.jtimes(B, x, xdot0) + ca.jacobian(B, t)
    fb = ca.Function("field_body", [x, t], [B, Bdot], ["x", "t"],
                     ["B", "Bdot"])
    # the same with wheels: state (q, ω, H), control Ḣ (body derivative)
    xh = ca.SX.sym("x", 10)
    hdot = ca.SX.sym("hdot", 3)
    qh, wh, H = xh[:4], xh[4:7], xh[7:10]
    Rh = quat_to_dcm(qh)
    wh_rel = wh - Rh.T @ ca.DM([0.0, w0, 0.0])
    Mh = (gravity_gradient_torque(J, Rh.T @ ca.DM([0.0, 0.0, 1.0]), w0)
          + ca.cross(m, Rh.T @ B_orb) + tau)
    whdot = Jinv @ (-ca.cross(wh, ca.DM(J) @ wh + H) - hdot + Mh)
    dyn_h = ca.Function(
        "orbit_wheel_dynamics", [xh, hdot, m, tau, t],
        [ca.vertcat(quat_rate(qh, wh_rel), whdot, hdot)],
        ["x", "hdot", "m", "tau", "t"], ["xdot"])
    return OrbitModel(J, float(radius), inc, w0, float(u0), dyn, fb,
                      dyn_h)


def orbit_wheel_law(model: OrbitModel, k_omega: float,
                      k_a: float) -> ca.Function:
    """Nominal wheel law of [2], eq. (1.8).

    .. math::
        \\dot H + ω \\times H = k_ω ω_{rel} + k_a S - ω \\times Jω
        - J \\dot A ω_0,\\quad
        S = (a_{23} - a_{32},\\; a_{31} - a_{13},\\; a_{12} - a_{21})

    with A the direction-cosine matrix body ← orbit and
    :math:`A ω_0 = ω_0 A e_2` the orbit rate in body axes, so
    :math:`\\dot A ω_0 = (ω_0 A e_2) \\times ω_{rel}`. The last term is
    read from the extraction (theory §3 omits it): with it the closed loop is
    exactly :math:`J \\dot ω_{rel} = -k_ω ω_{rel} - k_a S + M_{ext}`.

    Parameters
    ----------
    model : OrbitModel
    k_omega, k_a : float
        Positive gains [N·m·s], [N·m].

    Returns
    -------
    casadi.Function
        ``law(x, t) -> (hdot)`` for ``x = (q, ω, H)``.
    """
    k_omega = as_finite_scalar(k_omega, "k_omega")
    check_positive(k_omega, "k_omega")
    k_a = as_finite_scalar(k_a, "k_a")
    check_positive(k_a, "k_a")
    x = ca.SX.sym("x", 10)
    t = ca.SX.sym("t")
    q, w, H = x[:4], x[4:7], x[7:10]
    A = quat_to_dcm(q).T  # body <- orbit
    hdot = orbit_wheel_law_expr(model.inertia, model.w0, A, w, H,
                                  k_omega, k_a)
    return ca.Function("orbit_wheel_law", [x, t], [hdot], ["x", "t"],
                       ["hdot"])


def orbit_wheel_law_expr(inertia, w0: float, A, w, H, k_omega, k_a):
    """Right-hand side of eq. (1.8), the wheel momentum rate Ḣ (3,).

    The expression `orbit_wheel_law` wraps (and `magnetic_boom` uses with
    symbolic gains): ``A`` the direction-cosine matrix body ← orbit (3, 3),
    ``w`` the absolute body rate [rad/s], ``H`` the wheel momentum
    [N·m·s], gains numbers or casadi symbols. Returns a casadi SX (3,)
    [N·m].
    """
    w_orb = w0 * A[:, 1]
    w_rel = w - w_orb
    S = ca.vertcat(A[1, 2] - A[2, 1], A[2, 0] - A[0, 2], A[0, 1] - A[1, 0])
    J = ca.DM(inertia)
    return (-ca.cross(w, H) + k_omega * w_rel + k_a * S
            - ca.cross(w, J @ w) - J @ ca.cross(w_orb, w_rel))


@dataclass(frozen=True, eq=False, repr=False)
class BdotRun(ResultMixin):
    """Closed-loop −Bdot detumbling trajectory.

    Attributes
    ----------
    t : numpy.ndarray (K + 1,)
        Time [s].
    x : numpy.ndarray (K + 1, 7)
        States (q, ω).
    dipole : numpy.ndarray (K, 3)
        Coil dipoles held over each interval [A·m²].
    extras : dict
        Gain, limits, failed coils.
    """

    t: np.ndarray
    x: np.ndarray
    dipole: np.ndarray
    extras: dict = field(default_factory=dict)

    @property
    def w(self) -> np.ndarray:
        """Absolute body rates (K + 1, 3) [rad/s]."""
        return self.x[:, 4:7]

    def plot(self, axes: Any | None = None) -> Any:
        """Plot body rates and coil dipoles; return the figure."""
        import matplotlib.pyplot as plt

        if axes is None:
            fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
        else:
            fig = axes[0].figure
        axes[0].plot(self.t, self.w)
        axes[0].set_ylabel("ω [rad/s]")
        axes[0].legend(["x", "y", "z"], loc="best")
        axes[1].step(self.t[:-1], self.dipole, where="post")
        axes[1].set_ylabel("dipole [A·m²]")
        axes[1].set_xlabel("t [s]")
        return fig


def bdot_dipole(Bdot, gain, dipole_max, coils):
    """Return the −Bdot dipole, coil by coil: ``coils * sat(-gain Bdot)``.

    ``Bdot`` the field rate seen by the body [T/s] (3,), ``gain`` k
    [A·m²·s/T], ``dipole_max`` the saturation per coil [A·m²], ``coils``
    1 for a working and 0 for a failed coil (3,). Numbers or casadi
    symbols; `bdot_detumble` and `ocp.missions.magnetic_boom` share it.
    """
    return coils * ca.fmin(ca.fmax(-gain * Bdot, -dipole_max), dipole_max)


def bdot_detumble(model: OrbitModel, x0: ArrayLike, *, t_final: float,
                  gain: float, dipole_max: ArrayLike = 3.2, dt: float = 1.0,
                  failed_coils: Sequence[int] = ()) -> BdotRun:
    """Simulate the −Bdot damping law in closed loop (CVODES, ZOH).

    .. math:: m = \\mathrm{sat}_{m_{max}}(-k\\,\\dot B_{body})

    computed per coil and saturated per coil; the coils in
    ``failed_coils`` (0-based) give no dipole.

    Parameters
    ----------
    model : OrbitModel
    x0 : array_like (7,)
        Initial (q, ω).
    t_final : float
        Duration [s].
    gain : float
        k [A·m²·s/T].
    dipole_max : float or array_like (3,)
        Coil limits [A·m²] (Chibis-M: 3.2).
    dt : float
        Control sample time [s].
    failed_coils : sequence of int
        Coils off.

    Returns
    -------
    BdotRun
    """
    x0 = as_vector(x0, 7, "x0")
    k = as_finite_scalar(gain, "gain")
    check_positive(k, "gain")
    mmax = as_vector(dipole_max, 3, "dipole_max")
    check_positive(mmax, "dipole_max")
    dt = as_finite_scalar(dt, "dt")
    check_positive(dt, "dt")
    t_final = as_finite_scalar(t_final, "t_final")
    check_positive(t_final, "t_final")
    on = np.ones(3)
    for c in failed_coils:
        if c not in (0, 1, 2):
            raise InvalidValueError(
                f"failed_coils must hold 0, 1 or 2, got {c!r}")
        on[c] = 0.0
    x = ca.MX.sym("x", 7)
    t = ca.MX.sym("t")
    _, Bdot = model.field_body(x, t)
    m = bdot_dipole(Bdot, k, ca.DM(mmax), ca.DM(on))
    tt = ca.MX.sym("tt")
    xs = ca.MX.sym("xs", 7)
    p = ca.MX.sym("p", 4)  # dipole (3), start time of the interval
    ode = model.dynamics(xs, p[:3], ca.DM.zeros(3), p[3] + tt)
    F = ca.integrator("bdot", "cvodes", {"x": xs, "p": p, "t": tt,
                                         "ode": ode}, 0.0, dt,
                      {"abstol": 1e-10, "reltol": 1e-8})
    xf = F(x0=x, p=ca.vertcat(m, t))["xf"]
    n = int(np.ceil(t_final / dt - 1e-9))
    times = dt * np.arange(n + 1)
    X = np.empty((n + 1, 7))
    X[0] = x0
    sim = ca.Function("bdot_sim", [x, t], [xf, m])
    mapped = sim.mapaccum("bdot_run", n, [0], [0])
    out = mapped(x0, times[:-1][None, :])
    X[1:] = np.asarray(out[0]).T
    M = np.asarray(out[1]).T
    return BdotRun(t=times, x=X, dipole=M,
                   extras={"gain": k, "dipole_max": mmax,
                           "failed_coils": tuple(failed_coils), "dt": dt})


def simulate_wheel_law(model: OrbitModel, law: ca.Function, x0: ArrayLike, *,
                       t_final: float, dt: float = 1.0) -> tuple[
                           np.ndarray, np.ndarray]:
    """Integrate the orbit model with wheels under ``law`` (CVODES).

    Parameters
    ----------
    model : OrbitModel
    law : casadi.Function
        ``law(x, t) -> (hdot)``, e.g. `orbit_wheel_law`.
    x0 : array_like (10,)
        Initial ``(q, ω, H)``.
    t_final, dt : float
        Duration and output step [s].

    Returns
    -------
    t : numpy.ndarray (K + 1,)
    x : numpy.ndarray (K + 1, 10)
    """
    x0 = as_vector(x0, 10, "x0")
    t_final = as_finite_scalar(t_final, "t_final")
    check_positive(t_final, "t_final")
    dt = as_finite_scalar(dt, "dt")
    check_positive(dt, "dt")
    n = int(np.ceil(t_final / dt - 1e-9))
    times = dt * np.arange(n + 1)
    x = ca.MX.sym("x", 10)
    t = ca.MX.sym("t")
    ode = model.wheel_dynamics(x, law(x, t), ca.DM.zeros(3),
                               ca.DM.zeros(3), t)
    F = ca.integrator("wheel_law", "cvodes", {"x": x, "t": t, "ode": ode},
                      0.0, times[1:], {"abstol": 1e-11, "reltol": 1e-9})
    X = np.asarray(F(x0=x0)["xf"]).T
    return times, np.vstack([x0, X])
