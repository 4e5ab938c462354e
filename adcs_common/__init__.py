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
from .version import version as _version
from .validation import (
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_nonnegative,
    check_positive,
)

#: The toolbox's version (`adcs_common.version.version`), shared by
#: every package.
__version__ = _version()

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
