"""Rigid spacecraft with wheels, a torque box or thrusters (theory §3).

State ``x = (q, ω, H_w)``: attitude quaternion ``q`` (4, scalar-first,
body to reference), body rate ``ω`` (3) [rad/s] and the wheel momenta
``H_w`` (N) [N·m·s], each the absolute angular momentum of rotor ``i``
along its spin axis. Control ``u``: the motor torques ``m`` (N) [N·m]
acting on the rotors. Dynamics (theory §3):

.. math::
    J\\dot ω = -ω \\times (Jω + A H_w) - A m + τ_{ext},\\qquad
    \\dot H_w = m,\\qquad \\dot q = \\tfrac12 q \\otimes (0, ω)

``J`` is the inertia of the whole spacecraft with the rotors' spin-axis
inertia excluded (their momentum is in ``H_w``). Without wheels the state
is ``(q, ω)`` and ``u`` is a body torque (3) [N·m] bounded per axis (an
ideal torque box): :math:`J\\dot ω = -ω\\times Jω + u + τ_{ext}`.

A thruster set (`thrusters.ThrusterSet`, e.g. [4]'s six-engine unit)
adds its duty fractions ``k`` (n_t) in [0, 1] to the controls, after the
wheel torques: ``u = (m, k)``. It acts through its mean torque over a
pulse cycle, :math:`τ_{thr} = T k` with ``T = torque_matrix()`` ([4]
eqs. 5-6), on the right-hand side of the body equation. That is the
cycle-averaged model, valid when the cycle is short against the attitude
motion; the pulses themselves are in `thrusters.scenarios`.
"""

from __future__ import annotations

from typing import Any

from dataclasses import dataclass
import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError, SolverError
from adcs_common.validation import as_finite_array, as_vector, check_positive
from allocation import WheelArray
from thrusters import ThrusterSet

from ocp.spacecraft.definition import Spacecraft, spacecraft_parts

from adcs_common.rigid_body import body_rates, check_inertia
from adcs_common.quaternion import quat_rate, quat_to_dcm
from ocp.models.angles import ek_angle_rates

__all__ = [
    "SpacecraftModel",
    "check_inertia",
    "dynamics_numpy",
    "euler_krylov_model",
    "rigid_spacecraft",
]


def effective_torque_matrix(wheels: WheelArray) -> tuple[np.ndarray,
                                                           np.ndarray]:
    """(axes A (3, N), per-wheel torque factor scale·active (N,))."""
    return np.array(wheels.axes), wheels.scale * wheels.active


def dynamics_numpy(inertia: ArrayLike, x: ArrayLike, u: ArrayLike,
                   tau_ext: ArrayLike | None = None, axes: Any | None = None,
                   torque_factor: ArrayLike | None = None,
                   thruster_torque: ArrayLike | None = None) -> np.ndarray:
    """Numpy reference of `SpacecraftModel.dynamics` (independent code).

    Parameters
    ----------
    inertia : array_like (3, 3)
        Inertia J [kg·m²].
    x : array_like (7 + N,)
        State (q, ω, H_w).
    u : array_like (N,) or (3,)
        Motor torques m [N·m], or the body torque when ``axes`` is None.
    tau_ext : array_like (3,), optional
        External torque [N·m].
    axes : array_like (3, N), optional
        Wheel axes A; None for the torque-box model.
    torque_factor : array_like (N,), optional
        Actual / commanded torque per wheel (0 for a failed wheel).
    thruster_torque : array_like (3, n_t), optional
        Mean torque per unit duty of a thruster set [N·m]; the last n_t
        entries of ``u`` are then its duties.
    """
    J = np.asarray(inertia, dtype=float)
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    tau = np.zeros(3) if tau_ext is None else np.asarray(tau_ext, float)
    if thruster_torque is not None:
        T = np.asarray(thruster_torque, dtype=float)
        tau = tau + T @ u[len(u) - T.shape[1]:]
        u = u[:len(u) - T.shape[1]]
    q, w = x[:4], x[4:7]
    if axes is None:
        box = u if len(u) else np.zeros(3)
        qdot, wdot = body_rates(J, q, w, np.zeros(3), tau + box,
                                np.zeros(3))
        return np.concatenate([qdot, wdot])
    A = np.asarray(axes, dtype=float)
    m = u if torque_factor is None else np.asarray(torque_factor) * u
    qdot, wdot = body_rates(J, q, w, A @ x[7:], tau, A @ m)
    return np.concatenate([qdot, wdot, m])


@dataclass(frozen=True, eq=False)
class SpacecraftModel:
    """Symbolic rigid spacecraft with wheels, a torque box or thrusters.

    Build with `rigid_spacecraft`. The CasADi Functions have named inputs
    and outputs; states and controls follow the module docstring.

    Attributes
    ----------
    inertia : numpy.ndarray, shape (3, 3)
        J [kg·m²].
    wheels : WheelArray or None
        The wheel array; None for the torque-box model.
    torque_max : numpy.ndarray (3,) or None
        Per-axis bound of the body torque box [N·m] (torque-box model).
    dynamics : casadi.Function
        ``dynamics(x, u, tau) -> (xdot)``.
    thrusters : thrusters.ThrusterSet or None
        Thruster set whose duties end ``u`` (cycle-averaged torque).
    """

    inertia: np.ndarray
    wheels: WheelArray | None
    torque_max: np.ndarray | None
    dynamics: ca.Function
    thrusters: ThrusterSet | None = None

    @property
    def nx(self) -> int:
        """State dimension: 7 + N with wheels, 7 without."""
        return self.dynamics.size1_in(0)

    @property
    def nu(self) -> int:
        """Control dimension: N wheels or 3 (torque box), plus n_t duties."""
        return self.dynamics.size1_in(1)

    @property
    def n_wheels(self) -> int:
        """Number of wheels (0 for the torque box)."""
        return 0 if self.wheels is None else self.wheels.n_wheels

    @property
    def n_thrusters(self) -> int:
        """Number of thrusters (0 without a thruster set)."""
        return 0 if self.thrusters is None else self.thrusters.n

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(lb, ub)`` of ``u``, each (nu,).

        ``±m_max`` for working wheels (0 for failed ones), ``±torque_max``
        for the torque box [N·m], ``[0, 1]`` for thruster duties.
        """
        lo, hi = [], []
        if self.wheels is not None:
            m = np.asarray(self.wheels.m_max, dtype=float) * \
                self.wheels.active
            lo.append(-m)
            hi.append(m)
        elif self.torque_max is not None:
            lo.append(-self.torque_max)
            hi.append(np.array(self.torque_max))
        if self.thrusters is not None:
            lo.append(np.zeros(self.n_thrusters))
            hi.append(np.ones(self.n_thrusters))
        return np.concatenate(lo), np.concatenate(hi)

    def body_control_torque(self, u: ArrayLike) -> np.ndarray:
        """Control torque on the body [N·m], (3,) or (3, K).

        ``-A diag(s) m`` for wheels (the reaction of the rotors), ``u`` for
        the torque box, plus ``T k`` for thruster duties ``k``.
        """
        u = np.asarray(u, dtype=float)
        nt = self.n_thrusters
        own = u[:self.nu - nt]
        if self.wheels is None:
            out = own if self.torque_max is not None else np.zeros(
                (3,) + u.shape[1:])
        else:
            out = -self.wheels.body_torque(own)
        if self.thrusters is not None:       # nt > 0
            out = out + self.thrusters.torque_matrix() @ u[self.nu - nt:]
        return out

    def state(self, q: ArrayLike, w: ArrayLike | None = None,
              h: ArrayLike | None = None) -> np.ndarray:
        """Assemble a state vector from its parts (zeros by default)."""
        q = as_vector(q, 4, "q")
        w = np.zeros(3) if w is None else as_vector(w, 3, "w")
        parts = [q / np.linalg.norm(q), w]
        if self.wheels is not None:
            parts.append(np.zeros(self.n_wheels) if h is None
                         else as_vector(h, self.n_wheels, "h"))
        return np.concatenate(parts)

    def momentum_function(self) -> ca.Function:
        """``momentum(x) -> (H_ref)``: total angular momentum [N·m·s].

        :math:`H = R(q)\\,(Jω + A H_w)` in the reference frame; constant
        when no external torque acts (the check of the model).
        """
        x = ca.SX.sym("x", self.nx)
        Hb = ca.DM(self.inertia) @ x[4:7]
        if self.wheels is not None:
            Hb = Hb + ca.DM(self.wheels.axes) @ x[7:]
        return ca.Function("momentum", [x], [quat_to_dcm(x[:4]) @ Hb],
                           ["x"], ["H_ref"])

    def rk4_step(self, substeps: int = 1) -> ca.Function:
        """Explicit RK4 step ``rk4(x, u, tau, dt) -> (xf)`` (ZOH inputs).

        Parameters
        ----------
        substeps : int
            RK4 stages per call, each of length ``dt / substeps``.
        """
        if int(substeps) < 1:
            raise InvalidValueError(
                f"substeps must be >= 1, got {substeps!r}")
        x = ca.MX.sym("x", self.nx)
        u = ca.MX.sym("u", self.nu)
        tau = ca.MX.sym("tau", 3)
        dt = ca.MX.sym("dt")
        f = self.dynamics
        h = dt / int(substeps)
        xk = x
        for _ in range(int(substeps)):
            k1 = f(xk, u, tau)
            k2 = f(xk + h / 2 * k1, u, tau)
            k3 = f(xk + h / 2 * k2, u, tau)
            k4 = f(xk + h * k3, u, tau)
            xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return ca.Function("rk4", [x, u, tau, dt], [xk],
                           ["x", "u", "tau", "dt"], ["xf"])

    def integrator(self, dt: float, method: str = "cvodes",
                   options: dict | None = None) -> ca.Function:
        """Variable-step integrator over ``dt`` [s] with ZOH inputs.

        Parameters
        ----------
        dt : float
            Integration interval [s].
        method : {"cvodes", "idas", "rk", "collocation"}
            CasADi integrator plugin.
        options : dict, optional
            Plugin options, forwarded untouched (default tolerances
            ``abstol=1e-10``, ``reltol=1e-10``).

        Returns
        -------
        casadi.Function
            ``F(x0, p) -> (xf)`` with ``p = (u, tau)``.
        """
        dt = float(dt)
        check_positive(dt, "dt")
        if method not in ("cvodes", "idas", "rk", "collocation"):
            raise InvalidValueError(
                "method must be 'cvodes', 'idas', 'rk' or 'collocation', "
                f"got {method!r}")
        x = ca.MX.sym("x", self.nx)
        p = ca.MX.sym("p", self.nu + 3)
        dae = {"x": x, "p": p,
               "ode": self.dynamics(x, p[:self.nu], p[self.nu:])}
        opts = ({"abstol": 1e-10, "reltol": 1e-10}
                if method in ("cvodes", "idas") else {})
        opts.update(options or {})
        return ca.integrator("sim", method, dae, 0.0, dt, opts)

    def simulate(self, x0: ArrayLike, t: ArrayLike, u: ArrayLike,
                 tau: ArrayLike | None = None, method: str = "cvodes",
                 options: dict | None = None) -> np.ndarray:
        """Integrate from ``x0`` over the grid ``t`` with ZOH controls.

        Parameters
        ----------
        x0 : array_like (nx,)
            Initial state.
        t : array_like (K + 1,)
            Increasing time grid [s].
        u : array_like (K, nu)
            Control held over each interval [N·m].
        tau : array_like (K, 3), optional
            External torque held over each interval [N·m].
        method, options
            As `integrator`.

        Returns
        -------
        numpy.ndarray, shape (K + 1, nx)
            States at the grid points.
        """
        t = as_finite_array(t, "t", (None,))
        k = len(t) - 1
        if k < 1 or np.any(np.diff(t) <= 0):
            raise InvalidValueError("t must be increasing with >= 2 points")
        x0 = as_finite_array(x0, "x0", (self.nx,))
        u = as_finite_array(u, "u", (k, self.nu))
        tau = (np.zeros((k, 3)) if tau is None
               else as_finite_array(tau, "tau", (k, 3)))
        X = np.empty((k + 1, self.nx))
        X[0] = x0
        dts = np.diff(t)
        uniform = np.allclose(dts, dts[0], rtol=1e-12, atol=0.0)
        F = self.integrator(dts[0], method, options) if uniform else None
        for i in range(k):
            Fi = F if F is not None else self.integrator(dts[i], method,
                                                         options)
            try:
                xf = Fi(x0=X[i], p=np.concatenate([u[i], tau[i]]))["xf"]
            except RuntimeError as exc:     # the integrator broke down
                raise SolverError(
                    f"simulation failed on interval {i} (t = {t[i]:.6g} "
                    f"s): {str(exc).splitlines()[0][:200]}",
                    solver=method) from None
            X[i + 1] = np.asarray(xf).ravel()
            if not np.all(np.isfinite(X[i + 1])):
                raise SolverError(
                    f"simulation diverged on interval {i} (t = {t[i]:.6g} "
                    "s): the state is no longer finite", solver=method)
        return X


def rigid_spacecraft(inertia: ArrayLike | Spacecraft, wheels: WheelArray | None = None, *,
                     torque_max: ArrayLike | None = None,
                     thrusters: ThrusterSet | None = None
                     ) -> SpacecraftModel:
    """Rigid spacecraft with a wheel array, a torque box or thrusters.

    Parameters
    ----------
    inertia : array_like (3, 3) or (3,), or ocp.spacecraft.Spacecraft
        Inertia J [kg·m²] (rotor spin inertia excluded, see module doc),
        or a whole `Spacecraft` (its wheels and thrusters are used).
    wheels : WheelArray, optional
        Wheel array; its scale factors and failures enter ``Ḣ_w = s m``.
    torque_max : float or array_like (3,), optional
        Per-axis bound of the body torque [N·m]; only for the torque-box
        model (``wheels`` None).
    thrusters : thrusters.ThrusterSet, optional
        Thruster set; its duties follow the wheel torques in ``u`` and act
        through the cycle-averaged torque ``torque_matrix() @ k``. With
        wheels this is [4]'s spacecraft (wheels plus an unloading
        unit); alone, a thruster-only spacecraft.

    Returns
    -------
    SpacecraftModel

    Raises
    ------
    InvalidValueError
        Both ``wheels`` and ``torque_max``, none of the three actuators, a
        torque box with thrusters, or bad values.
    """
    inertia, wheels, thrusters = spacecraft_parts(inertia, wheels, thrusters)
    J = check_inertia(inertia)
    if wheels is not None and torque_max is not None:
        raise InvalidValueError(
            "give wheels (a WheelArray) or torque_max (the per-axis torque "
            "box), not both")
    if wheels is None and torque_max is None and thrusters is None:
        raise InvalidValueError(
            "give an actuator: wheels (a WheelArray), torque_max (the "
            "per-axis torque box) or thrusters (a ThrusterSet)")
    if thrusters is not None:
        if not isinstance(thrusters, ThrusterSet):
            raise InvalidValueError(
                f"thrusters must be a thrusters.ThrusterSet, got "
                f"{type(thrusters).__name__}")
        if torque_max is not None:
            raise InvalidValueError(
                "a torque box and thrusters are both external torques: "
                "give one of them")
    x_q = ca.SX.sym("q", 4)
    x_w = ca.SX.sym("w", 3)
    tau = ca.SX.sym("tau", 3)
    Jdm = ca.DM(J)
    Jinv = ca.DM(np.linalg.inv(J))
    k = ca.SX.sym("k", 0 if thrusters is None else thrusters.n)
    tau_c = tau if thrusters is None else tau + ca.DM(
        thrusters.torque_matrix()) @ k
    tmax = None
    if wheels is None:
        if torque_max is not None:
            tmax = as_vector(torque_max, 3, "torque_max")
            check_positive(tmax, "torque_max")
        u = ca.SX.sym("u", 0 if tmax is None else 3)
        x = ca.vertcat(x_q, x_w)
        wdot = Jinv @ (-ca.cross(x_w, Jdm @ x_w) + tau_c
                       + (u if tmax is not None else 0))
        xdot = ca.vertcat(quat_rate(x_q, x_w), wdot)
    else:
        if not isinstance(wheels, WheelArray):
            raise InvalidValueError(
                f"wheels must be a WheelArray, got {type(wheels).__name__}")
        A, s = effective_torque_matrix(wheels)
        n = wheels.n_wheels
        h = ca.SX.sym("h", n)
        u = ca.SX.sym("u", n)
        m = ca.DM(s) * u
        x = ca.vertcat(x_q, x_w, h)
        Adm = ca.DM(A)
        wdot = Jinv @ (-ca.cross(x_w, Jdm @ x_w + Adm @ h) - Adm @ m
                       + tau_c)
        xdot = ca.vertcat(quat_rate(x_q, x_w), wdot, m)
    f = ca.Function("dynamics", [x, ca.vertcat(u, k), tau], [xdot],
                    ["x", "u", "tau"], ["xdot"])
    return SpacecraftModel(inertia=J, wheels=wheels, torque_max=tmax,
                           dynamics=f, thrusters=thrusters)


def euler_krylov_model(inertia: ArrayLike, wheels: WheelArray | None = None
                       ) -> ca.Function:
    """Dynamics in Euler–Krylov angles, for comparison with [3].

    State ``(γ, ψ, ϑ, ω, H_w)``; the angle rates follow the inverse of
    [3] eq. (1) (see `ocp.models.angles.ek_angle_rates`) and are singular
    at ``cos ψ = 0`` (yaw ±90°), where the Function returns inf/NaN: use
    the quaternion model for large slews.

    Returns
    -------
    casadi.Function
        ``ek_dynamics(x, u, tau) -> (xdot)``, ``u`` the motor torques
        (or body torque without wheels).
    """
    J = check_inertia(inertia)
    ang = ca.SX.sym("angles", 3)
    w = ca.SX.sym("w", 3)
    tau = ca.SX.sym("tau", 3)
    Jdm = ca.DM(J)
    Jinv = ca.DM(np.linalg.inv(J))
    if wheels is None:
        u = ca.SX.sym("u", 3)
        x = ca.vertcat(ang, w)
        wdot = Jinv @ (-ca.cross(w, Jdm @ w) + u + tau)
        xdot = ca.vertcat(ek_angle_rates(ang, w), wdot)
    else:
        A, s = effective_torque_matrix(wheels)
        h = ca.SX.sym("h", wheels.n_wheels)
        u = ca.SX.sym("u", wheels.n_wheels)
        m = ca.DM(s) * u
        x = ca.vertcat(ang, w, h)
        wdot = Jinv @ (-ca.cross(w, Jdm @ w + ca.DM(A) @ h)
                       - ca.DM(A) @ m + tau)
        xdot = ca.vertcat(ek_angle_rates(ang, w), wdot, m)
    return ca.Function("ek_dynamics", [x, u, tau], [xdot],
                       ["x", "u", "tau"], ["xdot"])

