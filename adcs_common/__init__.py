"""Error types and input checks shared by every package of the toolbox."""

from .exceptions import (
    AdcsError,
    InfeasibleError,
    RankError,
    ShapeError,
    SolverError,
    SolverNotFound,
    InvalidValueError,
    ThreadOwnershipError,
)
from .validation import (
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_nonnegative,
    check_positive,
)

__all__ = [
    "AdcsError",
    "InfeasibleError",
    "InvalidValueError",
    "RankError",
    "ShapeError",
    "SolverError",
    "SolverNotFound",
    "ThreadOwnershipError",
    "as_finite_array",
    "as_finite_scalar",
    "as_vector",
    "check_nonnegative",
    "check_positive",
]
