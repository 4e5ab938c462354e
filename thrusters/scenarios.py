"""Pulse-cycle simulation of the 54 kg spacecraft ([4], Tables 2-5)."""

from __future__ import annotations

from typing import Any

from dataclasses import dataclass, field

import numpy as np
from adcs_common.results import ResultMixin

from adcs_common.exceptions import InvalidValueError
from adcs_common.quaternion import (
    quat_conj,
    quat_from_axis_angle,
    quat_mul,
    quat_to_dcm,
)
from adcs_common.rigid_body import body_rates, rk4_step
from adcs_common.validation import as_finite_array

from thrusters.laws import reorientation_law, unloading_law
from thrusters.qp import DutyCycleAllocator, MinOnTimeCarry
from thrusters.unit import G0, ThrusterSet, six_thruster_unit


#: Spacecraft of [4] (mass from Table 2's Δv; inertia, R and L are
#: not given by [4]: theory §2's stated values).
MASS = 54.0                                   # [kg]


INERTIA = np.diag([3.0, 2.5, 3.5])            # [kg·m²]


#: Disturbance torque of the burn (thrust mismatch and misalignment,
#: 0.0012 N·m in [4]), direction chosen in the XZ plane [N·m].
BURN_DISTURBANCE = 0.0012 * np.array([0.8, 0.0, -0.6])


#: [4] Table 2 (burn inputs) and Table 3 (achieved accuracy).
TABLE2 = {"T_imp": 340.0, "T_T": 10.0, "P_T": 0.739, "H_max": 0.012,
          "yaw": 64.51, "pitch": 35.32, "dV": 4.65}


TABLE3 = {"thrust_dev_max": 0.0021, "thrust_dev_max_pct": 0.28,
          "thrust_dev_mean": 0.00026, "thrust_dev_mean_pct": 0.035,
          "yaw_err_max": 0.135, "yaw_err_mean": 0.0091,
          "pitch_err_max": 0.106, "pitch_err_mean": 0.0065,
          "dV_err": 0.025, "dV_err_pct": 0.54}


#: [4] Table 5 (reorientation and hold, T_T = 2 s): per group
#: (Δv [m/s], max and mean group thrust in a cycle [N]) and per engine
#: (valve openings, total / max / mean open time [ms]).
TABLE5_GROUPS = {"group 1": (0.15967, 0.11947, 0.01432),
                 "group 2": (0.15999, 0.12004, 0.01435)}


TABLE5_ENGINES = {"D1": (148, 12078, 745, 40), "D2": (102, 6917, 698, 23),
                  "D3": (110, 7741, 400, 26), "D4": (121, 10078, 745, 33),
                  "D5": (149, 8007, 659, 27), "D6": (170, 8956, 494, 30)}


#: [4] text bounds of the reorientation run.
REORIENT_BOUNDS = {"hold_error_deg": 0.4, "propellant_g": 8.0,
                   "max_open_ms": 750.0, "residual_dv": 3.22e-4,
                   "H_y_peak": 0.03}


# ----------------------------------------------------------------------
# rigid body
def _error_vector(q, q_ref):
    """Small-angle attitude error 2 vec(q_ref* q), sign-fixed [rad]."""
    e = quat_mul(quat_conj(q_ref), q)
    return 2.0 * np.sign(e[0] if e[0] != 0 else 1.0) * e[1:]


@dataclass
class _Body:
    """State: attitude q (inertial_from_body), rate ω, wheel momentum."""

    J: np.ndarray
    q: np.ndarray = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))
    w: np.ndarray = field(default_factory=lambda: np.zeros(3))
    Hw: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def step(self, dt, tau_ext, u_w):
        """RK4 step with torques held over ``dt`` [s]."""
        def f(q, w, H):
            return (*body_rates(self.J, q, w, H, tau_ext, u_w), u_w)

        q, self.w, self.Hw = rk4_step(f, (self.q, self.w, self.Hw), dt)
        self.q = q / np.linalg.norm(q)


@dataclass(frozen=True, eq=False, repr=False)
class ScenarioResult(ResultMixin):
    """Time histories and per-cycle records of a pulse-cycle run.

    Attributes
    ----------
    name : str
        ``"burn"`` or ``"reorientation"``.
    t : numpy.ndarray, shape (m,)
        Simulation times [s].
    attitude_error : numpy.ndarray, shape (m, 3)
        Small-angle attitude error about body X, Y, Z [rad].
    angle : numpy.ndarray, shape (m, 3)
        Attitude as X-Y-Z rotation angles from the initial frame [rad].
    wheel_momentum : numpy.ndarray, shape (m, 3)
        Wheel momentum in body axes [N·m·s].
    velocity : numpy.ndarray, shape (m, 3)
        Inertial velocity change from the start [m/s].
    cycle_start : numpy.ndarray, shape (c,)
        Start time of each cycle [s].
    on_time : numpy.ndarray, shape (c, n)
        Valve command durations per cycle [s].
    cycle_thrust : numpy.ndarray, shape (c, n)
        True mean thrust of each engine over each cycle (pulse impulse
        over T_T, transients included) [N].
    demand : numpy.ndarray, shape (c, 3)
        Demanded (P_T, M_X, M_Z) per cycle.
    status : list of str
        Law or QP status per cycle.
    propellant : float
        Propellant used [kg].
    mass : numpy.ndarray, shape (m,)
        Spacecraft mass [kg].
    cycle : float
        T_T [s].
    unit : ThrusterSet
        The thrusters (with the K_p used by the allocator).
    """

    name: str
    t: np.ndarray
    attitude_error: np.ndarray
    angle: np.ndarray
    wheel_momentum: np.ndarray
    velocity: np.ndarray
    cycle_start: np.ndarray
    on_time: np.ndarray
    cycle_thrust: np.ndarray
    demand: np.ndarray
    status: list
    propellant: float
    mass: np.ndarray
    cycle: float
    unit: ThrusterSet

    @property
    def group_thrust(self) -> np.ndarray:
        """Mean thrust of group 1 (+Y) and group 2 (-Y) per cycle, (c, 2)."""
        g1 = self.unit.directions[1] > 0
        return np.column_stack([self.cycle_thrust[:, g1].sum(1),
                                self.cycle_thrust[:, ~g1].sum(1)])

    @property
    def net_thrust(self) -> np.ndarray:
        """Mean thrust along +Y per cycle (c,) [N]."""
        return self.cycle_thrust @ self.unit.directions[1]


def _euler_xyz_many(qs):
    """X-Y-Z rotation angles of quaternions (m, 4) [rad], (m, 3)."""
    w, x, y, z = qs.T
    r02 = 2 * (x * z + w * y)
    r12 = 2 * (y * z - w * x)
    r22 = 1 - 2 * (x * x + y * y)
    r01 = 2 * (x * y - w * z)
    r00 = 1 - 2 * (y * y + z * z)
    return np.column_stack([np.arctan2(-r12, r22),
                            np.arcsin(np.clip(r02, -1, 1)),
                            np.arctan2(-r01, r00)])


def _simulate(name, unit, cycle, n_cycles, t_end, dt, allocate,
              q_ref_fn, w_ref_fn, wheel_axes, wheel_gains, disturbance_fn,
              mass, J, carry, jitter=0.0, seed=0, pressure_fn=None):
    """Run the common loop: per cycle allocate, then integrate.

    The truth applies the transient model to the commanded valve times,
    each perturbed (when ``jitter`` > 0) by a Gaussian timing error of
    standard deviation ``jitter`` [s] (command latency, seeded), with the
    steady thrust of eq. (1) at the inlet pressure ``pressure_fn`` gives
    at mid-cycle (the unit's pressure when None).
    """
    rng = np.random.default_rng(seed)
    body = _Body(J=np.asarray(J, dtype=float))
    n = unit.n
    steps_per_cycle = int(round(cycle / dt))
    if abs(steps_per_cycle * dt - cycle) > 1e-9:
        raise InvalidValueError(
            f"dt = {dt} s must divide the cycle T_T = {cycle} s")
    total_steps = int(round(t_end / dt))
    arms = unit.arms
    dirs = unit.directions
    kp_w, kd_w, u_max = wheel_gains
    wheel_axes = np.asarray(wheel_axes, dtype=bool)
    m = mass
    v = np.zeros(3)
    prop = 0.0
    per_impulse = 1.0 / (unit.isp * G0)           # [kg/(N·s)]
    log_t, log_err, log_H, log_v, log_m = [], [], [], [], []
    starts, on_times, thrusts, demands, statuses = [], [], [], [], []
    pulses = []                        # (start, on_time) still active
    for step in range(total_steps):
        t = step * dt
        if step % steps_per_cycle == 0:
            c = step // steps_per_cycle
            if c < n_cycles:
                k, demand, status = allocate(c, t, body)
                k = carry.apply(k) if carry is not None else k
                t_on = k * cycle
                t_true = t_on
                if jitter > 0:
                    t_true = np.where(t_on > 0, np.maximum(
                        t_on + jitter * rng.standard_normal(n), 0.0), 0.0)
                P_ss = (unit.steady_thrust if pressure_fn is None else
                        unit.pressure_slope * pressure_fn(t + cycle / 2)
                        + unit.thrust_offset)
                impulse = unit.pulse_impulse(t_true, P_ss)
                starts.append(t)
                on_times.append(t_on)
                thrusts.append(impulse / cycle)
                demands.append(demand)
                statuses.append(status)
                if np.any(t_true > 0):
                    pulses.append((t, t_true, float(
                        t_true.max() + unit.close_delay + unit.open_delay
                        + 10 * (unit.tail_time + unit.rise_time)), P_ss))
        # pulses whose tail-off is over (10 time constants) are dropped
        pulses = [p for p in pulses if t - p[0] < p[2]]
        # thrust impulse of each engine over [t, t + dt]
        dI = np.zeros(n)
        for t0, t_on, _, P_ss in pulses:
            dI += (unit.cumulative_impulse(t + dt - t0, t_on, P_ss)
                   - unit.cumulative_impulse(t - t0, t_on, P_ss))
        F_body = dirs @ dI / dt
        tau_thr = arms @ dI / dt
        tau = tau_thr + disturbance_fn(t)
        # wheel controller (zero-order hold over dt) on its axes
        q_ref = q_ref_fn(t)
        err = _error_vector(body.q, q_ref)
        w_err = body.w - w_ref_fn(t)
        tau_c = -kp_w * err - kd_w * w_err + np.cross(
            body.w, body.J @ body.w + body.Hw)
        u_w = np.where(wheel_axes, np.clip(-tau_c, -u_max, u_max), 0.0)
        body.step(dt, tau, u_w)
        v = v + quat_to_dcm(body.q) @ F_body * dt / m
        used = float(dI.sum()) * per_impulse
        prop += used
        m -= used
        log_t.append(t + dt)
        log_err.append(body.q)
        log_H.append(body.Hw.copy())
        log_v.append(v.copy())
        log_m.append(m)
    ts = np.array(log_t)
    qs = np.array(log_err)
    errors = np.array([_error_vector(q, q_ref_fn(tk))
                       for q, tk in zip(qs, ts)])
    return ScenarioResult(
        name=name, t=ts, attitude_error=errors,
        angle=_euler_xyz_many(qs), wheel_momentum=np.array(log_H),
        velocity=np.array(log_v), cycle_start=np.array(starts),
        on_time=np.array(on_times), cycle_thrust=np.array(thrusts),
        demand=np.array(demands), status=statuses, propellant=prop,
        mass=np.array(log_m), cycle=cycle, unit=unit)


def _check_allocation(allocation):
    if allocation not in ("law", "qp"):
        raise InvalidValueError(
            f"allocation must be 'law' or 'qp', got {allocation!r}")


def burn_scenario(allocation: str = "law", solver: str = "daqp",
                  K_unl: float = 1.0, unit: ThrusterSet | None = None,
                  disturbance: Any = BURN_DISTURBANCE, dt: float = 0.1,
                  settle: float = 60.0, calibrate: bool = True,
                  pressure_drop: float = 0.0, wheel_bandwidth: float = 0.3,
                  wheel_torque_max: float = 0.02) -> ScenarioResult:
    """Simulate the translation burn of Table 2 with wheel unloading.

    Unloading by eq. 2 or by the QP.

    The spacecraft (54 kg, J = diag(3.0, 2.5, 3.5) kg·m²) fires group 1
    for T_imp = 340 s in T_T = 10 s cycles at P_T = 0.739 N; three
    reaction wheels hold the attitude (PD, ω_n = ``wheel_bandwidth``
    [rad/s], damping 0.9, torque up to ``wheel_torque_max`` [N·m]; [4]
    gives neither its attitude controller nor its gains) and
    absorb the thruster torque transients and the disturbance torque
    (0.0012 N·m, `BURN_DISTURBANCE`). Each cycle, the wheel momentum H at
    the cycle start sets the unloading torque ``-K_unl H / T_T``:
    ``allocation="law"`` uses `unloading_law`; ``"qp"`` the weighted
    `DutyCycleAllocator` with the bound ``|H|`` <= 0.012 N·m·s, a disturbance
    estimate from the last cycles' momentum change, and that estimate
    cancelled in the torque demand (feed-forward). The
    allocator's K_p comes from the transient model at the nominal duty
    (`ThrusterSet.calibrated`); the truth applies the transient model
    (`ThrusterSet.cumulative_impulse`) to the commanded valve times, and
    the mass decreases with the propellant used. ``calibrate=False``
    keeps K_p = 1 (no transient correction): the per-cycle thrust then
    misses P_T by the transients' impulse loss, about 0.3 %.
    ``pressure_drop`` (fraction, e.g. 0.1) lets the inlet pressure fall
    linearly over the burn (blowdown); each cycle the allocator reads the
    pressure at the cycle start (eq. 1: ``unit.with_pressure`` for the
    law, `DutyCycleAllocator.set_pressure` for the QP) while the truth
    fires at the mid-cycle pressure.

    Returns
    -------
    ScenarioResult
    """
    _check_allocation(allocation)
    T = TABLE2["T_T"]
    P_T = TABLE2["P_T"]
    base = unit if unit is not None else six_thruster_unit()
    duty0 = P_T / float(np.sum(base.steady_thrust[:3]))
    cal = base.calibrated(T, duty0) if calibrate else base
    dist = as_finite_array(disturbance, "disturbance", (3,))
    n_cycles = int(round(TABLE2["T_imp"] / T))
    state = {"H_prev": None, "tau_est": np.zeros(3), "k_prev": None}
    alloc = (DutyCycleAllocator(cal, T, TABLE2["H_max"], solver=solver,
                                tracking="weighted")
             if allocation == "qp" else None)

    drop = float(pressure_drop)
    if not (np.isfinite(drop) and 0.0 <= drop < 1.0):
        raise InvalidValueError(
            f"pressure_drop must lie in [0, 1), got {pressure_drop!r}")

    def pressure(t):
        return cal.pressure * (1.0 - drop * min(t, TABLE2["T_imp"])
                               / TABLE2["T_imp"])

    def allocate(c, t, body):
        H = body.Hw.copy()
        p_meas = pressure(t)
        if alloc is None:
            unit_now = cal if drop == 0 else cal.with_pressure(p_meas)
            res = unloading_law(unit_now, P_T, H, T, K_unl)
            return res.duty, res.demand, res.status
        if drop:
            alloc.set_pressure(p_meas)
        if state["H_prev"] is not None:
            # H+ = H + T (tau_thr + tau_dist): estimate tau_dist
            tau_thr = cal.torque_matrix() @ state["k_prev"]
            est = (H - state["H_prev"]) / T - tau_thr
            state["tau_est"] = 0.5 * state["tau_est"] + 0.5 * est
        # unload H and cancel the estimated disturbance (feed-forward)
        M = -K_unl * H[[0, 2]] / T - state["tau_est"][[0, 2]]
        res = alloc.solve(P_T, M, H, state["tau_est"])
        state["H_prev"], state["k_prev"] = H, res.duty
        return res.duty, res.demand, res.status

    def disturbance_fn(t):
        return dist if t < TABLE2["T_imp"] else np.zeros(3)

    zero = np.array([1.0, 0.0, 0.0, 0.0])
    return _simulate(
        "burn", cal, T, n_cycles, TABLE2["T_imp"] + settle, dt, allocate,
        lambda t: zero, lambda t: np.zeros(3), (True, True, True),
        (INERTIA.diagonal() * wheel_bandwidth ** 2,
         INERTIA.diagonal() * 1.8 * wheel_bandwidth, wheel_torque_max),
        disturbance_fn, MASS, INERTIA, MinOnTimeCarry(cal, T),
        pressure_fn=pressure if drop else None)


def slew_profile(t: float, t0: float = 70.0, t1: float = 240.0,
                 angle: float = np.deg2rad(170.0)):
    """Cycloidal rest-to-rest profile: angle, rate, acceleration at t.

    .. math::
        \\theta = \\Theta\\,(s - \\sin(2\\pi s)/(2\\pi)),\\quad
        s = (t - t_0)/(t_1 - t_0)
    """
    if t <= t0:
        return 0.0, 0.0, 0.0
    if t >= t1:
        return angle, 0.0, 0.0
    Ts = t1 - t0
    s = (t - t0) / Ts
    th = angle * (s - np.sin(2 * np.pi * s) / (2 * np.pi))
    rate = angle / Ts * (1 - np.cos(2 * np.pi * s))
    acc = angle / Ts ** 2 * 2 * np.pi * np.sin(2 * np.pi * s)
    return th, rate, acc


def reorientation_scenario(allocation: str = "law", solver: str = "daqp",
                           unit: ThrusterSet | None = None,
                           dt: float = 0.1, t_end: float = 600.0,
                           omega_n: float = 0.15,
                           valve_jitter: float = 0.002,
                           disturbance: Any = (0.0, 0.0, 0.0),
                           seed: int = 0, inertia: Any = None
                           ) -> ScenarioResult:
    """Hold, 170° slew about X, hold (Table 5): thrusters at T_T = 2 s.

    ``inertia`` (3, 3) [kg·m²] replaces the assumed diag(3.0, 2.5, 3.5)
    ([4] gives none); a product of inertia J_xz couples the X slew into Y
    through ``ω × Jω``, where only the wheel acts.

    0-70 s hold, 70-240 s cycloidal slew of 170° about body X, hold to
    600 s. Every cycle a PID attitude controller with feed-forward
    (:math:`M = J\\alpha_{ref} + \\omega \\times J\\omega - K_p\\phi -
    K_d(\\omega - \\omega_{ref}) - K_i\\int\\phi`, :math:`K_p =
    3J\\omega_n^2`, :math:`K_d = 3J\\omega_n`, :math:`K_i = J\\omega_n^3`:
    triple pole at :math:`-\\omega_n`) demands (M_X, M_Z); they go through
    `reorientation_law` (``allocation="law"``) or the weighted
    `DutyCycleAllocator` (``"qp"``, P_T = 0, bound 0.05 N·m·s on the
    cycle's momentum increment); `MinOnTimeCarry` applies the min
    on-time. A Y-axis wheel (the thrusters make no Y torque) holds the
    Y attitude and absorbs the gyroscopic coupling. [4] ran on a
    real-time prototype with actual command delays: here each valve time
    is off by a Gaussian error of ``valve_jitter`` seconds (seeded by
    ``seed``), the source of the residual Δv; ``disturbance`` is a
    constant body torque [N·m] (none by default).

    Returns
    -------
    ScenarioResult
    """
    _check_allocation(allocation)
    T = 2.0
    base = unit if unit is not None else six_thruster_unit()
    # K_p at the typical hold pulse (40 ms in a 2 s cycle)
    cal = base.calibrated(T, 0.02)
    J = INERTIA if inertia is None else as_finite_array(
        inertia, "inertia", (3, 3))
    # PID with the closed-loop poles at -omega_n (triple) per axis
    Kp = 3 * J.diagonal() * omega_n ** 2
    Kd = 3 * J.diagonal() * omega_n
    Ki = J.diagonal() * omega_n ** 3
    integ = np.zeros(3)
    axis = np.array([1.0, 0.0, 0.0])
    dist = as_finite_array(disturbance, "disturbance", (3,))
    if not np.isfinite(valve_jitter) or valve_jitter < 0:
        raise InvalidValueError(
            f"valve_jitter must be >= 0 [s], got {valve_jitter!r}")
    alloc = (DutyCycleAllocator(cal, T, 0.05, solver=solver,
                                tracking="weighted")
             if allocation == "qp" else None)

    def q_ref(t):
        return quat_from_axis_angle(axis, slew_profile(t)[0])

    def w_ref(t):
        return axis * slew_profile(t)[1]

    def allocate(c, t, body):
        th, rate, acc = slew_profile(t + T / 2)      # mid-cycle reference
        err = _error_vector(body.q, q_ref(t))
        w_err = body.w - w_ref(t)
        integ[:] = np.clip(integ + err * T, -0.05, 0.05)   # anti-windup
        M3 = (J @ (axis * acc) + np.cross(body.w, J @ body.w + body.Hw)
              - Kp * err - Kd * w_err - Ki * integ)
        M = M3[[0, 2]]
        if alloc is None:
            res = reorientation_law(cal, 0.0, M)
            return res.duty, res.demand, res.status
        res = alloc.solve(0.0, M, np.zeros(3))
        return res.duty, res.demand, res.status

    n_cycles = int(round(t_end / T))
    return _simulate(
        "reorientation", cal, T, n_cycles, t_end, dt, allocate, q_ref,
        w_ref, (False, True, False),
        (J.diagonal() * 0.09, J.diagonal() * 0.54, 0.02),
        lambda t: dist, MASS, J, MinOnTimeCarry(cal, T),
        jitter=float(valve_jitter), seed=seed)
