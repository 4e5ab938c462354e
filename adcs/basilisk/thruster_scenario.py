"""[4]'s six-thruster unit reorienting in Basilisk: its FSW vs our QP."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.quaternion import quat_from_axis_angle
from adcs_common.results import ResultMixin
from adcs_common.validation import as_angle, as_finite_scalar

from . import require_basilisk
from .convert import mrp_angle, quaternion_to_mrp
from .scenarios import run_recorded

#: The two thruster chains a run compares: Basilisk's thrForceMapping +
#: thrFiringRemainder, and the toolbox's duty-cycle QP.
THRUSTER_CHAINS = ("thrForceMapping", "DutyCycleAllocator")


@dataclass(frozen=True, eq=False, repr=False)
class ThrusterRun(ResultMixin):
    """One reorientation with [4]'s unit in Basilisk, sampled per cycle.

    Attributes
    ----------
    chain : str
        One of `THRUSTER_CHAINS`.
    t : (K,) ndarray
        Time [s].
    pointing_error : (K,) ndarray
        Attitude error to the target [rad].
    commanded : (K, 3) ndarray
        Torque ``L_r`` mrpFeedback asked for [N·m].
    on_time : (K, 6) ndarray
        Valve on-time requested per cycle [s].
    delta_v : (K, 3) ndarray
        Velocity gained since the start, inertial [m/s].
    extras : dict
        Settings.
    """

    chain: str
    t: np.ndarray
    pointing_error: np.ndarray
    commanded: np.ndarray
    on_time: np.ndarray
    delta_v: np.ndarray
    extras: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, float]:
        """Return the figures of merit: errors [deg], Δv [m/s], on-time."""
        return {
            "final pointing error [deg]": float(np.degrees(
                self.pointing_error[-1])),
            "residual |Δv| [m/s]": float(np.linalg.norm(self.delta_v[-1])),
            "total valve on-time [s]": float(self.on_time.sum()),
        }


def _thrusters(sim: Any, sc: Any, unit: Any):
    """Put [4]'s unit on the hub (Basilisk's thruster effector)."""
    from Basilisk.simulation import thrusterDynamicEffector
    from Basilisk.utilities import simIncludeThruster

    factory = simIncludeThruster.thrusterFactory()
    arms = unit.positions - unit.center_of_mass[:, None]
    for i in range(unit.n):
        factory.create("Blank_Thruster", [float(v) for v in arms[:, i]],
                       [float(v) for v in unit.directions[:, i]],
                       MaxThrust=float(unit.steady_thrust[i]),
                       steadyIsp=float(unit.isp), MinOnTime=0.0)
    eff = thrusterDynamicEffector.ThrusterDynamicEffector()
    eff.ModelTag = "thrusters"
    factory.addToSpacecraft("thrusters", eff, sc)
    sim.AddModelToTask("dyn", eff, None, 3)
    return eff, factory


def _chain(chain: str, unit: Any, ctrl: Any, factory: Any, keep: list,
           cycle: float) -> tuple[list, Any]:
    """Build the torque-to-on-time chain; its models and output message."""
    from Basilisk.fswAlgorithms import thrFiringRemainder, thrForceMapping

    from thrusters import DutyCycleAllocator

    from .modules import ThrusterDutyModule

    if chain == "thrForceMapping":
        keep.append(factory.getConfigMessage())
        fmap = thrForceMapping.thrForceMapping()
        fmap.controlAxes_B = [1, 0, 0, 0, 0, 1]
        fmap.thrForceSign = +1
        fmap.cmdTorqueInMsg.subscribeTo(ctrl.cmdTorqueOutMsg)
        fmap.thrConfigInMsg.subscribeTo(keep[-1])
        fmap.vehConfigInMsg.subscribeTo(keep[0])
        fire = thrFiringRemainder.thrFiringRemainder()
        fire.thrMinFireTime = unit.min_on_time
        fire.thrForceInMsg.subscribeTo(fmap.thrForceCmdOutMsg)
        fire.thrConfInMsg.subscribeTo(keep[-1])
        out = fire.onTimeOutMsg
        return [fmap, fire], out
    else:
        duty = ThrusterDutyModule(DutyCycleAllocator(
            unit, cycle, 1e3, tracking="weighted"))
        duty.cmdTorqueInMsg.subscribeTo(ctrl.cmdTorqueOutMsg)
        out = duty.onTimeOutMsg
        return [duty], out


def reorientation(chain: str, *, spacecraft: Any = None,
                  angle: float = np.deg2rad(30.0),
                  axis: Any = (1.0, 0.0, 0.3), t_final: float = 120.0,
                  cycle: float = 2.0, gains: tuple[float, float] = (
                      0.3, 1.5), dt_dynamics: float = 0.02) -> ThrusterRun:
    """Reorient [4]'s 54 kg craft by its six-thruster unit in Basilisk.

    ``mrpFeedback`` (gains ``K`` [N·m], ``P`` [N·m·s]) asks for a torque
    every cycle T_T = ``cycle`` [s]; ``chain`` turns it into valve
    on-times: Basilisk's ``thrForceMapping`` (X and Z controlled: the unit
    has no Y torque) and ``thrFiringRemainder``, or the toolbox's
    duty-cycle QP (`ThrusterDutyModule`: zero net thrust, duties in
    [0, 1]). J = diag(3.0, 2.5, 3.5) kg·m² as the toolbox assumes for [4],
    or the inertia and thruster set of ``spacecraft`` (a `Spacecraft`, a
    catalogue name or a TOML file with a ``[thrusters]`` table).

    Returns
    -------
    ThrusterRun
    """
    require_basilisk()
    from Basilisk.utilities import macros

    t_final = as_finite_scalar(t_final, "t_final")
    sim, parts = build_reorientation(
        chain, spacecraft=spacecraft, angle=angle, axis=axis, cycle=cycle,
        gains=gains, dt_dynamics=dt_dynamics)
    err, ctrl, out, sc, unit = (parts[k] for k in (
        "err", "ctrl", "out", "hub", "unit"))
    recs = run_recorded(sim, [err.attGuidOutMsg, ctrl.cmdTorqueOutMsg, out,
                              sc.scStateOutMsg], macros.sec2nano(cycle),
                        t_final)
    v = np.asarray(recs[3].v_BN_N)
    return ThrusterRun(
        chain=chain, t=recs[0].times() * macros.NANO2SEC,
        pointing_error=np.array([mrp_angle(s)
                                 for s in np.asarray(recs[0].sigma_BR)]),
        commanded=np.asarray(recs[1].torqueRequestBody),
        on_time=np.asarray(recs[2].OnTimeRequest)[:, :unit.n],
        delta_v=v - v[0],
        extras={"angle": parts["angle"], "axis": tuple(axis),
                "cycle": cycle, "gains": gains})


def build_reorientation(chain: str, *, spacecraft: Any = None,
                        angle: float = np.deg2rad(30.0),
                        axis: Any = (1.0, 0.0, 0.3), cycle: float = 2.0,
                        gains: tuple[float, float] = (0.3, 1.5),
                        dt_dynamics: float = 0.02) -> tuple[Any, dict]:
    """Build `reorientation`'s simulation (same arguments), not run.

    Returns
    -------
    sim : Basilisk SimBaseClass
    parts : dict
        ``"hub"``, ``"thrusters"`` (effector), ``"factory"`` (its
        thruster configurations), ``"err"``, ``"ctrl"``, ``"chain"`` (the
        chain's modules), ``"out"`` (on-time message), ``"unit"``,
        ``"inertia"`` (3, 3) [kg·m²], ``"angle"`` [rad], ``"keep"``.
    """
    require_basilisk()
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import (attTrackingError, inertial3D,
                                        mrpFeedback)
    from Basilisk.simulation import simpleNav
    from Basilisk.simulation import spacecraft as bsk_spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros
    from Basilisk.utilities.simHelpers import np2EigenMatrix3d

    from thrusters import six_thruster_unit

    if chain not in THRUSTER_CHAINS:
        raise InvalidValueError(
            f"chain must be one of {THRUSTER_CHAINS}, got {chain!r}")
    angle = as_angle(angle, "angle")
    unit, J = six_thruster_unit(), np.diag([3.0, 2.5, 3.5])
    if spacecraft is not None:
        from ocp.spacecraft import load_spacecraft

        craft = load_spacecraft(spacecraft)
        if craft.thrusters is None:
            raise InvalidValueError(
                f"spacecraft {craft.name!r} has no thrusters")
        unit, J = craft.thrusters, np.asarray(craft.inertia, float)
    sim = SimulationBaseClass.SimBaseClass()
    keep: list = []
    dyn = sim.CreateNewProcess("dynamics", 2)
    dyn.addTask(sim.CreateNewTask("dyn", macros.sec2nano(dt_dynamics)))
    sc = bsk_spacecraft.Spacecraft()
    sc.ModelTag = "spacecraft"
    sc.hub.mHub = 54.0
    sc.hub.IHubPntBc_B = np2EigenMatrix3d(J.ravel().tolist())
    eff, factory = _thrusters(sim, sc, unit)
    nav = simpleNav.SimpleNav()
    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    sim.AddModelToTask("dyn", sc, None, 2)
    sim.AddModelToTask("dyn", nav, None, 1)
    fsw = sim.CreateNewProcess("fsw", 1)
    fsw.addTask(sim.CreateNewTask("fsw", macros.sec2nano(cycle)))
    ref = inertial3D.inertial3D()
    ref.sigma_R0N = [float(v) for v in quaternion_to_mrp(
        quat_from_axis_angle(axis, angle))]
    err = attTrackingError.attTrackingError()
    err.attNavInMsg.subscribeTo(nav.attOutMsg)
    err.attRefInMsg.subscribeTo(ref.attRefOutMsg)
    veh = messaging.VehicleConfigMsgPayload()
    veh.ISCPntB_B = J.ravel().tolist()
    keep.append(messaging.VehicleConfigMsg().write(veh))
    ctrl = mrpFeedback.mrpFeedback()
    ctrl.K, ctrl.P, ctrl.Ki = gains[0], gains[1], -1.0
    ctrl.guidInMsg.subscribeTo(err.attGuidOutMsg)
    ctrl.vehConfigInMsg.subscribeTo(keep[-1])
    models = [ref, err, ctrl]
    chain_models, out = _chain(chain, unit, ctrl, factory, keep, cycle)
    models += chain_models
    eff.cmdsInMsg.subscribeTo(out)
    for prio, model in enumerate(reversed(models)):
        model.ModelTag = type(model).__name__ + str(prio)
        sim.AddModelToTask("fsw", model, None, prio + 1)
    return sim, {"hub": sc, "thrusters": eff, "factory": factory,
                 "err": err, "ctrl": ctrl, "chain": chain_models,
                 "out": out, "unit": unit, "inertia": J, "angle": angle,
                 "keep": keep}


def compare_reorientation(**kwargs: Any) -> dict[str, ThrusterRun]:
    """`reorientation` with each chain of `THRUSTER_CHAINS`."""
    return {c: reorientation(c, **kwargs) for c in THRUSTER_CHAINS}
