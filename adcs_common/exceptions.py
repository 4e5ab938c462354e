"""Exception hierarchy of the toolbox.

``allocation`` and ``thrusters`` are leaves that must not import each
other, so the shared error types live here and both re-export them.
"""

from __future__ import annotations

from typing import Any


class AdcsError(Exception):
    """Base class of every error raised by the toolbox."""


class ShapeError(AdcsError, ValueError):
    """An argument has the wrong shape (message: expected vs got)."""


class InvalidValueError(AdcsError, ValueError):
    """An argument has a forbidden value (NaN, inf, negative weight...)."""


class UnknownArgumentError(InvalidValueError, TypeError):
    """A keyword argument the function does not take (message: which ones
    it takes). Also a `TypeError`, as Python's own unknown keyword is."""


class RankError(AdcsError, ValueError):
    """An actuator matrix cannot span the demanded space (rank too low).

    Attributes
    ----------
    rank : int
        Numerical rank found.
    required : int
        Rank needed.
    """

    def __init__(self, message: str, rank: int, required: int) -> None:
        super().__init__(message)
        self.rank = rank
        self.required = required


class InfeasibleError(AdcsError):
    """A demand or constraint set admits no solution.

    Attributes
    ----------
    problem : Any
        The problem (or its data) that could not be solved.
    result : Any
        The result object of the failed attempt, when there is one.
    """

    def __init__(self, message: str, problem: Any = None,
                 result: Any = None) -> None:
        super().__init__(message)
        self.problem = problem
        self.result = result


class SolverError(AdcsError):
    """A numerical solver failed or returned a point that fails checks.

    Attributes
    ----------
    solver : str
        Name of the solver.
    result : Any
        What the solver returned, when anything.
    """

    def __init__(self, message: str, solver: str = "",
                 result: Any = None) -> None:
        super().__init__(message)
        self.solver = solver
        self.result = result


class SolverNotFound(AdcsError, ValueError):
    """The solver name is unknown or its package is not installed.

    Attributes
    ----------
    name : str
        The name that was asked for.
    available : tuple of str
        The names that would work on this installation.
    """

    def __init__(self, name: str, available: tuple[str, ...],
                 hint: str = "") -> None:
        msg = (f"solver {name!r} is not available; installed: "
               f"{', '.join(available) or '(none)'}")
        if hint:
            msg += f". {hint}"
        super().__init__(msg)
        self.name = name
        self.available = tuple(available)


class ThreadOwnershipError(AdcsError, RuntimeError):
    """An object that follows one thread's sequence was used by another.

    Controllers carry state from one call to the next (an MPC's warm
    start): they refuse a second thread instead of mixing two sequences.
    """
