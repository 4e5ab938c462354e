"""Spacecraft models: rigid body with wheels and thrusters, angles."""

from .angles import (
    body_rates_from_angle_rates,
    dcm_body_from_ref_ek,
    ek_angle_rates,
    ek_angle_rates_function,
    ek_from_quat,
    quat_from_ek,
)
from .rigid import (
    SpacecraftModel,
    check_inertia,
    dynamics_numpy,
    euler_krylov_model,
    rigid_spacecraft,
)
from .trajectory import (
    SlewTrajectory,
)

__all__ = [
    "SlewTrajectory",
    "SpacecraftModel",
    "body_rates_from_angle_rates",
    "check_inertia",
    "dcm_body_from_ref_ek",
    "dynamics_numpy",
    "ek_angle_rates",
    "ek_angle_rates_function",
    "ek_from_quat",
    "euler_krylov_model",
    "quat_from_ek",
    "rigid_spacecraft",
]
