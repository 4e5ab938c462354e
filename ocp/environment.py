"""Orbit environment of seed 002: orbit frame, gravity gradient, dipole field.

Orbit frame (SPEC 3, seed 002): X1 along the velocity, X3 along the radius
vector (up), X2 = X3 x X1 the orbit normal; on a circular orbit it turns
about X2 at the orbit rate ω0, so its angular velocity in its own axes is
``(0, ω0, 0)``. Attitude is the quaternion q of the body relative to the
orbit frame (``v_orbit = R(q) v_body``, scalar first), so the matrix
``A = R(q)^T`` takes orbit-frame vectors into body axes.

Every function accepts numpy arrays or CasADi symbols and returns the same
kind, so one formula serves simulation and code generation.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_scalar

from .attitude import _lib, _vcat

#: Earth's gravitational parameter [m³/s²].
MU_EARTH = 3.986004418e14
#: Earth's dipole strength μ0 M / (4π) [T·m³] (IGRF g10 ≈ 29,400 nT).
MU_DIPOLE = 7.94e15


@dataclass(frozen=True)
class CircularOrbit:
    """A circular orbit.

    Attributes
    ----------
    radius : float
        Orbit radius r [m] (Chibis-M: 6850 km).
    inclination : float
        Inclination i [rad] (Chibis-M: 51.7°).
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
        """Orbit rate ω0 = sqrt(μ / r³) [rad/s]."""
        return float(np.sqrt(MU_EARTH / self.radius**3))

    @property
    def period(self) -> float:
        """Orbit period 2π/ω0 [s]."""
        return 2 * np.pi / self.rate

    @property
    def field_strength(self) -> float:
        """B0 = μ_e / r³ [T], the direct dipole's scale at this radius."""
        return MU_DIPOLE / self.radius**3


def dipole_field_orbit(orbit: CircularOrbit, u):
    r"""Direct-dipole geomagnetic field in orbit axes [T] (seed 002).

    .. math::
        B_1 = B_0 \sin i \cos u,\quad B_2 = B_0 \cos i,\quad
        B_3 = -2 B_0 \sin i \sin u

    Parameters
    ----------
    u : float or casadi
        Argument of latitude [rad].
    """
    lib = _lib(u)
    b0, i = orbit.field_strength, orbit.inclination
    return _vcat(lib, [b0 * np.sin(i) * lib.cos(u), b0 * np.cos(i) + 0 * u,
                       -2 * b0 * np.sin(i) * lib.sin(u)])


def dipole_field_rate_orbit(orbit: CircularOrbit, u):
    """Time derivative of `dipole_field_orbit` along the orbit [T/s]."""
    lib = _lib(u)
    b0, i, w0 = orbit.field_strength, orbit.inclination, orbit.rate
    return _vcat(lib, [-b0 * w0 * np.sin(i) * lib.sin(u), 0 * u,
                       -2 * b0 * w0 * np.sin(i) * lib.cos(u)])


def gravity_gradient_torque(rate: float, inertia, vertical_body):
    r"""Gravity-gradient torque, seed 002 eq. (1.5) [N·m].

    .. math:: M_{gr} = 3\omega_0^2\, E_3 \times J E_3

    Parameters
    ----------
    rate : float
        Orbit rate ω0 [rad/s].
    inertia : (3, 3) array or casadi
        Inertia J [kg·m²].
    vertical_body : (3,) array or casadi
        Local vertical E3 (unit radius vector) in body axes.
    """
    lib = _lib(vertical_body, inertia)
    e3 = vertical_body
    je3 = inertia @ e3
    cross = ca.cross(e3, je3) if lib is ca else np.cross(e3, je3)
    return 3.0 * rate**2 * cross


def magnetic_torque(dipole, field):
    """Magnetic torque ``m x B``, seed 002 eq. (1.6) [N·m]."""
    if _lib(dipole, field) is ca:
        return ca.cross(dipole, field)
    return np.cross(dipole, field)


def bdot_dipole(gain: float, field_rate_body, max_dipole, coils=None):
    """The "-Bdot" damping law, seed 002 eq. (1.7), per-coil saturated.

    ``m_i = clip(-k dB_i/dt, -m_max, m_max)`` for working coils, 0 for
    failed ones (a failed coil carries no current).

    Parameters
    ----------
    gain : float
        k [A·m²·s/T].
    field_rate_body : (3,) array or casadi
        Derivative of the field seen in body axes [T/s].
    max_dipole : float
        Saturation of each coil [A·m²] (Chibis-M: 3.2).
    coils : (3,) array, optional
        1 for a working coil, 0 for a failed one.
    """
    lib = _lib(field_rate_body)
    raw = -gain * field_rate_body
    m = lib.fmin(lib.fmax(raw, -max_dipole), max_dipole) if lib is ca \
        else np.clip(raw, -max_dipole, max_dipole)
    if coils is not None:
        m = m * (ca.DM(coils) if lib is ca else np.asarray(coils))
    return m
