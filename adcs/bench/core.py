"""The bench's vocabulary: backends, rows, certificates, budgets."""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.interrupts import check as check_interrupt
from adcs_common.exceptions import (
    AdcsError,
    InvalidValueError,
    SolverNotFound,
)

#: Problem keys of `run_bench`.
PROBLEMS = ("wheels", "thrusters", "slew", "methods")
#: Problems `run_bench` and ``adcs bench`` run unless told (``methods``,
#: the literature's allocation methods, on request).
DEFAULT_PROBLEMS = ("wheels", "thrusters", "slew")
#: An answer whose KKT residual or error exceeds this is "wrong".
TOL = 1e-6
#: ``"<backend>@loose"``: OSQP at its own default tolerances, without
#: polishing: a fast solver whose loose answers the toolbox's optimality
#: certificate must polish to the optimum (or refuse).
LOOSE_OSQP = {"eps_abs": 1e-3, "eps_rel": 1e-3, "polishing": False}
#: Control rows added to the default QP backend lists.
CONTROLS = ("osqp@loose",)


def known_backends() -> tuple[str, ...]:
    """Every backend name some problem of the bench knows."""
    from allocation import available_solvers as wheel_solvers
    from ocp.mpc import available_mpc_solvers
    from thrusters import available_solvers as duty_solvers

    from .methods import METHOD_NAMES

    names = {*wheel_solvers(), *duty_solvers(), *available_mpc_solvers(),
             *CONTROLS, "sqpmethod-daqp", *METHOD_NAMES}
    return tuple(sorted(names))


def _check_backends(backends: Sequence[str] | None) -> None:
    if backends is None:
        return
    if isinstance(backends, str) or not all(isinstance(b, str)
                                            for b in backends):
        raise InvalidValueError(
            f"backends must be a list of names, got {backends!r}")
    known = known_backends()
    unknown = [b for b in backends if b not in known]
    if unknown:
        raise SolverNotFound(", ".join(unknown), known,
                             'pip install "adcs-toolbox[solvers]" adds '
                             "the optional QP backends")


def _split(name: str) -> tuple[str, dict]:
    """Backend name and solver options of ``"name"`` / ``"name@loose"``."""
    base, _, variant = name.partition("@")
    if variant == "loose" and base == "osqp":
        return base, dict(LOOSE_OSQP)
    if variant:
        raise InvalidValueError(
            f"backend {name!r}: the only variant is 'osqp@loose'")
    return base, {}


@dataclass(frozen=True)
class BenchRow:
    """Timing and correctness of one backend on one problem.

    Attributes
    ----------
    problem : str
        ``"wheels"``, ``"thrusters"`` or ``"slew"``.
    backend : str
        Backend name as the user passes it.
    n : int
        Solves attempted.
    median_s, p99_s : float
        Median and 99th percentile wall time per solve [s] (NaN if none
        succeeded).
    max_error : float
        Largest error against the reference (∞-norm of the point, in the
        problem's units: N·m, duty fraction, or relative cost for the
        slew).
    max_kkt : float
        Largest KKT residual (QPs; NaN for the NLP).
    failures : int
        Solves that raised or reported no solution.
    wrong : int
        Solves that returned an answer failing the checks (> `TOL`).
    requested : int
        Solves asked for; ``n < requested`` when the backend ran out of
        its time budget ("too slow").
    note : str
        What a failed, wrong or too-slow row means (empty when ok).
    """

    problem: str
    backend: str
    n: int
    median_s: float
    p99_s: float
    max_error: float
    max_kkt: float
    failures: int
    wrong: int
    requested: int = 0
    note: str = ""

    @property
    def ok(self) -> bool:
        """No failure and no wrong answer."""
        return self.failures == 0 and self.wrong == 0

    @property
    def too_slow(self) -> bool:
        """The time budget ran out before the requested solves."""
        return 0 < self.n < self.requested


def kkt_residual(P: ArrayLike, q: ArrayLike, C: ArrayLike, cl: ArrayLike,
                 cu: ArrayLike, x: ArrayLike,
                 active_tol: float = 1e-7) -> float:
    """KKT residual of ``x`` for ``min ½xᵀPx + qᵀx, cl <= C x <= cu``.

    The largest of the primal violation and the stationarity residual
    :math:`\\|Px + q + C^T y\\|_\\infty` minimised over multipliers with
    the right signs (``y <= 0`` on active lower bounds, ``>= 0`` on active
    upper bounds, free on equalities, zero on inactive rows), found by
    bounded least squares and scaled by ``1 + ||Px + q||``. Zero means
    optimal (convex QP).

    Parameters
    ----------
    P : array_like (n, n)
    q : array_like (n,)
    C : array_like (m, n)
        Constraint rows (include an identity block for variable bounds).
    cl, cu : array_like (m,)
        Bounds (±inf allowed).
    x : array_like (n,)
        The point to certify.
    active_tol : float
        Distance to a bound under which the row counts as active.
    """
    from scipy.optimize import lsq_linear

    P, q, C = (np.asarray(a, dtype=float) for a in (P, q, C))
    cl, cu = np.asarray(cl, dtype=float), np.asarray(cu, dtype=float)
    x = np.asarray(x, dtype=float)
    Cx = C @ x
    scale_c = 1.0 + np.abs(Cx)
    primal = float(np.max(np.r_[(cl - Cx) / scale_c, (Cx - cu) / scale_c,
                                0.0]))
    grad = P @ x + q
    eq = np.isclose(cl, cu)
    lo = ~eq & (Cx - cl <= active_tol * scale_c)
    up = ~eq & (cu - Cx <= active_tol * scale_c)
    rows = np.flatnonzero(eq | lo | up)
    if rows.size == 0:
        stat = float(np.max(np.abs(grad)))
    else:
        # grad + Cᵀy = 0: y <= 0 on an active lower bound, >= 0 on upper
        lb = np.where(up[rows] & ~lo[rows], 0.0, -np.inf)
        ub = np.where(lo[rows] & ~up[rows], 0.0, np.inf)
        with warnings.catch_warnings():   # scipy's trf on far-off points
            warnings.simplefilter("ignore", RuntimeWarning)
            sol = lsq_linear(C[rows].T, -grad, bounds=(lb, ub), tol=1e-14)
        stat = float(np.max(np.abs(C[rows].T @ sol.x + grad)))
    return max(primal, stat / (1.0 + float(np.linalg.norm(grad))))


def _stats(times: list[float]) -> tuple[float, float]:
    if not times:
        return float("nan"), float("nan")
    t = np.asarray(times)
    return float(np.median(t)), float(np.percentile(t, 99))


def _progress_fn(enabled: bool) -> Callable[[str], None]:
    def show(msg: str) -> None:
        if enabled:
            print(msg, file=sys.stderr, flush=True)
    return show


class Progress:
    """One progress bar with ETA over every solve of the bench (tqdm).

    ``add(n)`` announces solves, ``step(label)`` counts one, ``skip(n)``
    withdraws solves a backend will not make (budget spent, not
    available), ``say(msg)`` prints a line above the bar.
    """

    def __init__(self, enabled: bool) -> None:
        from tqdm.auto import tqdm

        self.bar = tqdm(total=0, unit="solve", file=sys.stderr,
                        disable=not enabled, dynamic_ncols=True,
                        bar_format="{l_bar}{bar}| {n}/{total} "
                        "[{elapsed}<{remaining}]")
        self.enabled = enabled

    def add(self, n: int) -> None:
        """Announce ``n`` more solves."""
        self.bar.total += n
        self.bar.refresh()

    def skip(self, n: int) -> None:
        """Withdraw ``n`` announced solves."""
        self.bar.total -= n
        self.bar.refresh()

    def step(self, label: str) -> None:
        """Count one solve of ``label``."""
        self.bar.set_description(label, refresh=False)
        self.bar.update(1)

    def say(self, msg: str) -> None:
        """Print ``msg`` above the bar (nothing when disabled)."""
        if self.enabled:
            self.bar.write(msg, file=sys.stderr)

    def close(self) -> None:
        """Close the bar."""
        self.bar.close()


def quiet() -> Progress:
    """Return a disabled `Progress` (the default of the bench functions)."""
    return Progress(False)


class Corrections:
    """What the QP layer's certificate did to a backend's answers.

    Call it on each result (a result with ``extras``, as the allocators
    return): it counts the answers whose point the certificate moved by
    more than `TOL` (polished on their active set) and those it refused
    (``extras["fallback"]``: the exact backend answered instead).
    """

    def __init__(self) -> None:
        self.seen = 0
        self.moved = 0
        self.refused = 0
        self.largest = 0.0

    def __call__(self, result: Any) -> Any:
        """Count ``result``; return it unchanged."""
        extras = getattr(result, "extras", None) or {}
        self.seen += 1
        if extras.get("fallback"):
            self.refused += 1
            return result
        moved = float(extras.get("certificate", {}).get("moved", 0.0))
        self.largest = max(self.largest, moved)
        self.moved += int(moved > TOL)
        return result

    def text(self) -> str:
        """One clause: the counts measured, e.g. ``moved 0 of 200``."""
        return (f"the certificate corrected {self.moved} of {self.seen} "
                f"of its points by more than {TOL:g} (largest move "
                f"{self.largest:.1e}) and refused {self.refused}")


def explain(row: BenchRow, budget: float,
            corrections: Corrections | None = None) -> str:
    """Say what a failed, wrong, too-slow or control row means.

    ``corrections``: what the certificate did to this row's answers,
    stated for the control rows (``@loose``) as measured.
    """
    parts = []
    if row.backend.endswith("@loose"):
        parts.append("control row: OSQP at eps 1e-3 without polishing"
                     + (f"; {corrections.text()}; after it the bench's "
                        f"check found {row.wrong} of {row.n} wrong"
                        if corrections is not None else ""))
    if row.wrong:
        parts.append(f"{row.wrong} answers beyond the {TOL:g} check (max "
                     f"error {row.max_error:.1e}, max KKT "
                     f"{row.max_kkt:.1e})")
    if row.failures:
        parts.append(f"{row.failures} solves raised or returned no point")
    if row.too_slow:
        parts.append(f"too slow: {row.n} of {row.requested} solves in the "
                     f"{budget:g} s budget")
    return "; ".join(parts)


def timed_row(problem: str, name: str, cases: list, refs: list,
              solve: Callable, certify: Callable, progress: Progress,
              budget: float) -> BenchRow:
    """Time ``solve`` on the cases until done or ``budget`` [s] is spent.

    ``solve(case)`` returns the point (None or a toolbox error: a
    failure); ``certify(case, point)`` its KKT residual. Compared with
    ``refs``.
    """
    reps = len(cases)
    times, err, kkt, fails, wrong, done = [], 0.0, 0.0, 0, 0, 0
    start = time.perf_counter()
    for case, ref in zip(cases, refs):
        check_interrupt()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            try:
                x = solve(case)
            except AdcsError:
                check_interrupt()       # a failure Ctrl-C caused
                x = None
            dt = time.perf_counter() - t0
        done += 1
        progress.step(f"{problem} {name}")
        if x is None:
            fails += 1
        else:
            e = float(np.max(np.abs(x - ref)))
            c = certify(case, x)
            err, kkt = max(err, e), max(kkt, c)
            wrong += int((e > TOL) or (c > TOL))
            times.append(dt)
        if time.perf_counter() - start > budget and done < reps:
            progress.skip(reps - done)
            break
    med, p99 = _stats(times)
    row = BenchRow(problem, name, done, med, p99, err, kkt, fails, wrong,
                   reps)
    return BenchRow(**{**row.__dict__, "note": explain(row, budget)})
