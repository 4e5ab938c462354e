"""Closed-loop scenarios in Basilisk: its FSW allocation against ours."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from adcs_common.results import ResultMixin

from adcs_common.exceptions import InvalidValueError
from adcs_common.quaternion import quat_from_axis_angle
from adcs_common.validation import as_angle, as_finite_scalar
from ocp.spacecraft import load_spacecraft

from . import require_basilisk
from .convert import gs_matrix, hub_inertia, mrp_angle, quaternion_to_mrp

#: The two allocations a scenario runs: Basilisk's minimum-norm
#: ``rwMotorTorque`` (clipped per wheel by the wheel effector) and ours.
ALLOCATORS = ("rwMotorTorque", "QPAllocator")


@dataclass(frozen=True, eq=False, repr=False)
class LoopRun(ResultMixin):
    """One closed loop in Basilisk, sampled at the control period.

    Attributes
    ----------
    allocator : str
        ``"rwMotorTorque"`` or ``"QPAllocator"``.
    t : (K,) ndarray
        Time [s].
    pointing_error : (K,) ndarray
        Attitude error angle to the target [rad].
    commanded : (K, 3) ndarray
        Control torque ``L_r`` asked of the wheels [N·m] (body).
    delivered : (K, 3) ndarray
        Torque the wheels put on the body, ``-G_s u`` with the torques
        the wheel effector applied (after its clipping) over the interval
        before each sample [N·m].
    wheel_torque : (K, N) ndarray
        Applied motor torques [N·m].
    wheel_speed : (K, N) ndarray
        Wheel speeds [rad/s].
    extras : dict
        Scenario settings.
    """

    allocator: str
    t: np.ndarray
    pointing_error: np.ndarray
    commanded: np.ndarray
    delivered: np.ndarray
    wheel_torque: np.ndarray
    wheel_speed: np.ndarray
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def direction_error(self) -> np.ndarray:
        """Angle between each command and the torque it produced, (K-1,).

        The wheel effector applies the command of sample k over the next
        dynamics steps, so command k is set against the torque recorded at
        sample k + 1 [rad]; 0 where either is zero.
        """
        c, d = self.commanded[:-1], self.delivered[1:]
        nc = np.linalg.norm(c, axis=1)
        nd = np.linalg.norm(d, axis=1)
        ok = (nc > 1e-12) & (nd > 1e-12)
        cos = np.ones(len(c))
        cos[ok] = np.einsum("ij,ij->i", c[ok], d[ok]) / (nc[ok] * nd[ok])
        return np.arccos(np.clip(cos, -1.0, 1.0))

    def settle_time(self, tol: float = np.deg2rad(0.1)) -> float:
        """First time [s] after which the error stays below ``tol`` [rad]."""
        above = np.flatnonzero(self.pointing_error > tol)
        if len(above) == len(self.t):
            return float("nan")
        return float(self.t[above[-1] + 1]) if len(above) else 0.0

    def summary(self) -> dict[str, float]:
        """Figures of merit: errors [deg], settle time [s], peak torque."""
        return {
            "max direction error [deg]": float(np.degrees(
                self.direction_error.max())),
            "final pointing error [deg]": float(np.degrees(
                self.pointing_error[-1])),
            "settle to 0.1° [s]": self.settle_time(),
            "peak |u| [N·m]": float(np.abs(self.wheel_torque).max()),
        }


def spacecraft_task(sim: Any, inertia, wheels: Any, Js: float,
                    dt_dyn: float):
    """Build the hub, the wheel effector and simple navigation."""
    from Basilisk.simulation import (reactionWheelStateEffector, simpleNav,
                                     spacecraft)
    from Basilisk.utilities import macros, simIncludeRW
    try:
        from Basilisk.utilities.simHelpers import np2EigenMatrix3d
    except ImportError:            # Basilisk before 2.12
        from Basilisk.utilities.unitTestSupport import np2EigenMatrix3d

    proc = sim.CreateNewProcess("dynamics", 2)
    proc.addTask(sim.CreateNewTask("dyn", macros.sec2nano(dt_dyn)))
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "spacecraft"
    sc.hub.mHub = 1000.0
    sc.hub.IHubPntBc_B = np2EigenMatrix3d(
        hub_inertia(inertia, wheels, Js).ravel().tolist())
    factory = simIncludeRW.rwFactory()
    rpm = 60.0 / (2.0 * np.pi)
    for i in range(wheels.n_wheels):
        rw = factory.create(
            "custom", [float(v) for v in wheels.axes[:, i]], Js=Js,
            u_max=float(wheels.m_max[i]), useMaxTorque=True, Omega=0.0,
            Omega_max=float(wheels.h_max[i] / Js * rpm))
        rw.Jt = rw.Jg = rw.mass = 0.0      # a spin-axis rotor only
    rw = reactionWheelStateEffector.ReactionWheelStateEffector()
    rw.ModelTag = "wheels"
    factory.addToSpacecraft("wheels", rw, sc)
    nav = simpleNav.SimpleNav()
    nav.ModelTag = "nav"
    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    for model, prio in ((rw, 3), (sc, 2), (nav, 1)):
        sim.AddModelToTask("dyn", model, None, prio)
    return sc, rw, nav


def run_recorded(sim: Any, messages: list, period: int,
                 t_final: float) -> list:
    """Record ``messages`` every ``period`` [ns] on the ``"fsw"`` task,
    then initialise ``sim`` and run it to ``t_final`` [s]; return the
    recorders, in the messages' order."""
    from Basilisk.utilities import macros

    recs = [m.recorder(period) for m in messages]
    for r in recs:
        sim.AddModelToTask("fsw", r)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(t_final))
    sim.ExecuteSimulation()
    return recs


def _fsw_task(sim: Any, sc_def: Any, nav: Any, rw: Any, allocator: str,
              sigma_target, gains: tuple[float, float], Js: float,
              dt: float, keep: list):
    """Guidance, mrpFeedback and the allocator under test (FSW task)."""
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import (attTrackingError, inertial3D,
                                        mrpFeedback, rwMotorTorque)
    from Basilisk.utilities import macros

    from .modules import WheelQPAllocatorModule

    proc = sim.CreateNewProcess("fsw", 1)
    proc.addTask(sim.CreateNewTask("fsw", macros.sec2nano(dt)))
    wheels = sc_def.wheels
    n = wheels.n_wheels
    ref = inertial3D.inertial3D()
    ref.ModelTag = "reference"
    ref.sigma_R0N = [float(v) for v in sigma_target]
    err = attTrackingError.attTrackingError()
    err.ModelTag = "trackingError"
    err.attNavInMsg.subscribeTo(nav.attOutMsg)
    err.attRefInMsg.subscribeTo(ref.attRefOutMsg)
    veh = messaging.VehicleConfigMsgPayload()
    veh.ISCPntB_B = np.asarray(sc_def.inertia, float).ravel().tolist()
    cfg = messaging.RWArrayConfigMsgPayload()
    cfg.GsMatrix_B = gs_matrix(wheels)
    cfg.JsList = [Js] * n
    cfg.uMax = [float(u) for u in wheels.m_max]
    cfg.numRW = n
    keep += [messaging.VehicleConfigMsg().write(veh),
             messaging.RWArrayConfigMsg().write(cfg)]
    ctrl = mrpFeedback.mrpFeedback()
    ctrl.ModelTag = "mrpFeedback"
    ctrl.K, ctrl.P, ctrl.Ki = gains[0], gains[1], -1.0
    ctrl.guidInMsg.subscribeTo(err.attGuidOutMsg)
    ctrl.vehConfigInMsg.subscribeTo(keep[-2])
    ctrl.rwParamsInMsg.subscribeTo(keep[-1])
    ctrl.rwSpeedsInMsg.subscribeTo(rw.rwSpeedOutMsg)
    if allocator == "rwMotorTorque":
        alloc = rwMotorTorque.rwMotorTorque()
        alloc.controlAxes_B = [1, 0, 0, 0, 1, 0, 0, 0, 1]
        alloc.rwParamsInMsg.subscribeTo(keep[-1])
    else:
        alloc = WheelQPAllocatorModule(wheels, Js=Js, dt=dt)
        alloc.rwSpeedsInMsg.subscribeTo(rw.rwSpeedOutMsg)
    alloc.ModelTag = allocator
    alloc.vehControlInMsg.subscribeTo(ctrl.cmdTorqueOutMsg)
    rw.rwMotorCmdInMsg.subscribeTo(alloc.rwMotorTorqueOutMsg)
    for model, prio in ((ref, 5), (err, 4), (ctrl, 3), (alloc, 2)):
        sim.AddModelToTask("fsw", model, None, prio)
    return err, ctrl, alloc


@dataclass(eq=False)
class LoopSetup:
    """A closed loop of `run_loop`, built and not yet run.

    Attributes
    ----------
    sim : Basilisk SimBaseClass
    spacecraft : ocp.spacecraft.Spacecraft
        The craft.
    hub, wheels, err, ctrl, alloc : Basilisk modules
        The hub, the wheel effector, attTrackingError, mrpFeedback and the
        allocator under test.
    availability : RWAvailabilityMsgPayload or None
        The availability written to both allocators: the craft's failed
        wheels unavailable from the start (None when all work and none
        fails during the run).
    keep : list
        Messages kept alive for the run.
    """

    sim: Any
    spacecraft: Any
    hub: Any
    wheels: Any
    err: Any
    ctrl: Any
    alloc: Any
    availability: Any
    availability_msg: Any
    keep: list


def build_loop(allocator: str, spacecraft: Any = "meteor-m", *,
               angle: float = np.deg2rad(40.0),
               axis=(1.0, -0.5, 0.3), dt: float = 0.5,
               dt_dynamics: float = 0.1,
               gains: tuple[float, float] = (20.0, 500.0), Js: float = 0.1,
               fail_wheel: int | None = None) -> LoopSetup:
    """Build `run_loop`'s simulation (same arguments) without running it."""
    require_basilisk()
    from Basilisk.architecture import messaging

    if allocator not in ALLOCATORS:
        raise InvalidValueError(
            f"allocator must be one of {ALLOCATORS}, got {allocator!r}")
    sc_def = load_spacecraft(spacecraft)
    angle = as_angle(angle, "angle")
    sigma_target = quaternion_to_mrp(quat_from_axis_angle(axis, angle))
    from Basilisk.utilities import SimulationBaseClass

    sim = SimulationBaseClass.SimBaseClass()
    keep: list = []
    sc, rw, nav = spacecraft_task(sim, sc_def.inertia, sc_def.wheels, Js,
                                  dt_dynamics)
    err, ctrl, alloc = _fsw_task(sim, sc_def, nav, rw, allocator,
                                 sigma_target, gains, Js, dt, keep)
    n = sc_def.wheels.n_wheels
    avail = avail_msg = None
    if fail_wheel is not None or sc_def.wheels.failed:
        # the craft's failed wheels are unavailable to both allocators
        avail = messaging.RWAvailabilityMsgPayload()
        avail.wheelAvailability = [
            messaging.UNAVAILABLE if i in sc_def.wheels.failed
            else messaging.AVAILABLE for i in range(n)]
        avail_msg = messaging.RWAvailabilityMsg().write(avail)
        alloc.rwAvailInMsg.subscribeTo(avail_msg)
    return LoopSetup(sim, sc_def, sc, rw, err, ctrl, alloc, avail,
                     avail_msg, keep)


def run_loop(allocator: str, spacecraft: Any = "meteor-m", *,
             angle: float = np.deg2rad(40.0),
             axis=(1.0, -0.5, 0.3), t_final: float = 400.0,
             dt: float = 0.5, dt_dynamics: float = 0.1,
             gains: tuple[float, float] = (20.0, 500.0), Js: float = 0.1,
             fail_wheel: int | None = None,
             t_fail: float | None = None) -> LoopRun:
    """Slew from rest in Basilisk with ``mrpFeedback`` and ``allocator``.

    The spacecraft's inertia and wheels (``reactionWheelStateEffector``
    with each wheel's ``u_max``, clipped by the effector); a rest-to-rest
    slew by ``angle`` [rad] about ``axis`` under ``mrpFeedback`` (gains
    ``K`` [N·m], ``P`` [N·m·s]): with the defaults on Meteor-M the
    commanded torque exceeds what the wheels give, for most of the slew.
    The craft's failed wheels are reported unavailable to both allocators
    from the start (Basilisk's availability message); with ``fail_wheel``
    (0-based) that wheel too from ``t_fail`` [s]. `build_loop` builds
    the same simulation without running it.

    Returns
    -------
    LoopRun
    """
    require_basilisk()
    from Basilisk.architecture import messaging
    from Basilisk.utilities import macros

    if allocator not in ALLOCATORS:
        raise InvalidValueError(
            f"allocator must be one of {ALLOCATORS}, got {allocator!r}")
    angle = as_angle(angle, "angle")
    t_final = as_finite_scalar(t_final, "t_final")
    if t_final <= 0 or (fail_wheel is not None and (
            t_fail is None or not 0 < t_fail < t_final)):
        raise InvalidValueError(
            "t_final must be positive and t_fail within (0, t_final)")
    setup = build_loop(allocator, spacecraft, angle=angle, axis=axis,
                       dt=dt, dt_dynamics=dt_dynamics, gains=gains, Js=Js,
                       fail_wheel=fail_wheel)
    sim, sc_def, rw = setup.sim, setup.spacecraft, setup.wheels
    err, ctrl = setup.err, setup.ctrl
    avail, avail_msg = setup.availability, setup.availability_msg
    n = sc_def.wheels.n_wheels
    period = macros.sec2nano(dt)
    recs = [err.attGuidOutMsg.recorder(period),
            ctrl.cmdTorqueOutMsg.recorder(period),
            rw.rwSpeedOutMsg.recorder(period)]
    recs += [rw.rwOutMsgs[i].recorder(period) for i in range(n)]
    for r in recs:
        sim.AddModelToTask("fsw", r)
    sim.InitializeSimulation()
    stops = [t_final] if fail_wheel is None else [t_fail, t_final]
    for k, stop in enumerate(stops):
        if k == 1:
            avail.wheelAvailability = [
                messaging.UNAVAILABLE if i == fail_wheel
                or i in sc_def.wheels.failed
                else messaging.AVAILABLE for i in range(n)]
            avail_msg.write(avail)
        sim.ConfigureStopTime(macros.sec2nano(stop))
        sim.ExecuteSimulation()
    sigma = np.asarray(recs[0].sigma_BR)
    u = np.column_stack([np.asarray(r.u_current) for r in recs[3:]])
    return LoopRun(
        allocator=allocator, t=recs[0].times() * macros.NANO2SEC,
        pointing_error=np.array([mrp_angle(s) for s in sigma]),
        commanded=np.asarray(recs[1].torqueRequestBody),
        delivered=-(u @ np.asarray(sc_def.wheels.axes).T),
        wheel_torque=u, wheel_speed=np.asarray(recs[2].wheelSpeeds)[:, :n],
        extras={"spacecraft": sc_def.name, "angle": angle,
                "axis": tuple(axis), "gains": gains, "dt": dt,
                "fail_wheel": fail_wheel, "t_fail": t_fail})


def compare_loops(**kwargs: Any) -> dict[str, LoopRun]:
    """`run_loop` with each allocator of `ALLOCATORS` (same settings)."""
    return {name: run_loop(name, **kwargs) for name in ALLOCATORS}
