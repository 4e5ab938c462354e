"""Basilisk modules (Python ``SysModel``) wrapping the toolbox's laws."""

from __future__ import annotations

import ctypes
from typing import TYPE_CHECKING, Any

import numpy as np

from adcs_common.exceptions import AdcsError, InvalidValueError
from adcs_common.validation import as_finite_scalar, as_vector, check_positive
from allocation import QPAllocator, WheelAllocation, WheelArray

from . import require_basilisk

if TYPE_CHECKING:
    from thrusters import DutyAllocation

require_basilisk()

from Basilisk.architecture import bskLogging, messaging, sysModel  # noqa: E402

#: `status` of a module after a step: it wrote its command.
OK = "ok"
#: A reader the module needs is not subscribed: zero command.
UNSUBSCRIBED = "unsubscribed"
#: An input message holds NaN or inf: zero command.
INVALID_INPUT = "invalid input"
#: No allocation possible (every wheel unavailable, or the wheels left
#: cannot span 3-D): zero command.
NO_WHEELS = "no wheels"
#: The controller raised a toolbox error (its message in ``fault``): zero.
SOLVER_FAILED = "solver failed"


class _Guarded:
    """Fault handling shared by the modules (a mix-in of ``SysModel``).

    A fault never raises inside Basilisk (an exception in a Python
    module reaches the simulation as ``SWIG director method error``): the
    module writes a zero command, sets ``status`` and ``fault`` (what
    went wrong), counts it in ``faults`` and logs each kind once at
    ``BSK_WARNING``.
    """

    status: str = OK
    fault: str = ""
    faults: int = 0
    # SysModel's, on the modules that mix this in
    bskLogger: Any
    ModelTag: str

    def _reset_status(self) -> None:
        self.status, self.fault, self.faults = OK, "", 0
        self._logged: set = set()

    def _unlinked(self, *names: str) -> list[str]:
        return [n for n in names if not getattr(self, n).isLinked()]

    def _fail(self, status: str, fault: str) -> None:
        self.status, self.fault = status, fault
        self.faults += 1
        if status not in self._logged:
            self._logged.add(status)
            # BSK_ERROR would raise inside the simulation (Basilisk 2.12)
            self.bskLogger.bskLog(
                bskLogging.BSK_WARNING, f"{type(self).__name__} {self.ModelTag}: {fault}; "
                "zero command written")


def _finite(values: Any, name: str) -> str:
    """Return "" when every entry is finite, else a message naming it."""
    v = np.asarray(values, float)
    return "" if np.all(np.isfinite(v)) else f"{name} holds NaN or inf"


def _positive_vector(value: Any, n: int, name: str) -> np.ndarray:
    """``value`` as a finite positive (n,) vector (a scalar is repeated)."""
    v = as_vector(np.broadcast_to(np.asarray(value, float), (n,))
                  if np.ndim(value) == 0 else value, n, name)
    check_positive(v, name)
    return v


def _positive(value: Any, name: str) -> float:
    """``value`` as a finite positive scalar."""
    v = as_finite_scalar(value, name)
    if not v > 0:
        raise InvalidValueError(f"{name} must be positive, got {v!r}")
    return v


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


class WheelQPAllocatorModule(_Guarded, sysModel.SysModel):
    """`QPAllocator` as a Basilisk module, in place of ``rwMotorTorque``.

    Reads ``vehControlInMsg`` (``CmdTorqueBodyMsg``: the torque ``L_r``
    the body should receive), and optionally ``rwSpeedsInMsg`` (wheel
    speeds Ω [rad/s]; with ``Js`` and ``dt`` the momentum bound
    ``|J_s Ω + m dt| <= h_max``) and ``rwAvailInMsg`` (unavailable wheels
    are failed wheels of the QP). Writes ``rwMotorTorqueOutMsg``
    (``ArrayMotorTorqueMsg``): the motor torques ``m`` of
    ``A m = -L_r`` (α-scaled when unattainable: the direction is kept),
    within ``|m_i| <= m_max``, so Basilisk's torque clipping never acts.

    Faults write zero torques and set ``status`` (never an exception
    inside the simulation): ``vehControlInMsg`` not subscribed
    (`UNSUBSCRIBED`), NaN or inf in the torque request or the wheel
    speeds (`INVALID_INPUT`), every wheel unavailable or too few left to
    span 3-D (`NO_WHEELS`).

    Parameters
    ----------
    array : WheelArray
        The wheels, in the order of Basilisk's wheel list (``A = G_s``).
    Js : float or array_like (N,), optional
        Wheel spin inertias [kg·m²], positive (for the momenta from the
        speeds).
    dt : float, optional
        Control period [s] of the momentum bound, positive.
    **allocator_options
        Passed to `QPAllocator` (weights, solver, momentum management);
        checked here.

    Attributes
    ----------
    last : WheelAllocation or None
        The last allocation (status, α, torques); None after a fault.
    status : str
        `OK` or the last step's fault; ``fault`` says what, ``faults``
        counts the faults since ``Reset``.

    Raises
    ------
    InvalidValueError
        ``array`` not a WheelArray, ``Js`` or ``dt`` not finite and
        positive.
    SolverNotFound
        The options' ``solver`` unknown or not installed.
    """

    def __init__(self, array: WheelArray, Js=None, dt: float | None = None,
                 **allocator_options: Any) -> None:
        super().__init__()
        if not isinstance(array, WheelArray):
            raise InvalidValueError(
                f"array must be a WheelArray, got {type(array).__name__}")
        self.array = array
        n = array.n_wheels
        self.Js = None if Js is None else _positive_vector(Js, n, "Js")
        self.dt = None if dt is None else _positive(dt, "dt")
        self.options = allocator_options
        self._allocators: dict[tuple, QPAllocator] = {}
        self.allocator(tuple(array.failed))    # checks the options
        self._reset_status()
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
        """Basilisk's reset: nothing is carried between runs.

        An unsubscribed ``vehControlInMsg`` is reported here (``status``
        `UNSUBSCRIBED`, logged) and at every step.
        """
        self.last = None
        self._reset_status()
        if self._unlinked("vehControlInMsg"):
            self._fail(UNSUBSCRIBED, "vehControlInMsg is not subscribed")

    def _write(self, torques, nanos: int) -> None:
        out = messaging.ArrayMotorTorqueMsgPayload()
        out.motorTorque = _padded(torques)
        self.rwMotorTorqueOutMsg.write(out, nanos, self.moduleID)

    def UpdateState(self, CurrentSimNanos: int) -> None:  # noqa: N802,N803
        """Allocate the commanded torque; write the motor torques."""
        n = self.array.n_wheels
        self.last = None
        if self._unlinked("vehControlInMsg"):
            self._fail(UNSUBSCRIBED, "vehControlInMsg is not subscribed")
            return self._write(np.zeros(n), CurrentSimNanos)
        L = np.array(_entries(self.vehControlInMsg().torqueRequestBody, 3,
                              ctypes.c_double), float)
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
        bad = _finite(L, "vehControlInMsg.torqueRequestBody") or (
            "" if h is None else _finite(h, "rwSpeedsInMsg.wheelSpeeds"))
        if bad:
            self._fail(INVALID_INPUT, bad)
            return self._write(np.zeros(n), CurrentSimNanos)
        if len(failed) == n:
            self._fail(NO_WHEELS, "every wheel is unavailable")
            return self._write(np.zeros(n), CurrentSimNanos)
        try:
            alloc = self.allocator(failed)
        except AdcsError as exc:
            self._fail(NO_WHEELS, f"wheels {[i + 1 for i in failed]} "
                       f"unavailable: {exc}")
            return self._write(np.zeros(n), CurrentSimNanos)
        self.last = alloc.allocate(-L, h, dt)
        self.status, self.fault = OK, ""
        self._write(self.last.torques, CurrentSimNanos)


class AttitudeMPCModule(_Guarded, sysModel.SysModel):
    """`ocp.mpc.AttitudeMPC` as a Basilisk module: wheel torques directly.

    Reads ``attNavInMsg`` (``NavAttMsg``: MRP σ_BN, ω_BN_B) and
    ``rwSpeedsInMsg`` (relative wheel speeds Ω), forms the toolbox's state
    ``(q, ω, H_w)`` with ``H_w = J_s (Ω + Gᵀω)`` (`convert.rotor_momenta`),
    steps the MPC towards ``qf`` and writes ``rwMotorTorqueOutMsg``
    (``ArrayMotorTorqueMsg``). The MPC's warm start carries from
    step to step; ``Reset`` clears it.

    Faults write zero torques and set ``status`` (never an exception
    inside the simulation): a reader not subscribed (`UNSUBSCRIBED`), NaN
    or inf in the navigation or the wheel speeds (`INVALID_INPUT`), the
    MPC raising a toolbox error (`SOLVER_FAILED`; no step is appended).

    Parameters
    ----------
    mpc : ocp.mpc.AttitudeMPC
        The controller (its model's wheels in Basilisk's order).
    qf : array_like (4,)
        Target quaternion (scalar-first).
    Js : float or array_like (N,)
        Rotor spin inertias [kg·m²], positive.

    Attributes
    ----------
    steps : list of MPCStep
        Every step's result (status, cost, solve time).
    status : str
        `OK` or the last step's fault; ``fault`` says what, ``faults``
        counts the faults since ``Reset``.

    Raises
    ------
    InvalidValueError
        ``mpc`` not an `AttitudeMPC`, ``qf`` not a quaternion, ``Js`` not
        finite and positive.
    """

    def __init__(self, mpc: Any, qf, Js) -> None:
        super().__init__()
        from adcs_common.quaternion import as_unit_quaternion
        from ocp.mpc import AttitudeMPC

        if not isinstance(mpc, AttitudeMPC):
            raise InvalidValueError(
                f"mpc must be an ocp.mpc.AttitudeMPC, got "
                f"{type(mpc).__name__}")
        self.mpc = mpc
        self.qf = as_unit_quaternion(qf, "qf")
        self.Js = _positive_vector(Js, mpc.wheels.n_wheels, "Js")
        self._reset_status()
        self.attNavInMsg = messaging.NavAttMsgReader()
        self.rwSpeedsInMsg = messaging.RWSpeedMsgReader()
        self.rwMotorTorqueOutMsg = messaging.ArrayMotorTorqueMsg()
        self.steps: list = []

    def Reset(self, CurrentSimNanos: int) -> None:  # noqa: N802, N803
        """Basilisk's reset: forget the MPC's warm start.

        Unsubscribed readers are reported here (``status``
        `UNSUBSCRIBED`, logged) and at every step.
        """
        self.mpc.reset()
        self.steps = []
        self._reset_status()
        missing = self._unlinked("attNavInMsg", "rwSpeedsInMsg")
        if missing:
            self._fail(UNSUBSCRIBED, f"{', '.join(missing)} not subscribed")

    def _write(self, torques, nanos: int) -> None:
        out = messaging.ArrayMotorTorqueMsgPayload()
        out.motorTorque = _padded(torques)
        self.rwMotorTorqueOutMsg.write(out, nanos, self.moduleID)

    def UpdateState(self, CurrentSimNanos: int) -> None:  # noqa: N802,N803
        """Step the MPC from the navigation state; write wheel torques."""
        from .convert import mrp_to_quaternion, rotor_momenta

        wheels = self.mpc.wheels
        n = wheels.n_wheels
        missing = self._unlinked("attNavInMsg", "rwSpeedsInMsg")
        if missing:
            self._fail(UNSUBSCRIBED, f"{', '.join(missing)} not subscribed")
            return self._write(np.zeros(n), CurrentSimNanos)
        nav = self.attNavInMsg()
        w = np.array(_entries(nav.omega_BN_B, 3, ctypes.c_double), float)
        sigma = np.array(_entries(nav.sigma_BN, 3, ctypes.c_double), float)
        speeds = np.array(_entries(self.rwSpeedsInMsg().wheelSpeeds, n,
                                   ctypes.c_double), float)
        bad = (_finite(sigma, "attNavInMsg.sigma_BN")
               or _finite(w, "attNavInMsg.omega_BN_B")
               or _finite(speeds, "rwSpeedsInMsg.wheelSpeeds"))
        if bad:
            self._fail(INVALID_INPUT, bad)
            return self._write(np.zeros(n), CurrentSimNanos)
        x = np.r_[mrp_to_quaternion(sigma), w,
                  rotor_momenta(wheels, self.Js, speeds, w)]
        try:
            step = self.mpc.step(x, self.qf)
        except AdcsError as exc:
            self._fail(SOLVER_FAILED, str(exc))
            return self._write(np.zeros(n), CurrentSimNanos)
        self.status, self.fault = OK, ""
        self.steps.append(step)
        self._write(step.u[:n], CurrentSimNanos)


class ThrusterDutyModule(_Guarded, sysModel.SysModel):
    """`thrusters.DutyCycleAllocator` as a Basilisk module (on-times).

    Reads ``cmdTorqueInMsg`` (``CmdTorqueBodyMsg``: the torque ``L_r``
    the body should receive), solves the duty-cycle QP for the torques
    about the unit's two torque axes (X and Z of [4]'s unit) with zero net
    thrust, and writes ``onTimeOutMsg`` (``THRArrayOnTimeCmdMsg``): duty
    times the cycle [s]. Where the demand exceeds the unit (weighted
    tracking) the QP returns the nearest torque it can make within duties
    in [0, 1]; no impulse is dropped or carried. Faults write zero
    on-times and set ``status`` (never an exception inside the
    simulation): ``cmdTorqueInMsg`` not subscribed (`UNSUBSCRIBED`), NaN
    or inf in it (`INVALID_INPUT`).

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
        self.last: DutyAllocation | None = None
        self._reset_status()

    def Reset(self, CurrentSimNanos: int) -> None:  # noqa: N802, N803
        """Basilisk's reset: nothing is carried between runs."""
        self.last = None
        self._reset_status()
        if self._unlinked("cmdTorqueInMsg"):
            self._fail(UNSUBSCRIBED, "cmdTorqueInMsg is not subscribed")

    def _write(self, duty, nanos: int) -> None:
        out = messaging.THRArrayOnTimeCmdMsgPayload()
        out.OnTimeRequest = _padded(duty * self.allocator.cycle)
        self.onTimeOutMsg.write(out, nanos, self.moduleID)

    def UpdateState(self, CurrentSimNanos: int) -> None:  # noqa: N802,N803
        """Allocate this cycle's torque; write the valve on-times."""
        from thrusters.laws import TORQUE_AXES

        zero = np.zeros(self.allocator.unit.n)
        self.last = None
        if self._unlinked("cmdTorqueInMsg"):
            self._fail(UNSUBSCRIBED, "cmdTorqueInMsg is not subscribed")
            return self._write(zero, CurrentSimNanos)
        L = np.array(_entries(self.cmdTorqueInMsg().torqueRequestBody, 3,
                              ctypes.c_double), float)
        bad = _finite(L, "cmdTorqueInMsg.torqueRequestBody")
        if bad:
            self._fail(INVALID_INPUT, bad)
            return self._write(zero, CurrentSimNanos)
        self.last = self.allocator.solve(0.0, L[list(TORQUE_AXES)])
        self.status, self.fault = OK, ""
        self._write(self.last.duty if self.last.success else zero,
                    CurrentSimNanos)
