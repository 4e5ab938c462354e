"""Closed-form duty-cycle laws of [4]: eqs. (2), (8)-(9), Table 4."""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from adcs_common.results import ResultMixin

from adcs_common.exceptions import InvalidValueError, RankError
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    check_instance,
    check_nonnegative,
)

from .unit import ThrusterSet

#: Body axis of the unit's thrust (Y) and the torque axes the thrusters
#: control (X, Z), 0-based.
THRUST_AXIS = 1
TORQUE_AXES = (0, 2)

_CLIP_TOL = 1e-12
#: Per-unit matrices of the laws, computed once (a ThrusterSet is frozen).
_CACHE: "weakref.WeakKeyDictionary[ThrusterSet, dict]" = (
    weakref.WeakKeyDictionary())


def _cached(unit: ThrusterSet) -> dict:
    entry = _CACHE.get(unit)
    if entry is None:
        entry = {}
        _CACHE[unit] = entry
    return entry


@dataclass(frozen=True, eq=False, repr=False)
class LawResult(ResultMixin):
    """One cycle of a closed-form duty-cycle law.

    Attributes
    ----------
    duty : numpy.ndarray, shape (n,)
        Duty fractions :math:`k_i \\in [0, 1]` (D1..Dn) to command: valve
        ``i`` is open for ``duty[i] * T_T`` seconds.
    duty_unclipped : numpy.ndarray, shape (n,)
        What the law's linear solve asked for (may leave [0, 1]).
    status : str
        ``"ok"`` (no clipping) or ``"clipped"`` (some coefficient left
        [0, 1] and was clipped; ``error`` is then non-zero).
    demand : numpy.ndarray, shape (3,)
        Demanded ``(P_T [N], M_X [N·m], M_Z [N·m])``.
    achieved : numpy.ndarray, shape (3,)
        ``(P, M_X, M_Z)`` the clipped duty gives under the linear cycle
        model.
    error : numpy.ndarray, shape (3,)
        ``achieved - demand``.
    mode : str
        Table 4: ``"group1"`` (P_T > 0, braking impulse), ``"reorientation"``
        (P_T = 0, slews and hold), ``"group2"`` (P_T < 0, accelerating
        impulse); ``"mixed"`` when eq. (9) had to fire engines of both
        groups with P_T != 0 (torque demand large against the thrust).
    law : str
        Name of the law and equation.
    """

    duty: np.ndarray
    duty_unclipped: np.ndarray
    status: str
    demand: np.ndarray
    achieved: np.ndarray
    error: np.ndarray
    mode: str
    law: str

    @property
    def clipped(self) -> bool:
        """True when the law's coefficients had to be clipped."""
        return self.status == "clipped"

    def on_times(self, cycle: float) -> np.ndarray:
        """Valve command durations :math:`t_{rdi} = k_i T_T` (eq. 3) [s]."""
        return self.duty * float(cycle)


def _tracking_matrix(unit: ThrusterSet) -> np.ndarray:
    """Rows (thrust along +Y, M_X, M_Z) per unit duty, (3, n)."""
    entry = _cached(unit)
    C = entry.get("track")
    if C is None:
        F = unit.force_matrix()
        M = unit.torque_matrix()
        C = np.vstack([F[THRUST_AXIS], M[TORQUE_AXES[0]],
                       M[TORQUE_AXES[1]]])
        entry["track"] = C
    return C


def _finish(unit, k_raw, demand, mode, law) -> LawResult:
    k = np.clip(k_raw, 0.0, 1.0)
    clipped = bool(np.any(k_raw < -_CLIP_TOL) or np.any(k_raw > 1 + _CLIP_TOL))
    achieved = _tracking_matrix(unit) @ k
    return LawResult(duty=k, duty_unclipped=k_raw,
                     status="clipped" if clipped else "ok", demand=demand,
                     achieved=achieved, error=achieved - demand, mode=mode,
                     law=law)


def _group(unit: ThrusterSet, sign: float) -> np.ndarray:
    along = unit.directions[THRUST_AXIS]
    idx = np.flatnonzero(along * sign > 0.5)
    if idx.size != 3:
        raise InvalidValueError(
            f"unit: the unloading law (eq. 2) needs exactly three engines "
            f"thrusting along {'+' if sign > 0 else '-'}Y, got {idx.size}")
    return idx


def _mode(P_T: float) -> str:
    return "group1" if P_T > 0 else ("group2" if P_T < 0 else
                                     "reorientation")


def unloading_law(unit: ThrusterSet, P_T: float, H: ArrayLike, T_T: float,
                  K_unl: float = 1.0) -> LawResult:
    """Duties for a translation with wheel unloading, [4] eq. (2).

    (Reconstructed form, theory §2.)

    One group fires (group 1, +Y, when ``P_T > 0``; group 2, -Y, when
    ``P_T < 0``). Its three duty coefficients solve

    .. math::
        \\sum_i k_i P_i = P_T,\\quad
        \\sum_i k_i M_{x,i} = -K_{unl} H_X / T_T,\\quad
        \\sum_i k_i M_{z,i} = -K_{unl} H_Z / T_T

    with :math:`P_i, M_{x,i}, M_{z,i}` the cycle thrust (signed along +Y)
    and Table 1 torques of engine i at full duty.

    Sign convention: ``H`` is the momentum stored in the wheels (body
    axes) that the thrusters must remove. The wheels hold the attitude, so
    a thruster torque M changes the stored momentum by :math:`T_T M` over
    the cycle and the law leaves :math:`(1 - K_{unl}) H` (``K_unl = 1``
    removes it in one cycle; ``0 < K_unl < 1`` spreads the unloading).

    Parameters
    ----------
    unit : ThrusterSet
        The thruster set (three engines along +Y, three along -Y).
    P_T : float
        Required mean thrust along +Y over the cycle [N], non-zero.
    H : array_like, shape (3,) or (2,)
        Wheel momentum (H_X, H_Y, H_Z) or (H_X, H_Z) [N·m·s].
    T_T : float
        Cycle length [s] (>= ``unit.min_on_time``).
    K_unl : float
        Unloading coefficient [1], >= 0.

    Returns
    -------
    LawResult
        ``status == "clipped"`` when a coefficient left [0, 1]: the
        coefficients are clipped and ``error`` reports the thrust and
        torque errors [N, N·m].
    """
    check_instance(unit, ThrusterSet, "unit")
    P_T = as_finite_scalar(P_T, "P_T")
    if P_T == 0.0:
        raise InvalidValueError(
            "P_T must be non-zero for the unloading law (eq. 2); use "
            "reorientation_law for P_T = 0")
    T = unit.check_cycle(T_T, "T_T")
    K = as_finite_scalar(K_unl, "K_unl")
    check_nonnegative(K, "K_unl")
    Hv = as_finite_array(H, "H")
    if Hv.shape == (3,):
        hx, hz = Hv[0], Hv[2]
    elif Hv.shape == (2,):
        hx, hz = Hv
    else:
        raise InvalidValueError(
            f"H must have shape (3,) or (2,), got {Hv.shape}")
    demand = np.array([P_T, -K * hx / T, -K * hz / T])
    key = "group+" if P_T > 0 else "group-"
    entry = _cached(unit)
    if key not in entry:
        idx = _group(unit, np.sign(P_T))
        C = _tracking_matrix(unit)[:, idx]
        if np.linalg.matrix_rank(C) < 3:
            raise RankError("unit: the firing group's thrust/torque matrix "
                            "is singular (engines collinear?)", int(
                                np.linalg.matrix_rank(C)), 3)
        entry[key] = (idx, np.linalg.inv(C))
    idx, Ci = entry[key]
    k_raw = np.zeros(unit.n)
    k_raw[idx] = Ci @ demand
    return _finish(unit, k_raw, demand, _mode(P_T), "unloading (eq. 2)")


def pair_forces(unit: ThrusterSet, P_T: float, M: ArrayLike) -> np.ndarray:
    """Signed mean pair forces F_1..F_3 of eq. (8) [N].

    .. math::
        \\sum_i F_i = P_T,\\quad \\sum_i F_i\\,x^{arm}_i = M_X,\\quad
        \\sum_i F_i\\,z^{arm}_i = M_Z

    where the arms are the Table 1 torques per newton of the group-1
    engine of pair i (``unit.pairs[i][0]``), F_i > 0 along +Y.
    """
    check_instance(unit, ThrusterSet, "unit")
    if len(unit.pairs) != 3:
        raise InvalidValueError(
            f"unit: eq. (8) needs three opposed engine pairs, got "
            f"{len(unit.pairs)} (ThrusterSet.pairs)")
    P_T = as_finite_scalar(P_T, "P_T")
    Mv = as_finite_array(M, "M", (2,))
    entry = _cached(unit)
    Ci = entry.get("pairs_inv")
    if Ci is None:
        first = [i if unit.directions[THRUST_AXIS, i] > 0 else j
                 for i, j in unit.pairs]
        arms = unit.arms
        C = np.vstack([np.ones(3), arms[TORQUE_AXES[0], first],
                       arms[TORQUE_AXES[1], first]])
        if np.linalg.matrix_rank(C) < 3:
            raise RankError("unit: eq. (8) is singular (pairs collinear?)",
                            int(np.linalg.matrix_rank(C)), 3)
        Ci = np.linalg.inv(C)
        entry["pairs_inv"] = Ci
    return Ci @ np.array([P_T, Mv[0], Mv[1]])


def reorientation_law(unit: ThrusterSet, P_T: float,
                      M: ArrayLike) -> LawResult:
    """Reorientation and hold, [4] eqs. (8)-(9) (reconstructed).

    Solves eq. (8) for the signed pair forces (`pair_forces`), then
    eq. (9): :math:`F_i > 0` fires engine i of group 1 with
    :math:`k_i = F_i / (K_{pi} P_{Di})`, :math:`F_i < 0` fires its pair in
    group 2 with :math:`k_j = -F_i / (K_{pj} P_{Dj})`; at most three of
    the six engines fire. With ``P_T = 0`` the net thrust is zero
    (eq. 10). Modes follow Table 4 (see `LawResult.mode`).

    Parameters
    ----------
    unit : ThrusterSet
        A set with three opposed pairs (`six_thruster_unit`).
    P_T : float
        Required mean thrust along +Y [N] (0 for reorientation).
    M : array_like, shape (2,)
        Demanded torques (M_X, M_Z) [N·m].

    Returns
    -------
    LawResult
        Clipping (k > 1) is reported with ``status == "clipped"`` and the
        resulting thrust/torque error.
    """
    check_instance(unit, ThrusterSet, "unit")
    F = pair_forces(unit, P_T, M)
    P_T = float(P_T)
    Mv = np.asarray(M, dtype=float)
    levels = unit.cycle_thrust
    k_raw = np.zeros(unit.n)
    for f, (i, j) in zip(F, unit.pairs):
        plus, minus = (i, j) if unit.directions[THRUST_AXIS, i] > 0 else (j,
                                                                         i)
        if f > 0:
            k_raw[plus] = f / levels[plus]
        elif f < 0:
            k_raw[minus] = -f / levels[minus]
    mode = _mode(P_T)
    if P_T != 0:
        g1 = unit.directions[THRUST_AXIS] > 0
        used1, used2 = np.any(k_raw[g1] > 0), np.any(k_raw[~g1] > 0)
        if used1 and used2:
            mode = "mixed"
    demand = np.array([P_T, Mv[0], Mv[1]])
    return _finish(unit, k_raw, demand, mode, "reorientation (eqs. 8-9)")
