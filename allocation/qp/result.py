"""What a wheel allocation returns: one demand, or a batch of them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from adcs_common.results import ResultMixin


@dataclass(frozen=True, eq=False, repr=False)
class WheelAllocation(ResultMixin):
    """Outcome of one wheel allocation (`QPAllocator.allocate`).

    Every answer is checked (bounds, A m = target) before it is returned;
    a backend failure raises `SolverError`, so ``success`` is always True
    on a result you hold: ``status`` says which answer it is.

    Attributes
    ----------
    torques : (N,) ndarray
        Motor torques m [N·m] (failed wheels exactly 0, bounds kept).
    achieved : (3,) ndarray
        Array torque A m they produce [N·m].
    status : str
        ``"optimal"``: A m = M within tolerance; ``"saturated"``: M is not
        attainable and ``achieved`` is the documented substitute (see
        ``mode``).
    shortfall : (3,) ndarray
        ``M - achieved`` [N·m] (zero when optimal).
    alpha : float
        ``achieved·M / |M|²``: 1 when optimal, the scale reached in mode
        ``"scale"`` (within 1e-9 of the largest attainable), the component
        along M (clipped at 0) in mode ``"least_squares"``.
    mode : str
        ``"exact"``, ``"scale"`` (largest α <= 1 with A m = α M) or
        ``"least_squares"`` (attainable torque closest to M).
    solve_time : float
        Wall time of the whole allocation [s].
    solver : str
        Backend name (``"closed form"`` where the exact closed form of the
        default answered).
    iterations : int
        Iterations of the last QP (-1 if the backend does not say).
    momentum_after : (N,) ndarray or None
        ``h + m dt`` when momentum and dt were given [N·m·s].
    residual : float
        Largest constraint violation of the returned torques (bounds and
        ``A m = target``) [N·m], the quantity the check bounds.
    extras : dict
        The backend's own status text and anything else it reports.
    """

    torques: np.ndarray
    achieved: np.ndarray
    status: str
    shortfall: np.ndarray
    alpha: float
    mode: str
    solve_time: float
    solver: str
    iterations: int = -1
    momentum_after: np.ndarray | None = None
    residual: float = 0.0
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """The answer passed its checks (always, else SolverError)."""
        return self.status in ("optimal", "saturated")


@dataclass(frozen=True, eq=False, repr=False)
class BatchAllocation:
    """Outcome of `QPAllocator.allocate_batch`: K demands at once.

    Row k is what ``allocate(torques[k], ...)`` returns, checked the same
    way (bounds and ``A m = α M`` within the allocator's ``check_tol``);
    a row no vectorised exact form covers was answered by `allocate`
    itself, so a failure raises `SolverError` and ``success`` is always
    True on a result you hold.

    Attributes
    ----------
    torques : (K, N) ndarray
        Motor torques [N·m] (failed wheels exactly 0, bounds kept).
    achieved : (K, 3) ndarray
        Array torques ``A m`` they produce [N·m].
    alpha : (K,) ndarray
        Scale reached: 1 where the demand is attainable, else the largest
        ``α < 1`` with ``α M`` attainable.
    status : (K,) ndarray of str
        ``"optimal"`` or ``"saturated"`` per row.
    residual : (K,) ndarray
        Largest constraint violation of each row [N·m].
    solve_time : float
        Wall time of the whole batch [s].
    extras : dict
        ``"vectorised"``: rows answered by the exact numpy form;
        ``"one_at_a_time"``: rows handed to `allocate` (more than four
        working wheels, a wheel past its momentum bound, a cost the
        closed form does not cover).
    """

    torques: np.ndarray
    achieved: np.ndarray
    alpha: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    solve_time: float
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Every row passed its checks (always, else SolverError)."""
        return True

    @property
    def saturated(self) -> np.ndarray:
        """Rows whose demand was scaled down, (K,) bool."""
        return self.alpha < 1.0

    def __len__(self) -> int:
        """Return the number of demands K."""
        return int(self.torques.shape[0])

    def __repr__(self) -> str:
        """Summarise the batch (no arrays)."""
        k, n = self.torques.shape
        return (f"BatchAllocation({k} demands × {n} wheels, "
                f"{int(self.saturated.sum())} saturated, "
                f"max residual {float(self.residual.max(initial=0.0)):.2g} "
                f"N·m, {self.solve_time * 1e3:.3g} ms)")
