"""`ocp`: spacecraft models, slews, MPC, code export and the command line."""

from .attitude import (
    body_rates_from_angle_rates,
    dcm_body_from_ref_ek,
    ek_angle_rates,
    ek_angle_rates_function,
    ek_from_quat,
    quat_conj,
    quat_error_angle,
    quat_from_axis_angle,
    quat_from_ek,
    quat_mul,
    quat_rate,
    quat_to_dcm,
    rotation_between,
)
from .compare import (
    METEOR_M_INERTIA,
    SlewComparisonRow,
    compare_slews,
    comparison_table,
    meteor_m_spacecraft,
    seed003_slew_spacecraft,
)
from .laws import EigenaxisSlew, eigenaxis_slew, quaternion_feedback_slew
from .models import (
    SpacecraftModel,
    check_inertia,
    dynamics_numpy,
    euler_krylov_model,
    rigid_spacecraft,
)
from .seed003 import (
    SEED003_INERTIA,
    Seed003Run,
    Seed003Spacecraft,
    seed003_run,
    seed003_spacecraft,
)
from .slews import (
    NLP_SOLVERS,
    TRANSCRIPTIONS,
    available_nlp_solvers,
    min_energy_slew,
    time_optimal_slew,
)
from .trajectory import SlewTrajectory

__all__: list[str] = [
    "EigenaxisSlew",
    "METEOR_M_INERTIA",
    "NLP_SOLVERS",
    "SlewTrajectory",
    "SEED003_INERTIA",
    "Seed003Run",
    "Seed003Spacecraft",
    "SlewComparisonRow",
    "SpacecraftModel",
    "TRANSCRIPTIONS",
    "available_nlp_solvers",
    "body_rates_from_angle_rates",
    "check_inertia",
    "compare_slews",
    "comparison_table",
    "dcm_body_from_ref_ek",
    "dynamics_numpy",
    "eigenaxis_slew",
    "ek_angle_rates",
    "ek_angle_rates_function",
    "ek_from_quat",
    "meteor_m_spacecraft",
    "min_energy_slew",
    "euler_krylov_model",
    "quat_conj",
    "quaternion_feedback_slew",
    "quat_error_angle",
    "quat_from_axis_angle",
    "quat_from_ek",
    "quat_mul",
    "quat_rate",
    "quat_to_dcm",
    "rigid_spacecraft",
    "rotation_between",
    "seed003_run",
    "seed003_slew_spacecraft",
    "seed003_spacecraft",
    "time_optimal_slew",
]
