"""What a QP backend returns: one vocabulary for every solver."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["QPSolution"]


@dataclass
class QPSolution:
    """The answer of one backend to one `QP`.

    Attributes
    ----------
    x : (n,) ndarray or None
        The point, None when the backend found none.
    success : bool
        The point is the QP's optimum: through `make_backend` every point
        is certified (`certificate.certify`) before it is called a
        success.
    status : {"solved", "infeasible", "failed", "inaccurate"}
        The verdict in the toolbox's words (``"inaccurate"``: a point
        that failed the optimality certificate); the backend's own text is
        ``extras["backend_status"]``, the certificate
        ``extras["certificate"]``.
    iterations : int
        Iterations reported (-1 if the backend does not say).
    solve_time : float
        Wall time of the backend call [s].
    extras : dict
        Anything else the backend reports.
    """

    x: np.ndarray | None
    success: bool
    status: str
    iterations: int = -1
    solve_time: float = 0.0
    extras: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def failed(cls, status: str = "failed", **extras: Any) -> "QPSolution":
        """Return a solution without a point (``status`` failed/infeasible)."""
        return cls(None, False, status, extras=extras)
