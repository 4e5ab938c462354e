"""Brushless DC wheel-motor model: current draw, power, allocation weights.

The model (per wheel, SI units):

* motor current ``i = m / k_t`` [A] for motor torque ``m`` [N·m];
* terminal voltage ``u = R i + k_e Ω`` [V] (winding resistance R [Ω],
  back-EMF constant k_e [V·s/rad], wheel speed Ω [rad/s]);
* the drive saturates at the bus voltage U, so the torque available in the
  direction that accelerates the wheel is
  ``m_avail(Ω) = k_t (U - k_e |Ω|) / R``;
* electrical power drawn ``P = R i² + p(m Ω)`` with the mechanical power
  ``m Ω`` counted in full when motoring and only a fraction ``η`` (the
  regeneration efficiency, 0 = none, 1 = ideal) when braking:
  ``p(x) = max(x, η x)``, a convex function, so power-optimal allocation
  stays a QP.

[1] weighs wheel torques by a positive function of each motor's current
draw (criterion ``J = Σ V_i m_i²``, ref. [10]). Here
``V_i = 1 / m_avail,i(Ω_i)²``: J is the sum of squared current draws, each
as a fraction of the current the drive can still deliver at that speed,
so fast (back-EMF limited) wheels are asked for less.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InfeasibleError, InvalidValueError
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    check_nonnegative,
    check_positive,
)


@dataclass(frozen=True)
class WheelMotor:
    """Electrical parameters of one wheel motor (an example, not a datasheet).

    Attributes
    ----------
    torque_constant : float
        k_t [N·m/A].
    resistance : float
        Winding resistance R [Ω].
    back_emf : float
        Back-EMF constant k_e [V·s/rad] (equals k_t in SI for an ideal
        motor).
    bus_voltage : float
        Supply voltage U [V].
    rotor_inertia : float
        Rotor inertia about the spin axis [kg·m²]; speed Ω = H / I.
    regen_efficiency : float
        Fraction η in [0, 1] of braking mechanical power returned to the
        bus.
    """

    torque_constant: float = 0.05
    resistance: float = 1.5
    back_emf: float = 0.05
    bus_voltage: float = 28.0
    rotor_inertia: float = 0.01
    regen_efficiency: float = 0.5

    def __post_init__(self) -> None:
        """Check the fields and store read-only copies."""
        for name in ("torque_constant", "resistance", "back_emf",
                     "bus_voltage", "rotor_inertia"):
            check_positive(as_finite_scalar(getattr(self, name), name), name)
        eta = as_finite_scalar(self.regen_efficiency, "regen_efficiency")
        check_nonnegative(eta, "regen_efficiency")
        if eta > 1:
            raise InvalidValueError(
                f"regen_efficiency must lie in [0, 1], got {eta}")

    @property
    def no_load_speed(self) -> float:
        """Speed at which the back-EMF reaches the bus voltage [rad/s]."""
        return self.bus_voltage / self.back_emf

    def speed(self, momentum: ArrayLike) -> np.ndarray:
        """Wheel speed Ω [rad/s] from wheel momentum H [N·m·s]."""
        return as_finite_array(momentum, "momentum") / self.rotor_inertia

    def current(self, torque: ArrayLike) -> np.ndarray:
        """Motor current i = m / k_t [A]."""
        return as_finite_array(torque, "torque") / self.torque_constant

    def available_torque(self, speed: ArrayLike) -> np.ndarray:
        """Torque the drive can deliver at speed Ω [N·m] (accelerating)."""
        speed = as_finite_array(speed, "speed")
        return self.torque_constant * (
            self.bus_voltage - self.back_emf * np.abs(speed)) / self.resistance

    def current_weights(self, speed: ArrayLike) -> np.ndarray:
        """Weights ``V_i = 1 / m_avail(Ω_i)²`` [1/(N·m)²] for the weighted law.

        Raises
        ------
        InfeasibleError
            A wheel is at or beyond its no-load speed (no torque left).
        """
        avail = self.available_torque(speed)
        if np.any(avail <= 0):
            raise InfeasibleError(
                "speed: a wheel is at or beyond the no-load speed "
                f"{self.no_load_speed:.1f} rad/s; it has no torque left",
                problem=np.asarray(speed))
        return 1.0 / avail**2

    def copper_coefficient(self) -> float:
        """R / k_t² [W/(N·m)²]: winding loss per squared torque."""
        return self.resistance / self.torque_constant**2

    def electrical_power(self, torque: ArrayLike,
                         speed: ArrayLike) -> np.ndarray:
        """Electrical power drawn [W], ``R (m/k_t)² + max(mΩ, η mΩ)``."""
        m = as_finite_array(torque, "torque")
        w = as_finite_array(speed, "speed")
        mech = m * w
        return self.copper_coefficient() * m**2 + np.maximum(
            mech, self.regen_efficiency * mech)

