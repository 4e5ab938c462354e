"""The toolbox's error types (defined in `adcs_common`, shared by all)."""

from adcs_common.exceptions import (
    AdcsError,
    InfeasibleError,
    InvalidValueError,
    RankError,
    ShapeError,
    SolverError,
    SolverNotFound,
)

__all__ = [
    "AdcsError",
    "InfeasibleError",
    "InvalidValueError",
    "RankError",
    "ShapeError",
    "SolverError",
    "SolverNotFound",
]
