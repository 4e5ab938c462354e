"""Rest-to-rest slews as NLPs and their comparison with closed forms."""

from .compare import (
    METEOR_M_INERTIA,
    SlewComparisonRow,
    compare_slews,
    comparison_table,
    comparison_frame,
    four_wheel_slew_spacecraft,
    meteor_m_spacecraft,
)
from .nlp import (
    KeepOut,
    NLP_SOLVERS,
    TRANSCRIPTIONS,
    available_nlp_solvers,
    clear_solver_cache,
    min_energy_slew,
    time_optimal_slew,
)

__all__ = [
    "KeepOut",
    "METEOR_M_INERTIA",
    "NLP_SOLVERS",
    "SlewComparisonRow",
    "TRANSCRIPTIONS",
    "available_nlp_solvers",
    "clear_solver_cache",
    "compare_slews",
    "comparison_table",
    "comparison_frame",
    "four_wheel_slew_spacecraft",
    "meteor_m_spacecraft",
    "min_energy_slew",
    "time_optimal_slew",
]
