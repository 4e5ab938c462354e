r"""How the allocation methods handle the wheel momentum bound.

The exact QP (`QPAllocator.allocate(M, h, dt)`) keeps every wheel's
momentum after the step within its bound, :math:`|h_i + m_i\,dt| \le
h_{max,i}`, as a constraint. The literature's methods know box bounds
only. They can be run two ways:

* **torque limits only** (their usual setting): they ignore the momentum
  and may drive a wheel past ``h_max``;
* **momentum folded into the box**: ``lo``/``hi`` from `torque_bounds`
  (the QP's own box): they stay within the bound, but the attainable set
  shrinks near a saturated wheel, and each method reaches only its own
  share of it.

`momentum_handling` measures both on momentum states with wheels near
their bound and demands uniform in the nominal attainable set.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import check_instance

from .arrays import WheelArray
from .method_comparison import sample_attainable
from .methods import METHODS
from .qp import QPAllocator
from .qp.problem import torque_bounds

__all__ = ["MomentumHandling", "format_momentum", "momentum_cases",
           "momentum_handling"]

#: Name of the exact QP's row.
QP_NAME = "exact QP (scale)"


@dataclass(frozen=True)
class MomentumHandling:
    """One method's handling of the momentum bound on one array.

    Attributes
    ----------
    method : str
    failed : tuple of int
        0-based failed wheels.
    violation_share : float
        Torque limits only: share of the cases after which some wheel's
        momentum exceeds ``h_max (1 + 1e-9)`` [1] (the QP: with its
        momentum bound).
    worst_excess : float
        Torque limits only: the largest ``(|h_i + m_i dt| - h_max,i) /
        h_max,i`` over the cases [1] (≤ 0: none exceeded).
    bounded_violation_share : float
        Momentum folded into ``lo``/``hi``: the same share [1].
    reach_share : float
        Momentum folded in: share of the cases the exact QP meets exactly
        (``A m = M`` within the momentum-limited set) that the method
        meets too, ``|A m - M| <= tol |M|`` [1].
    miss_error_p95 : float
        95th percentile of ``|A m - M| / |M|`` on those it missed [1]
        (NaN: none missed).
    n_cases : int
        Momentum states × demands evaluated.
    n_exact : int
        Cases the exact QP meets exactly.
    """

    method: str
    failed: tuple[int, ...]
    violation_share: float
    worst_excess: float
    bounded_violation_share: float
    reach_share: float
    miss_error_p95: float
    n_cases: int
    n_exact: int


def momentum_cases(array: WheelArray, n: int, dt: float, seed: int = 0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Wheel momenta (n, N) [N·m·s] and demands (n, 3) [N·m].

    Each working wheel is, with probability 1/2, within 1.5 steps of full
    torque of its bound (``h_max - u·1.5·m_max·dt``, u uniform in [0, 1],
    random sign), else uniform in ``±h_max``; failed wheels hold 0. The
    demands are uniform in the nominal attainable torque set
    (`sample_attainable`, seed ``seed``).
    """
    check_instance(array, WheelArray, "array")
    if not (np.isfinite(dt) and dt > 0):
        raise InvalidValueError(f"dt must be positive, got {dt!r}")
    rng = np.random.default_rng(seed + 1)
    k = array.n_wheels
    h_max = np.asarray(array.h_max, dtype=float)
    m_max = np.asarray(array.m_max, dtype=float)
    near = h_max - rng.uniform(0, 1, (n, k)) * np.minimum(
        1.5 * m_max * dt, h_max)
    near *= rng.choice([-1.0, 1.0], (n, k))
    anywhere = h_max * rng.uniform(-1, 1, (n, k))
    h = np.where(rng.random((n, k)) < 0.5, near, anywhere) * array.active
    return h, sample_attainable(array, n, seed)


def _evaluate(array, f, h, D, dt) -> tuple[np.ndarray, np.ndarray]:
    """Torques (n, N) of ``f`` with the torque limits only, and boxed."""
    free, boxed = [], []
    for hk, M in zip(h, D):
        lo, hi, _ = torque_bounds(array, hk, dt)
        free.append(f(array, M))
        boxed.append(f(array, M, lo, hi))
    return np.array(free), np.array(boxed)


def _row(array, name, free, boxed, h, D, dt, exact, tol
         ) -> MomentumHandling:
    """One row from the torques ``free`` and ``boxed`` (n, N) [N·m]."""
    A = array.working_axes
    h_max = np.asarray(array.h_max, dtype=float)

    def excess(m):
        return np.max((np.abs(h + m * dt) - h_max) / h_max, axis=1)
    nM = np.maximum(np.linalg.norm(D, axis=1), 1e-300)
    err = np.linalg.norm(boxed @ A.T - D, axis=1) / nM
    met = err[exact] <= tol
    miss = err[exact][~met]
    e_free = excess(free)
    return MomentumHandling(
        method=name, failed=tuple(array.failed),
        violation_share=float(np.mean(e_free > 1e-9)),
        worst_excess=float(np.max(e_free)),
        bounded_violation_share=float(np.mean(excess(boxed) > 1e-9)),
        reach_share=float(np.mean(met)) if met.size else float("nan"),
        miss_error_p95=float(np.percentile(miss, 95)) if miss.size
        else float("nan"),
        n_cases=len(D), n_exact=int(exact.sum()))


def momentum_handling(array: WheelArray,
                      methods: Mapping[str, Callable] | None = None, *,
                      dt: float = 0.5, n_cases: int = 400, seed: int = 0,
                      tol: float = 1e-3, include_qp: bool = True
                      ) -> list[MomentumHandling]:
    """Each method's momentum-bound handling against the exact QP.

    On `momentum_cases` (wheels near their bound, demands uniform in the
    nominal attainable set): each method with the torque limits only
    (``f(array, M)``), then with the momentum folded into its box
    (``f(array, M, lo, hi)``, `torque_bounds`). The exact QP's row is
    ``allocate(M, h, dt)`` in both columns. A case is "exact" when the QP
    meets M exactly (status ``"optimal"``).

    Parameters
    ----------
    array : WheelArray
    methods : mapping name -> f(array, M, lo=None, hi=None) -> m, optional
        Default `allocation.methods.METHODS`.
    dt : float
        Step [s] of the momentum bound.
    n_cases : int
        Momentum states, one demand each.
    seed : int
    tol : float
        Relative torque error of a met demand [1].
    include_qp : bool
        Add the exact QP's row (first).

    Returns
    -------
    list of MomentumHandling
    """
    h, D = momentum_cases(array, int(n_cases), dt, seed)
    if not 0.0 < tol < 1.0:
        raise InvalidValueError(f"tol must lie in (0, 1), got {tol!r}")
    qp = QPAllocator(array, saturation="scale")
    res = [qp.allocate(M, hk, dt) for hk, M in zip(h, D)]
    exact = np.array([r.status == "optimal" for r in res])
    rows = []
    if include_qp:
        m = np.array([r.torques for r in res])
        rows.append(_row(array, QP_NAME, m, m, h, D, dt, exact, tol))
    methods = dict(METHODS if methods is None else methods)
    for k, f in methods.items():
        free, boxed = _evaluate(array, f, h, D, dt)
        rows.append(_row(array, k, free, boxed, h, D, dt, exact, tol))
    return rows


def format_momentum(rows: Sequence[MomentumHandling]) -> str:
    """Plain-text table of `momentum_handling` rows (percent)."""
    head = (f"{'method':<30}{'limits only: over h_max %':>27}"
            f"{'worst excess %':>16}{'boxed: over %':>15}"
            f"{'boxed: reach %':>16}{'miss p95':>10}")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r.method:<30}{100 * r.violation_share:>27.1f}"
            f"{100 * max(r.worst_excess, 0.0):>16.2f}"
            f"{100 * r.bounded_violation_share:>15.1f}"
            f"{100 * r.reach_share:>16.1f}{r.miss_error_p95:>10.3g}")
    return "\n".join(lines)
