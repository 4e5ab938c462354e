"""Thruster sets: geometry, thrust model, pulse transients ([4])."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Sequence

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import (InvalidValueError, ShapeError,
                                    UnknownArgumentError)
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_nonnegative,
    check_positive,
)

#: 1 kgf/cm² in Pa ([4] gives inlet pressures in kgf/cm²).
KGF_PER_CM2 = 98066.5
#: Standard gravity [m/s²] (propellant mass = impulse / (Isp g0)).
G0 = 9.80665
#: Mounting angles θ of D1, D2, D3 in the XZ plane, from +X towards +Z
#: [rad] (theory §2); D4, D6, D5 share the positions of D1, D2, D3.
SIX_UNIT_ANGLES = np.deg2rad([180.0, 300.0, 60.0])
#: Engine pairs (0-based) of the six-thruster unit: D1-D4, D2-D6, D3-D5.
SIX_UNIT_PAIRS = ((0, 3), (1, 5), (2, 4))

_UNIT_TOL = 1e-9


def _readonly(arr) -> np.ndarray:
    out = np.array(arr, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class ThrusterSet:
    """A set of ``n`` on/off thrusters fired in pulse-cycle mode.

    Thruster ``i`` (0-based in code, named ``names[i]`` in reports) sits at
    ``positions[:, i]`` and pushes the spacecraft along the unit vector
    ``directions[:, i]`` (body frame). Its steady thrust is [4]
    eq. (1) and its thrust in a cycle eq. (4):

    .. math::
        P_{Di} = a_i p_{in} + b_i,\\qquad
        P^{cyc}_{Di} = K_{pi}(a_i p_{in} + b_i)

    A duty fraction :math:`k_i \\in [0, 1]` (valve command open for
    :math:`t_{rdi} = k_i T_T`, eq. 3) gives the mean force
    :math:`k_i P^{cyc}_{Di} d_i` and mean torque
    :math:`k_i P^{cyc}_{Di} (r_i - c) \\times d_i` over the cycle
    (eqs. 5-6), i.e. ``force_matrix() @ k`` and ``torque_matrix() @ k``.

    Pulse transients ([4]'s "rise and tail-off" model, its refs. [11, 14],
    here a documented first-order model): all valves are
    commanded open at the start of the cycle; valve ``i`` opens after
    ``open_delay`` and closes ``close_delay`` after its close command at
    ``t_on``; the thrust rises as :math:`P(1 - e^{-t'/\\tau_r})` from the
    physical opening and decays as :math:`e^{-t''/\\tau_d}` from the
    physical closing. The impulse of a pulse is then (`pulse_impulse`)

    .. math::
        I(t_{on}) = P\\,[D + (\\tau_d - \\tau_r)(1 - e^{-D/\\tau_r})],
        \\qquad D = \\max(t_{on} + \\delta_c - \\delta_o, 0)

    so short pulses give less than :math:`k P T_T` and the correction
    coefficient :math:`K_p = I(t_{on}) / (P t_{on})` follows
    (`correction_coefficient`).

    Attributes
    ----------
    positions : numpy.ndarray, shape (3, n)
        Thruster positions in the body frame [m].
    directions : numpy.ndarray, shape (3, n)
        Unit force directions on the spacecraft (body frame).
    center_of_mass : numpy.ndarray, shape (3,)
        Centre of mass in the body frame [m].
    pressure_slope : numpy.ndarray, shape (n,)
        :math:`a_i` of eq. (1) [N/Pa].
    thrust_offset : numpy.ndarray, shape (n,)
        :math:`b_i` of eq. (1) [N].
    pressure : float
        Propellant inlet pressure :math:`p_{in}` [Pa].
    correction : numpy.ndarray, shape (n,)
        Cycle correction coefficients :math:`K_{pi}` [1].
    min_on_time : float
        Shortest valve command the drive electronics accept [s].
    open_delay, close_delay : float
        Valve opening and closing delays :math:`\\delta_o, \\delta_c` [s].
    rise_time, tail_time : float
        First-order time constants :math:`\\tau_r, \\tau_d` of the thrust
        rise and tail-off [s].
    isp : float
        Specific impulse [s] (propellant mass flow = P / (Isp g0)).
    pairs : tuple of (int, int)
        Opposed engine pairs on one line of action (opposite directions);
        firing both equally gives no force and no torque.
    names : tuple of str
        Engine names for reports (default ``"D1"`` to ``"Dn"``).
    """

    positions: np.ndarray
    directions: np.ndarray
    center_of_mass: np.ndarray = field(
        default_factory=lambda: np.zeros(3))
    # None by default: __post_init__ stores the (n,) arrays
    pressure_slope: np.ndarray = field(
        default=None)  # type: ignore[arg-type]
    thrust_offset: np.ndarray = field(
        default=None)  # type: ignore[arg-type]
    pressure: float = 9.0 * KGF_PER_CM2
    correction: np.ndarray = field(default=None)  # type: ignore[arg-type]
    min_on_time: float = 0.02
    open_delay: float = 0.02
    close_delay: float = 0.01
    rise_time: float = 0.02
    tail_time: float = 0.015
    isp: float = 220.0
    pairs: tuple[tuple[int, int], ...] = ()
    names: tuple[str, ...] = ()
    if TYPE_CHECKING:   # derived in __post_init__, not dataclass fields
        _arms: np.ndarray = field(init=False)
        _force: np.ndarray = field(init=False)
        _torque: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        """Validate every field and freeze the arrays."""
        pos = as_finite_array(self.positions, "positions", (3, None))
        n = pos.shape[1]
        if n == 0:
            raise ShapeError("positions must have at least one column")
        dirs = as_finite_array(self.directions, "directions", (3, n))
        norms = np.linalg.norm(dirs, axis=0)
        if np.any(np.abs(norms - 1.0) > _UNIT_TOL):
            raise InvalidValueError(
                "directions must be unit columns (normalise them first); "
                f"column norms are {norms}")
        com = as_finite_array(self.center_of_mass, "center_of_mass", (3,))
        pressure = as_finite_scalar(self.pressure, "pressure")
        check_nonnegative(pressure, "pressure")
        slope = (np.zeros(n) if self.pressure_slope is None
                 else as_vector(self.pressure_slope, n, "pressure_slope"))
        offset = (np.zeros(n) if self.thrust_offset is None
                  else as_vector(self.thrust_offset, n, "thrust_offset"))
        corr = (np.ones(n) if self.correction is None
                else as_vector(self.correction, n, "correction"))
        check_positive(corr, "correction")
        steady = slope * pressure + offset
        if np.any(steady <= 0):
            raise InvalidValueError(
                "pressure_slope * pressure + thrust_offset (steady thrust, "
                f"eq. 1) must be positive for every engine, got {steady} N "
                f"at pressure {pressure} Pa")
        scalars = {}
        for name in ("min_on_time", "open_delay", "close_delay",
                     "rise_time", "tail_time", "isp"):
            scalars[name] = as_finite_scalar(getattr(self, name), name)
            check_nonnegative(scalars[name], name)
        check_positive(scalars["isp"], "isp")
        check_positive(scalars["rise_time"], "rise_time")
        pairs = tuple((int(i), int(j)) for i, j in self.pairs)
        for i, j in pairs:
            if not (0 <= i < n and 0 <= j < n) or i == j:
                raise InvalidValueError(
                    f"pairs: ({i}, {j}) is not a pair of distinct engine "
                    f"indices in 0..{n - 1}")
            off_line = np.cross(pos[:, i] - pos[:, j], dirs[:, i])
            if (np.linalg.norm(off_line) > 1e-9
                    or np.linalg.norm(dirs[:, i] + dirs[:, j]) > 1e-9):
                raise InvalidValueError(
                    f"pairs: engines {i} and {j} are not opposed on one "
                    "line of action (opposite directions, collinear)")
        names = tuple(self.names) or tuple(f"D{i + 1}" for i in range(n))
        if len(names) != n:
            raise ShapeError(f"names must have {n} entries, got {len(names)}")
        set_ = object.__setattr__
        set_(self, "positions", _readonly(pos))
        set_(self, "directions", _readonly(dirs))
        set_(self, "center_of_mass", _readonly(com))
        set_(self, "pressure", pressure)
        set_(self, "pressure_slope", _readonly(slope))
        set_(self, "thrust_offset", _readonly(offset))
        set_(self, "correction", _readonly(corr))
        for name, value in scalars.items():
            set_(self, name, value)
        set_(self, "pairs", pairs)
        set_(self, "names", names)
        # derived matrices, computed once (the set is immutable)
        arms = np.cross(pos - com[:, None], dirs, axis=0)
        level = corr * steady
        set_(self, "_arms", _readonly(arms))
        set_(self, "_force", _readonly(dirs * level))
        set_(self, "_torque", _readonly(arms * level))

    # ------------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of thrusters."""
        return self.positions.shape[1]

    @property
    def steady_thrust(self) -> np.ndarray:
        """Steady thrust :math:`P_{Di} = a_i p_{in} + b_i` (eq. 1) [N]."""
        return self.pressure_slope * self.pressure + self.thrust_offset

    @property
    def cycle_thrust(self) -> np.ndarray:
        """Cycle thrust :math:`K_{pi}(a_i p_{in} + b_i)` (eq. 4) [N]."""
        return self.correction * self.steady_thrust

    @property
    def arms(self) -> np.ndarray:
        """Torque per newton :math:`(r_i - c) \\times d_i`, (3, n) [m]."""
        return self._arms

    def force_matrix(self) -> np.ndarray:
        """Mean force per unit duty, (3, n) [N]: ``F = force_matrix() @ k``.

        .. math:: F = \\sum_i k_i K_{pi} P_{Di} d_i \\quad (eq. 6)
        """
        return self._force

    def torque_matrix(self) -> np.ndarray:
        """Mean torque per unit duty, (3, n) [N·m]: ``torque_matrix() @ k``.

        .. math:: M = \\sum_i k_i K_{pi} P_{Di} (r_i - c) \\times d_i
        """
        return self._torque

    def propellant_rate(self) -> np.ndarray:
        """Propellant mass flow of each engine at cycle thrust, (n,) [kg/s].

        .. math:: \\dot m_i = K_{pi} P_{Di} / (I_{sp} g_0)
        """
        return self.cycle_thrust / (self.isp * G0)

    # ------------------------------------------------------------------
    def with_pressure(self, pressure: float) -> "ThrusterSet":
        """Return the same set at another inlet pressure [Pa]."""
        return replace(self, pressure=pressure)

    def with_correction(self, correction: ArrayLike) -> "ThrusterSet":
        """Return the set with other correction coefficients K_p (n,) [1]."""
        return replace(self, correction=as_vector(correction, self.n,
                                                  "correction"))

    def check_cycle(self, cycle: float, name: str = "cycle") -> float:
        """Validate a cycle length T_T [s] against ``min_on_time``."""
        T = as_finite_scalar(cycle, name)
        check_positive(T, name)
        if T < self.min_on_time:
            raise InvalidValueError(
                f"{name} = {T} s is shorter than the thrusters' "
                f"min_on_time = {self.min_on_time} s; use a longer cycle")
        return T

    # ------------------------------------------------------------------
    def pulse_impulse(self, on_time: ArrayLike,
                      steady_thrust: ArrayLike | None = None) -> np.ndarray:
        """Impulse of one pulse under the first-order transient model [N·s].

        .. math::
            I = P\\,[D + (\\tau_d - \\tau_r)(1 - e^{-D/\\tau_r})],
            \\quad D = \\max(t_{on} + \\delta_c - \\delta_o, 0)

        (tail-off integrated to its end, which may fall in the next cycle).

        Parameters
        ----------
        on_time : array_like, shape (n,) or broadcastable
            Valve command durations :math:`t_{rdi}` [s]; 0 = no command.
        steady_thrust : array_like, optional
            Steady thrust P [N]; default `steady_thrust`.

        Returns
        -------
        numpy.ndarray
            Impulse of each pulse [N·s].
        """
        t = np.asarray(on_time, dtype=float)
        if not np.all(np.isfinite(t)) or np.any(t < 0):
            raise InvalidValueError(
                f"on_time must be finite and >= 0, got {t!r}")
        P = self.steady_thrust if steady_thrust is None else np.asarray(
            steady_thrust, dtype=float)
        D = np.where(t > 0, np.maximum(t + self.close_delay
                                       - self.open_delay, 0.0), 0.0)
        rise = 1.0 - np.exp(-D / self.rise_time)
        return P * (D + (self.tail_time - self.rise_time) * rise)

    def cumulative_impulse(self, t: float, on_time: ArrayLike,
                           steady_thrust: ArrayLike | None = None
                           ) -> np.ndarray:
        """Impulse delivered from the cycle start up to time ``t`` [N·s].

        Closed-form integral of `thrust_profile` (same first-order model
        as `pulse_impulse`, which is its limit for large ``t``).

        Parameters
        ----------
        t : float
            Time from the start of the cycle [s] (may exceed the cycle:
            the tail-off of a pulse spills into the next one).
        on_time : array_like, shape (n,)
            Valve command durations [s] (0: no pulse).

        Returns
        -------
        numpy.ndarray, shape (n,)
        """
        t_on = np.asarray(on_time, dtype=float)
        P = self.steady_thrust if steady_thrust is None else np.asarray(
            steady_thrust, dtype=float)
        a = self.open_delay
        c = t_on + self.close_delay
        D = np.where(t_on > 0, np.maximum(c - a, 0.0), 0.0)
        tr, td = self.rise_time, self.tail_time
        up = np.clip(t - a, 0.0, D)
        rising = up - tr * (1.0 - np.exp(-up / tr))
        level = 1.0 - np.exp(-D / tr)
        after = np.maximum(t - c, 0.0)
        tail = (level * td * (1.0 - np.exp(-after / td)) if td > 0
                else 0.0 * level)
        return P * np.where(D > 0, rising + np.where(t > c, tail, 0.0), 0.0)

    def mean_thrust(self, duty: ArrayLike, cycle: float) -> np.ndarray:
        """Return the true mean thrust of each engine over a cycle, (n,) [N].

        ``pulse_impulse(duty * cycle) / cycle``; compare with the linear
        cycle model ``duty * cycle_thrust``.
        """
        T = self.check_cycle(cycle)
        k = np.asarray(duty, dtype=float)
        return self.pulse_impulse(k * T) / T

    def correction_coefficient(self, cycle: float,
                               duty: ArrayLike = 1.0) -> np.ndarray:
        """Correction coefficients :math:`K_{pi}` for pulses of ``duty``.

        .. math:: K_{pi} = I(k T_T) / (P_{Di}\\, k T_T)

        i.e. the ratio of the true mean thrust of a pulse of duty ``k`` in a
        cycle of ``cycle`` seconds to ``k`` times the steady thrust (eq. 4).

        Parameters
        ----------
        cycle : float
            Cycle length T_T [s].
        duty : float or array_like (n,)
            Reference duty fraction(s) in (0, 1].

        Returns
        -------
        numpy.ndarray, shape (n,)
        """
        T = self.check_cycle(cycle)
        k = as_vector(duty, self.n, "duty")
        if np.any(k <= 0) or np.any(k > 1):
            raise InvalidValueError(f"duty must lie in (0, 1], got {k}")
        if np.any(k * T < self.min_on_time):
            raise InvalidValueError(
                f"duty * cycle = {k * T} s is below min_on_time "
                f"{self.min_on_time} s")
        return self.pulse_impulse(k * T) / (self.steady_thrust * k * T)

    def calibrated(self, cycle: float, duty: ArrayLike = 1.0) -> "ThrusterSet":
        """Return the set with K_p from `correction_coefficient` (firing)."""
        return self.with_correction(self.correction_coefficient(cycle, duty))

    def thrust_profile(self, times: ArrayLike, on_time: ArrayLike,
                       steady_thrust: ArrayLike | None = None) -> np.ndarray:
        """Instantaneous thrust of each engine during a pulse, (n, m) [N].

        Parameters
        ----------
        times : array_like, shape (m,)
            Times from the start of the cycle [s].
        on_time : array_like, shape (n,)
            Valve command durations [s].
        """
        t = np.asarray(times, dtype=float)[None, :]
        t_on = np.broadcast_to(np.asarray(on_time, dtype=float),
                               (self.n,))[:, None]
        P = (self.steady_thrust if steady_thrust is None
             else np.asarray(steady_thrust, dtype=float))[:, None]
        t_open = self.open_delay
        t_close = t_on + self.close_delay
        fired = (t_on > 0) & (t_close > t_open)
        up = np.clip(t - t_open, 0.0, None)
        level = 1.0 - np.exp(-np.minimum(up, np.clip(t_close - t_open, 0,
                                                     None)) / self.rise_time)
        decay = np.where(t > t_close,
                         np.exp(-(t - t_close) / max(self.tail_time, 1e-12)),
                         1.0)
        if self.tail_time == 0:
            decay = np.where(t > t_close, 0.0, 1.0)
        return np.where(fired & (t >= t_open), P * level * decay, 0.0)


def six_thruster_unit(R: float = 0.25, L: float = 0.3,
                      thrust: ArrayLike = 0.5,
                      pressure: float = 9.0 * KGF_PER_CM2,
                      thrust_offset: ArrayLike = 0.0,
                      center_of_mass: Sequence[float] = (0.0, 0.0, 0.0),
                      correction: ArrayLike = 1.0, **kwargs) -> ThrusterSet:
    """Build the six-thruster unit of [4] (engines ordered D1..D6).

    Two groups of three engines on a circle of radius ``R`` in planes
    ``y = -L`` (group 1, D1-D3, thrust along +Y) and ``y = +L`` (group 2,
    D4-D6, thrust along -Y). Angles θ from +X towards +Z: D1 180°,
    D2 300°, D3 60°; D4 shares D1's (x, z), D6 D2's, D5 D3's. A +Y thrust
    P at (x, z) gives :math:`M_x = -zP`, :math:`M_z = xP` (Table 1,
    reconstructed in theory §2).

    Parameters
    ----------
    R : float
        Radius of the mounting circle [m].
    L : float
        Distance of each mounting plane from the centre of mass [m].
    thrust : float or array_like (6,)
        Steady thrust of each engine at ``pressure`` [N] (0.5 N at
        9 kgf/cm² in [4]).
    pressure : float
        Nominal inlet pressure [Pa].
    thrust_offset : float or array_like (6,)
        :math:`b_i` of eq. (1) [N]; :math:`a_i` is chosen so that
        :math:`a_i p + b_i` equals ``thrust`` at ``pressure``.
    center_of_mass : sequence of 3 float
        Centre of mass in the unit's frame [m].
    correction : float or array_like (6,)
        K_p of each engine.
    **kwargs
        Other `ThrusterSet` fields (``min_on_time``, ``open_delay``,
        ``close_delay``, ``rise_time``, ``tail_time``, ``isp``).

    Returns
    -------
    ThrusterSet
    """
    R = as_finite_scalar(R, "R")
    L = as_finite_scalar(L, "L")
    check_positive(R, "R")
    check_nonnegative(L, "L")
    p = as_finite_scalar(pressure, "pressure")
    check_positive(p, "pressure")
    P = as_vector(thrust, 6, "thrust")
    check_positive(P, "thrust")
    b = as_vector(thrust_offset, 6, "thrust_offset")
    unknown = set(kwargs) - {"min_on_time", "open_delay", "close_delay",
                             "rise_time", "tail_time", "isp", "names"}
    if unknown:
        raise UnknownArgumentError(
            f"six_thruster_unit() got unknown keyword argument(s) "
            f"{sorted(unknown)}; it takes min_on_time, open_delay, "
            f"close_delay, rise_time, tail_time, isp, names")
    com = as_finite_array(center_of_mass, "center_of_mass", (3,))
    th = SIX_UNIT_ANGLES
    x, z = R * np.cos(th), R * np.sin(th)
    # D1, D2, D3 (group 1, y = -L) then D4 (=D1), D5 (=D3), D6 (=D2)
    order = [0, 1, 2, 0, 2, 1]
    ys = [-L] * 3 + [L] * 3
    positions = np.array([[x[j] for j in order], ys, [z[j] for j in order]])
    directions = np.zeros((3, 6))
    directions[1, :3] = 1.0
    directions[1, 3:] = -1.0
    pos = positions
    return ThrusterSet(
        positions=pos, directions=directions,
        center_of_mass=com,
        pressure_slope=(P - b) / p, thrust_offset=b, pressure=p,
        correction=as_vector(correction, 6, "correction"),
        pairs=SIX_UNIT_PAIRS, **kwargs)
