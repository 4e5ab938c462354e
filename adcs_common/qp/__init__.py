"""The QP layer both allocators share: one form, one answer, backends."""

from .backends import (
    FAMILIES,
    INSTALL_HINT,
    Backend,
    available_solvers,
    make_backend,
    resolve,
)
from .certificate import Certificate, certify
from .problem import QP, primal_residual
from .solution import QPSolution

__all__ = [
    "FAMILIES",
    "INSTALL_HINT",
    "QP",
    "Backend",
    "Certificate",
    "QPSolution",
    "available_solvers",
    "certify",
    "make_backend",
    "primal_residual",
    "resolve",
]
