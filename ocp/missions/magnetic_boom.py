"""Chibis-M ([2]): magnetic and wheel actuators, failures, gravity boom.

One closed-loop ODE holds the spacecraft in the orbit frame (`environment`)
with three coils running "-Bdot" (eq. 1.7) plus an optional constant
dipole, three orthogonal wheel pairs running the paper's law (eq. 1.8) or a
constant spin-up torque, and failures of coils and wheel pairs. It is a
CasADi expression integrated by CVODES.

State ``x = (q (4), ω (3), H (3), u)``: q the body attitude relative to
the orbit frame (scalar first, ``v_orbit = R(q) v_body``), ω the absolute
body rate in body axes [rad/s], H the wheel momentum vector in body axes
[N·m·s], u the argument of latitude [rad].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from adcs_common.results import ResultMixin

from adcs_common.exceptions import InvalidValueError, ShapeError
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_positive,
)

from adcs_common.quaternion import (
    quat_from_axis_angle,
    quat_mul,
    quat_rate,
    quat_to_dcm,
)
from ocp.missions.orbit_environment import (
    EARTH_DIPOLE,
    bdot_dipole,
    dipole_field_orbit,
    gravity_gradient_torque,
    orbit_rate,
    orbit_wheel_law_expr,
)

__all__ = [
    "ChibisConfig",
    "ChibisRun",
    "CircularOrbit",
    "MAX_DIPOLE",
    "N_PARAMS",
    "STOWED_INERTIA",
    "airplane_angles",
    "closed_loop_ode",
    "deployed_inertia",
    "dipole_scale_gain",
    "initial_state",
    "pitch_offset_eq37",
    "planar_boom_rotates",
    "planar_critical_dipole",
    "planar_model_critical_dipole",
    "simulate",
]


@dataclass(frozen=True)
class CircularOrbit:
    """The circular orbit of a study (Chibis-M by default).

    Attributes
    ----------
    radius : float
        Orbit radius r [m] (6850 km).
    inclination : float
        Inclination i [rad] (51.7°).
    """

    radius: float = 6850e3
    inclination: float = np.deg2rad(51.7)

    def __post_init__(self) -> None:
        """Check the orbit."""
        r = as_finite_scalar(self.radius, "radius")
        if r < 6.4e6:
            raise InvalidValueError(
                f"radius is the orbit radius from Earth's centre in metres, "
                f"got {r} (below the surface)")
        as_finite_scalar(self.inclination, "inclination")

    @property
    def rate(self) -> float:
        """Orbit rate ω0 [rad/s]."""
        return orbit_rate(self.radius)

    @property
    def period(self) -> float:
        """Orbit period 2π/ω0 [s]."""
        return 2 * np.pi / self.rate

    @property
    def field_strength(self) -> float:
        """B0 = μ_e / r³ [T], the direct dipole's scale at this radius."""
        return EARTH_DIPOLE / self.radius**3

    def field(self, u):
        """Direct-dipole field in orbit axes at argument of latitude u [T]."""
        return dipole_field_orbit(u, self.inclination, self.radius)


#: Inertia before the boom is deployed [kg·m²] ([2]).
STOWED_INERTIA = (1.02, 1.51, 1.73)
#: Chibis-M coil saturation [A·m²] ([2]).
MAX_DIPOLE = 3.2


def deployed_inertia(orbit: CircularOrbit | None = None, *,
                     epsilon: float = 0.16, offset_deg: float = 6.0,
                     dipole: float = 0.1) -> tuple[float, float, float]:
    """Boom-deployed inertia (A, B, C) inferred from the paper's figures.

    The paper gives no deployed inertia. Its small parameter
    ``ε = k B0 / (B ω0²) ≈ 0.16`` at ``k = 0.1 A·m²`` gives B, and its
    6° offset at the same dipole through eq. (3.7) gives ``A - C``; C (about
    the boom) keeps its stowed value 1.73 kg·m².

    Returns
    -------
    (A, B, C) : tuple of float
        Principal inertia [kg·m²].
    """
    orbit = orbit or CircularOrbit()
    for value, name in ((epsilon, "epsilon"), (offset_deg, "offset_deg"),
                        (dipole, "dipole")):
        check_positive(as_finite_scalar(value, name), name)
    w0, b0, i = orbit.rate, orbit.field_strength, orbit.inclination
    B = dipole * b0 / (epsilon * w0**2)
    a_minus_c = 2 * b0 * dipole * np.sin(i)**2 / (
        3 * w0**2 * np.deg2rad(offset_deg))
    C = STOWED_INERTIA[2]
    return (C + a_minus_c, B, C)


def pitch_offset_eq37(orbit: CircularOrbit, inertia, dipole: float) -> float:
    r"""Steady pitch offset under a constant dipole along the boom, eq. (3.7).

    .. math:: \alpha_1 = \frac{2 B_0 k \sin^2 i}{3\omega_0^2 (A - C)}

    (the extraction prints ``C - A``; with ``A > C`` the magnitude is
    this). Returns radians.
    """
    A, _, C = inertia
    return float(2 * orbit.field_strength * dipole * np.sin(
        orbit.inclination)**2 / (3 * orbit.rate**2 * (A - C)))


@dataclass(frozen=True)
class ChibisConfig:
    """Actuators, gains and failures of one simulation.

    Attributes
    ----------
    inertia : (3,) tuple
        Principal inertia (A, B, C) [kg·m²].
    orbit : CircularOrbit
    bdot_gain : float
        "-Bdot" gain k [A·m²·s/T] (0: coils off).
    max_dipole : float
        Coil saturation [A·m²].
    coils : (3,) tuple
        1 working, 0 failed (a failed coil carries no current).
    constant_dipole : (3,) tuple
        Dipole added in body axes [A·m²] (e.g. along the boom, x3).
    wheel_gains : (k_ω, k_a)
        Gains of the wheel law eq. (1.8) [N·m·s, N·m] (0, 0: law off).
    spin_torque : (3,) tuple
        Constant wheel torque in body axes [N·m] (pitch-wheel spin-up).
    spin_limit : float
        Wheel momentum at which the spin-up torque stops [N·m·s].
    wheel_pairs : (3,) tuple
        1 working, 0 failed pair (a failed pair keeps its momentum).
    """

    inertia: tuple = STOWED_INERTIA
    orbit: CircularOrbit = field(default_factory=CircularOrbit)
    bdot_gain: float = 0.0
    max_dipole: float = MAX_DIPOLE
    coils: tuple = (1.0, 1.0, 1.0)
    constant_dipole: tuple = (0.0, 0.0, 0.0)
    wheel_gains: tuple = (0.0, 0.0)
    spin_torque: tuple = (0.0, 0.0, 0.0)
    spin_limit: float = np.inf
    wheel_pairs: tuple = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        """Check the configuration."""
        inertia = as_vector(self.inertia, 3, "inertia")
        if np.any(inertia <= 0):
            raise InvalidValueError(f"inertia must be positive, got "
                                    f"{inertia}")
        for name in ("coils", "wheel_pairs"):
            v = as_vector(getattr(self, name), 3, name)
            if not np.all(np.isin(v, (0.0, 1.0))):
                raise InvalidValueError(f"{name} entries must be 0 or 1, "
                                        f"got {v}")
        as_vector(self.constant_dipole, 3, "constant_dipole")
        as_vector(self.spin_torque, 3, "spin_torque")
        as_vector(self.wheel_gains, 2, "wheel_gains")


def _params(cfg: ChibisConfig) -> np.ndarray:
    spin_limit = cfg.spin_limit if np.isfinite(cfg.spin_limit) else 1e9
    return np.concatenate([
        [cfg.bdot_gain, cfg.max_dipole], cfg.coils,
        cfg.constant_dipole, cfg.wheel_gains, cfg.spin_torque, [spin_limit],
        cfg.wheel_pairs]).astype(float)


N_PARAMS = 17


def closed_loop_ode(orbit: CircularOrbit, inertia) -> ca.Function:
    """Right-hand side ``f(x, p) -> xdot`` of the Chibis-M closed loop.

    Parameters
    ----------
    orbit : CircularOrbit
    inertia : (3,) array_like
        Principal inertia [kg·m²].

    ``p`` packs the rest of `ChibisConfig` (Bdot gain, saturation, coil
    mask, constant dipole, wheel-law gains, spin torque and limit, pair
    mask), so one Function serves every actuator setting.
    """
    x = ca.SX.sym("x", 11)
    p = ca.SX.sym("p", N_PARAMS)
    q, w, H, u = x[0:4], x[4:7], x[7:10], x[10]
    J = np.diag(as_vector(inertia, 3, "inertia"))
    k_bdot, m_max, coils = p[0], p[1], p[2:5]
    m_const, k_w, k_a = p[5:8], p[8], p[9]
    spin, spin_limit, pairs = p[10:13], p[13], p[14:17]
    w0 = orbit.rate
    A = quat_to_dcm(q).T                       # body from orbit
    w_orb = A @ ca.DM([0.0, w0, 0.0])
    w_rel = w - w_orb
    B_orbit = orbit.field(u)
    B = A @ B_orbit
    B_dot = A @ (ca.jacobian(B_orbit, u) * w0) - ca.cross(w_rel, B)
    dipole = bdot_dipole(B_dot, k_bdot, m_max, coils) + m_const
    e3 = A @ ca.DM([0.0, 0.0, 1.0])
    torque = gravity_gradient_torque(J, e3, w0) + ca.cross(dipole, B)
    # eq. (1.8), the same expression as `orbit_wheel_law`, gains symbolic
    Jd = ca.DM(J)
    law = orbit_wheel_law_expr(J, w0, A, w, H, k_w, k_a)
    law = ca.if_else(k_w + k_a > 0, law, ca.DM.zeros(3))
    spin_on = ca.fabs(H) < spin_limit
    h_dot = pairs * (law + spin * spin_on)
    w_dot = ca.DM(np.linalg.inv(J)) @ (-ca.cross(w, Jd @ w + H) + torque
                                       - h_dot)
    x_dot = ca.vertcat(quat_rate(q, w_rel), w_dot, h_dot, w0)
    return ca.Function("chibis_ode", [x, p], [x_dot], ["x", "p"], ["xdot"])


@dataclass(frozen=True, eq=False, repr=False)
class ChibisRun(ResultMixin):
    """A simulated trajectory.

    Attributes
    ----------
    t : (K,) ndarray
        Time [s].
    q : (K, 4) ndarray
        Attitude relative to the orbit frame (scalar first).
    w : (K, 3) ndarray
        Absolute body rate [rad/s].
    w_rel : (K, 3) ndarray
        Body rate relative to the orbit frame [rad/s].
    H : (K, 3) ndarray
        Wheel momentum [N·m·s].
    angles : (K, 3) ndarray
        Airplane angles (α, β, γ) of eq. (1.1) [rad]: α pitch about the
        orbit normal.
    config : ChibisConfig
    """

    t: np.ndarray
    q: np.ndarray
    w: np.ndarray
    w_rel: np.ndarray
    H: np.ndarray
    angles: np.ndarray
    config: ChibisConfig


def airplane_angles(A: np.ndarray) -> np.ndarray:
    """Angles (α, β, γ) of eq. (1.1) from body-from-orbit matrices (K,3,3).

    ``A[0] = (cα cβ, sβ, -sα cβ)``, ``A[1, 1] = cβ cγ``,
    ``A[2, 1] = -cβ sγ``.
    """
    alpha = np.arctan2(-A[:, 0, 2], A[:, 0, 0])
    beta = np.arcsin(np.clip(A[:, 0, 1], -1, 1))
    gamma = np.arctan2(-A[:, 2, 1], A[:, 1, 1])
    return np.column_stack([alpha, beta, gamma])


def initial_state(cfg: ChibisConfig, angles_deg=(0.0, 0.0, 0.0),
                  rel_rate_deg=(0.0, 0.0, 0.0), u0: float = 0.0,
                  H0=(0.0, 0.0, 0.0)) -> np.ndarray:
    """State from airplane-like angles [deg] and relative rates [deg/s].

    The attitude is the rotation by α about x2, then β about x3, then γ
    about x1 (small-angle consistent with eq. 1.1).
    """
    a, b, g = np.deg2rad(as_vector(angles_deg, 3, "angles_deg"))
    q = quat_mul(quat_mul(quat_from_axis_angle([0, 1, 0], -a),
                          quat_from_axis_angle([0, 0, 1], b)),
                 quat_from_axis_angle([1, 0, 0], g))
    A = quat_to_dcm(q).T
    w = A @ np.array([0.0, cfg.orbit.rate, 0.0]) + np.deg2rad(
        as_vector(rel_rate_deg, 3, "rel_rate_deg"))
    return np.concatenate([q, w, as_vector(H0, 3, "H0"), [u0]])


def simulate(cfg: ChibisConfig, x0, duration: float, *,
             n_out: int = 600, rtol: float = 1e-8,
             atol: float = 1e-10) -> ChibisRun:
    """Integrate the closed loop with CVODES.

    Parameters
    ----------
    cfg : ChibisConfig
    x0 : (11,) array
        Initial state (see `initial_state`).
    duration : float
        Length [s].
    n_out : int
        Output samples.

    Raises
    ------
    ShapeError, InvalidValueError
        Bad state or duration.
    """
    x0 = as_finite_array(x0, "x0", (11,))
    if not duration > 0:
        raise InvalidValueError(f"duration must be positive, got {duration}")
    if n_out < 2:
        raise ShapeError(f"n_out must be at least 2, got {n_out}")
    f = closed_loop_ode(cfg.orbit, cfg.inertia)
    x = ca.SX.sym("x", 11)
    p = ca.SX.sym("p", N_PARAMS)
    t = np.linspace(0.0, duration, n_out)
    integ = ca.integrator("chibis", "cvodes", {"x": x, "p": p,
                                               "ode": f(x, p)},
                          0.0, t[1:], {"reltol": rtol, "abstol": atol,
                                       "max_num_steps": 200000})
    xs = np.array(integ(x0=x0, p=_params(cfg))["xf"]).T
    X = np.vstack([x0, xs])
    q = X[:, 0:4] / np.linalg.norm(X[:, 0:4], axis=1, keepdims=True)
    A = np.transpose(np.array([quat_to_dcm(qk) for qk in q]), (0, 2, 1))
    w = X[:, 4:7]
    w_rel = w - A @ np.array([0.0, cfg.orbit.rate, 0.0])
    return ChibisRun(t, q, w, w_rel, X[:, 7:10], airplane_angles(A), cfg)


def dipole_scale_gain(orbit: CircularOrbit, dipole: float) -> float:
    """-Bdot gain whose dipole amplitude near orbital attitude is ``dipole``.

    Held in the orbit frame the field turns at ~ω0, so ``|dB/dt| ~ B0 ω0``
    and the gain ``k = dipole / (B0 ω0)`` [A·m²·s/T] gives coils of about
    ``dipole`` [A·m²]: the "dipole moment of the coils" that eq. (3.7)'s
    k stands for.
    """
    return dipole / (orbit.field_strength * orbit.rate)


def planar_boom_rotates(inertia, orbit: CircularOrbit, dipole: float, *,
                        alpha0: float = 0.0, rate0: float = 0.0,
                        u0: float = 0.0, n_orbits: float = 5.0) -> bool:
    r"""Whether the boom leaves the vertical: planar motion, eq. (3.4).

    Polar orbit, constant dipole k along the boom (x3):

    .. math::
        B\ddot\alpha + 3\omega_0^2 (A - C)\sin\alpha\cos\alpha =
        k B_0 (\cos\alpha\cos u + 2\sin\alpha\sin u)

    integrated from ``alpha0`` [rad] and pitch rate ``rate0`` [rad/s]
    relative to the orbit frame; True when ``|α|`` passes 90° (rotation), False
    when it oscillates about the vertical for ``n_orbits``.
    """
    from scipy.integrate import solve_ivp

    A, B, C = inertia
    w0, b0 = orbit.rate, orbit.field_strength

    def rhs(tau, y):
        a, da = y
        u = u0 + tau
        dda = (-3.0 * (A - C) * np.sin(a) * np.cos(a) + dipole * b0 / w0**2
               * (np.cos(a) * np.cos(u) + 2.0 * np.sin(a) * np.sin(u))) / B
        return [da, dda]

    def over(tau, y):
        return np.pi / 2 - abs(y[0])

    setattr(over, "terminal", True)    # solve_ivp: the event stops it
    sol = solve_ivp(rhs, (0.0, 2 * np.pi * n_orbits), [alpha0, rate0 / w0],
                    events=over, rtol=1e-8, atol=1e-10, max_step=0.05)
    return bool(sol.t_events[0].size)


def planar_model_critical_dipole(inertia, orbit: CircularOrbit,
                                 rate0: float, alpha0: float = 0.0
                                 ) -> float:
    r"""Largest dipole that keeps the boom oscillating: the paper's model.

    [2] simplifies (3.4) to a linear oscillator with the largest
    forcing: the free amplitude
    :math:`\alpha_{gr} = \sqrt{\alpha_0^2 + (\dot\alpha_0/\lambda)^2}`,
    :math:`\lambda^2 = 3\omega_0^2 (A-C)/B`, plus the forced amplitude
    :math:`\alpha_{mag} = 2 k B_0 / (B\omega_0^2)` must stay below 90°.
    Returns k [A·m²] (0 if even k = 0 rotates).
    """
    A, B, C = inertia
    w0, b0 = orbit.rate, orbit.field_strength
    lam = w0 * np.sqrt(3 * (A - C) / B)
    a_gr = np.hypot(alpha0, rate0 / lam)
    return float(max(np.pi / 2 - a_gr, 0.0) * B * w0**2 / (2 * b0))


def planar_critical_dipole(inertia, orbit: CircularOrbit, rate0: float, *,
                           alpha0: float = 0.0, phase: str = "worst",
                           n_phases: int = 8, n_orbits: float = 5.0,
                           k_max: float = 2.0, tol: float = 0.005) -> float:
    """Largest dipole [A·m²] for which (3.4) keeps oscillating.

    Bisection on k; at each k the motion from (``alpha0``, ``rate0``) is
    integrated for ``n_phases`` initial arguments of latitude
    (`planar_boom_rotates`). ``phase="worst"``: every phase must oscillate;
    ``"best"``: one phase suffices.
    """
    if phase not in ("worst", "best"):
        raise InvalidValueError(
            f"phase must be 'worst' or 'best', got {phase!r}")
    phases = np.linspace(0, 2 * np.pi, n_phases, endpoint=False)
    agg = any if phase == "worst" else all

    def rotates(k):
        return agg(planar_boom_rotates(inertia, orbit, k, alpha0=alpha0,
                                       rate0=rate0, u0=u, n_orbits=n_orbits)
                   for u in phases)

    lo, hi = 0.0, k_max
    if rotates(lo):
        return 0.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if rotates(mid) else (mid, hi)
    return lo
