"""Basilisk modules (Python ``SysModel``) wrapping the toolbox's laws."""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_scalar, as_vector
from allocation import QPAllocator, WheelAllocation, WheelArray

from . import require_basilisk

require_basilisk()

from Basilisk.architecture import messaging, sysModel  # noqa: E402


def _entries(value: Any, n: int, ctype: Any = ctypes.c_int) -> list:
    """Return the first ``n`` entries of a payload's array field.

    A list normally; a raw SWIG pointer once another Basilisk module (e.g.
    ``rwMotorTorque``) has wrapped the same struct: then read through its
    address.
    """
    try:
        return list(value)[:n]
    except TypeError:
        return list((ctype * n).from_address(int(value)))


def _padded(values: np.ndarray) -> list[float]:
    out = [0.0] * messaging.MAX_EFF_CNT
    out[:len(values)] = [float(v) for v in values]
    return out


class WheelQPAllocatorModule(sysModel.SysModel):
    """`QPAllocator` as a Basilisk module, in place of ``rwMotorTorque``.

    Reads ``vehControlInMsg`` (``CmdTorqueBodyMsg``: the torque ``L_r``
    the body should receive), and optionally ``rwSpeedsInMsg`` (wheel
    speeds Ω [rad/s]; with ``Js`` and ``dt`` the momentum bound
    ``|J_s Ω + m dt| <= h_max``) and ``rwAvailInMsg`` (unavailable wheels
    are failed wheels of the QP). Writes ``rwMotorTorqueOutMsg``
    (``ArrayMotorTorqueMsg``): the motor torques ``m`` of
    ``A m = -L_r`` (α-scaled when unattainable: the direction is kept),
    within ``|m_i| <= m_max``, so Basilisk's torque clipping never acts.

    Parameters
    ----------
    array : WheelArray
        The wheels, in the order of Basilisk's wheel list (``A = G_s``).
    Js : float or array_like (N,), optional
        Wheel spin inertias [kg·m²] (for the momenta from the speeds).
    dt : float, optional
        Control period [s] of the momentum bound.
    **allocator_options
        Passed to `QPAllocator` (weights, solver, momentum management).

    Attributes
    ----------
    last : WheelAllocation or None
        The last allocation (status, α, torques).
    """

    def __init__(self, array: WheelArray, Js=None, dt: float | None = None,
                 **allocator_options: Any) -> None:
        super().__init__()
        if not isinstance(array, WheelArray):
            raise InvalidValueError(
                f"array must be a WheelArray, got {type(array).__name__}")
        self.array = array
        n = array.n_wheels
        self.Js = None if Js is None else as_vector(
            np.broadcast_to(np.asarray(Js, float), (n,)) if np.ndim(Js) == 0
            else Js, n, "Js")
        self.dt = None if dt is None else as_finite_scalar(dt, "dt")
        self.options = allocator_options
        self._allocators: dict[tuple, QPAllocator] = {}
        self.vehControlInMsg = messaging.CmdTorqueBodyMsgReader()
        self.rwSpeedsInMsg = messaging.RWSpeedMsgReader()
        self.rwAvailInMsg = messaging.RWAvailabilityMsgReader()
        self.rwMotorTorqueOutMsg = messaging.ArrayMotorTorqueMsg()
        self.last: WheelAllocation | None = None

    def allocator(self, failed: tuple[int, ...] = ()) -> QPAllocator:
        """Return the allocator of a set of unavailable wheels (built once)."""
        if failed not in self._allocators:
            arr = self.array.with_failed(*failed) if failed else self.array
            self._allocators[failed] = QPAllocator(arr, **self.options)
        return self._allocators[failed]

    def Reset(self, CurrentSimNanos: int) -> None:  # noqa: N802, N803
        """Basilisk's reset: nothing is carried between runs."""
        self.last = None

    def UpdateState(self, CurrentSimNanos: int) -> None:  # noqa: N802,N803
        """Allocate the commanded torque; write the motor torques."""
        n = self.array.n_wheels
        L = np.array(self.vehControlInMsg().torqueRequestBody, float)
        failed: tuple[int, ...] = tuple(self.array.failed)
        if self.rwAvailInMsg.isLinked():
            avail = _entries(self.rwAvailInMsg().wheelAvailability, n)
            failed = tuple(sorted(set(failed) | {
                i for i, a in enumerate(avail) if a != messaging.AVAILABLE}))
        h = dt = None
        if self.rwSpeedsInMsg.isLinked() and self.Js is not None \
                and self.dt is not None:
            h = self.Js * np.array(_entries(
                self.rwSpeedsInMsg().wheelSpeeds, n, ctypes.c_double))
            dt = self.dt
        self.last = self.allocator(failed).allocate(-L, h, dt)
        out = messaging.ArrayMotorTorqueMsgPayload()
        out.motorTorque = _padded(self.last.torques)
        self.rwMotorTorqueOutMsg.write(out, CurrentSimNanos, self.moduleID)


class AttitudeMPCModule(sysModel.SysModel):
    """`ocp.mpc.AttitudeMPC` as a Basilisk module: wheel torques directly.

    Reads ``attNavInMsg`` (``NavAttMsg``: MRP σ_BN, ω_BN_B) and
    ``rwSpeedsInMsg`` (relative wheel speeds Ω), forms the toolbox's state
    ``(q, ω, H_w)`` with ``H_w = J_s (Ω + Gᵀω)`` (`convert.rotor_momenta`),
    steps the MPC towards ``qf`` and writes ``rwMotorTorqueOutMsg``
    (``ArrayMotorTorqueMsg``). The MPC's warm start carries from step to
    step; ``Reset`` clears it.

    Parameters
    ----------
    mpc : ocp.mpc.AttitudeMPC
        The controller (its model's wheels in Basilisk's order).
    qf : array_like (4,)
        Target quaternion (scalar-first).
    Js : float or array_like (N,)
        Rotor spin inertias [kg·m²].

    Attributes
    ----------
    steps : list of MPCStep
        Every step's result (status, cost, solve time).
    """

    def __init__(self, mpc: Any, qf, Js) -> None:
        super().__init__()
        from adcs_common.quaternion import as_unit_quaternion

        self.mpc = mpc
        self.qf = as_unit_quaternion(qf, "qf")
        self.Js = Js
        self.attNavInMsg = messaging.NavAttMsgReader()
        self.rwSpeedsInMsg = messaging.RWSpeedMsgReader()
        self.rwMotorTorqueOutMsg = messaging.ArrayMotorTorqueMsg()
        self.steps: list = []

    def Reset(self, CurrentSimNanos: int) -> None:  # noqa: N802, N803
        """Basilisk's reset: forget the MPC's warm start."""
        self.mpc.reset()
        self.steps = []

    def UpdateState(self, CurrentSimNanos: int) -> None:  # noqa: N802,N803
        """Step the MPC from the navigation state; write wheel torques."""
        from .convert import mrp_to_quaternion, rotor_momenta

        wheels = self.mpc.wheels
        n = wheels.n_wheels
        nav = self.attNavInMsg()
        w = np.array(_entries(nav.omega_BN_B, 3, ctypes.c_double), float)
        sigma = np.array(_entries(nav.sigma_BN, 3, ctypes.c_double), float)
        speeds = _entries(self.rwSpeedsInMsg().wheelSpeeds, n,
                          ctypes.c_double)
        x = np.r_[mrp_to_quaternion(sigma), w,
                  rotor_momenta(wheels, self.Js, speeds, w)]
        step = self.mpc.step(x, self.qf)
        self.steps.append(step)
        out = messaging.ArrayMotorTorqueMsgPayload()
        out.motorTorque = _padded(step.u[:n])
        self.rwMotorTorqueOutMsg.write(out, CurrentSimNanos, self.moduleID)


class ThrusterDutyModule(sysModel.SysModel):
    """`thrusters.DutyCycleAllocator` as a Basilisk module (on-times).

    Reads ``cmdTorqueInMsg`` (``CmdTorqueBodyMsg``: the torque ``L_r``
    the body should receive), solves the duty-cycle QP for the torques
    about the unit's two torque axes (X and Z of [4]'s unit) with zero net
    thrust, and writes ``onTimeOutMsg`` (``THRArrayOnTimeCmdMsg``): duty
    times the cycle [s]. Where the demand exceeds the unit (weighted
    tracking) the QP returns the nearest torque it can make within duties
    in [0, 1]; no impulse is dropped or carried.

    Parameters
    ----------
    allocator : thrusters.DutyCycleAllocator
        Built for the unit and the cycle T_T (the module's period).

    Attributes
    ----------
    last : DutyAllocation or None
        The last cycle's result.
    """

    def __init__(self, allocator: Any) -> None:
        super().__init__()
        from thrusters import DutyCycleAllocator

        if not isinstance(allocator, DutyCycleAllocator):
            raise InvalidValueError(
                "allocator must be a thrusters.DutyCycleAllocator, got "
                f"{type(allocator).__name__}")
        self.allocator = allocator
        self.cmdTorqueInMsg = messaging.CmdTorqueBodyMsgReader()
        self.onTimeOutMsg = messaging.THRArrayOnTimeCmdMsg()
        self.last = None

    def Reset(self, CurrentSimNanos: int) -> None:  # noqa: N802, N803
        """Basilisk's reset: nothing is carried between runs."""
        self.last = None

    def UpdateState(self, CurrentSimNanos: int) -> None:  # noqa: N802,N803
        """Allocate this cycle's torque; write the valve on-times."""
        from thrusters.laws import TORQUE_AXES

        L = np.array(_entries(self.cmdTorqueInMsg().torqueRequestBody, 3,
                              ctypes.c_double), float)
        self.last = self.allocator.solve(0.0, L[list(TORQUE_AXES)])
        out = messaging.THRArrayOnTimeCmdMsgPayload()
        duty = self.last.duty if self.last.success else np.zeros(
            self.allocator.unit.n)
        out.OnTimeRequest = _padded(duty * self.allocator.cycle)
        self.onTimeOutMsg.write(out, CurrentSimNanos, self.moduleID)
