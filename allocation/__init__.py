"""Reaction-wheel arrays and torque allocation ([1], theory §1).

Citations: [1]–[4] are the source papers and "theory §N" the sections of
the project's docs (docs/references.md and docs/theory.md in the
repository; the misprints the code corrects are in docs/errata.md).
"""

from adcs_common.version import version as _version
from .accuracy import (
    AccuracyResult,
    ErrorSummary,
    TorqueError,
    actual_axes,
    compare_law_axes,
    gain_error_uniform,
    gain_error_uniform_as_printed,
    monte_carlo_accuracy,
    monte_carlo_accuracy_array,
    paper_actual_axes_as_printed,
    tilted_axes,
    torque_error,
)
from .arrays import WheelArray, pyramid_axes
from .design import FAMILIES, ArrayDesign, certify_layout, design_array
from .design_trade import TradeCurve, reference_layouts, trade_curve
from .electrical import WheelMotor
from .envelope import Envelope, Facets, envelope, envelope_frame
from .exceptions import (
    AdcsError,
    InfeasibleError,
    InvalidValueError,
    RankError,
    ShapeError,
    SolverError,
    SolverNotFound,
)
from . import methods
from .method_comparison import (
    MethodComparison,
    compare_methods,
    comparison_arrays,
    format_comparison,
)
from .method_momentum import (
    MomentumHandling,
    format_momentum,
    momentum_cases,
    momentum_handling,
)
from .laws import (
    EQ9_GAINS,
    PAPER_EQ9_GAINS_PRINTED,
    LinearLaw,
    allocate_min_norm,
    min_norm_gains,
    min_norm_law,
    pyramid_failure_gains,
    sign_matrix_gains,
    weighted_gains,
    weighted_law,
)
from .plots import (
    plot_accuracy_histogram,
    plot_envelope,
    plot_error_histogram,
)
from .qp import (
    BatchAllocation,
    WheelAllocation,
    QPAllocator,
    available_solvers,
    conic_allocator_function,
)
from .reach import (
    ReachResult,
    fibonacci_directions,
    format_reach_table,
    reach_frame,
    law_extent,
    reach_table,
    torque_reach,
)
from .symbolic import (
    min_norm_function,
    pyramid_axes_function,
    pyramid_min_norm_function,
    sign_matrix_function,
    weighted_function,
)

#: The toolbox's version (one source: `adcs_common.version`).
__version__ = _version()

__all__ = [
    "AccuracyResult",
    "AdcsError",
    "ArrayDesign",
    "BatchAllocation",
    "EQ9_GAINS",
    "Envelope",
    "ErrorSummary",
    "FAMILIES",
    "Facets",
    "InfeasibleError",
    "InvalidValueError",
    "LinearLaw",
    "MethodComparison",
    "MomentumHandling",
    "PAPER_EQ9_GAINS_PRINTED",
    "QPAllocator",
    "RankError",
    "ReachResult",
    "ShapeError",
    "SolverError",
    "SolverNotFound",
    "TorqueError",
    "TradeCurve",
    "WheelAllocation",
    "WheelArray",
    "WheelMotor",
    "actual_axes",
    "allocate_min_norm",
    "available_solvers",
    "certify_layout",
    "compare_law_axes",
    "compare_methods",
    "comparison_arrays",
    "conic_allocator_function",
    "design_array",
    "envelope",
    "envelope_frame",
    "fibonacci_directions",
    "format_comparison",
    "format_momentum",
    "format_reach_table",
    "gain_error_uniform",
    "gain_error_uniform_as_printed",
    "law_extent",
    "methods",
    "min_norm_function",
    "min_norm_gains",
    "min_norm_law",
    "momentum_cases",
    "momentum_handling",
    "monte_carlo_accuracy",
    "monte_carlo_accuracy_array",
    "paper_actual_axes_as_printed",
    "plot_accuracy_histogram",
    "plot_envelope",
    "plot_error_histogram",
    "pyramid_axes",
    "pyramid_axes_function",
    "pyramid_failure_gains",
    "pyramid_min_norm_function",
    "reach_frame",
    "reach_table",
    "reference_layouts",
    "sign_matrix_function",
    "sign_matrix_gains",
    "tilted_axes",
    "torque_error",
    "torque_reach",
    "trade_curve",
    "weighted_function",
    "weighted_gains",
    "weighted_law",
]
