"""Optimizer comparison: every installed backend, each answer certified.

Three problems, each solved by every backend installed here and checked
against an exact reference, so that a fast wrong answer shows as wrong:

* ``wheels``: the bounded 4-wheel allocation QP (`allocation.QPAllocator`,
  every name of `allocation.available_solvers`) on attainable demands
  ``M = A m`` with ``m`` near the torque box corners (bounds active);
* ``thrusters``: the duty-cycle QP (`thrusters.DutyCycleAllocator`,
  weighted tracking, momentum box) on random cycles;
* control row ``osqp@loose`` (OSQP at eps 1e-3, no polishing) in both
  QPs: fast, and its wrong answers must show in the ``wrong`` column;
* ``slew``: the MPC slew NLP (`ocp.mpc.AttitudeMPC`, horizon 20) from rest,
  cold-started, by every NLP solver name.

QP answers are certified by their KKT residuals (primal feasibility, and
stationarity with sign-correct multipliers found by bounded least
squares) and compared with a reference backend's point; NLP answers are
compared with IPOPT at ``tol = 1e-12``.
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from adcs_common.exceptions import (
    AdcsError,
    InvalidValueError,
    SolverNotFound,
)
from adcs_common.paths import output_folder
from ocp.spacecraft import load_spacecraft
from adcs.provenance import provenance

__all__ = [
    "BenchRow",
    "PROBLEMS",
    "bench_slew",
    "bench_thrusters",
    "bench_wheels",
    "format_table",
    "kkt_residual",
    "run_bench",
]

#: Problem keys of `run_bench`.
PROBLEMS = ("wheels", "thrusters", "slew")
#: An answer whose KKT residual or error exceeds this is "wrong".
TOL = 1e-6
#: ``"<backend>@loose"``: OSQP at its own default tolerances, without
#: polishing: a fast solver whose answers the certificate must catch.
LOOSE_OSQP = {"eps_abs": 1e-3, "eps_rel": 1e-3, "polishing": False}
#: Control rows added to the default QP backend lists.
CONTROLS = ("osqp@loose",)


def known_backends() -> tuple[str, ...]:
    """Every backend name some problem of the bench knows."""
    from allocation import available_solvers as wheel_solvers
    from ocp.mpc import available_mpc_solvers
    from thrusters import available_solvers as duty_solvers

    names = {*wheel_solvers(), *duty_solvers(), *available_mpc_solvers(),
             *CONTROLS, "sqpmethod-daqp"}
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

    @property
    def ok(self) -> bool:
        """No failure and no wrong answer."""
        return self.failures == 0 and self.wrong == 0


def kkt_residual(P, q, C, cl, cu, x, active_tol: float = 1e-7) -> float:
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
    return max(primal, stat / (1.0 + np.linalg.norm(grad)))


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


# -------------------------------------------------------------------- wheels
def bench_wheels(backends: Sequence[str] | None = None, reps: int = 200,
                 seed: int = 0, progress: Callable[[str], None] | None = None,
                 spacecraft=None) -> list[BenchRow]:
    """Time the bounded wheel-allocation QP across backends.

    The spacecraft's wheel array (default: the pyramid δ = 55°, γ = 45°,
    ``m_max = 0.2`` N·m); ``reps`` attainable demands ``M = A m`` with
    ``m`` uniform in ``0.97 · [-m_max, m_max]`` (0 for a failed wheel;
    most leave the minimum-norm law's reach, so bounds are active).
    Reference: the first certified backend among quadprog, daqp, clarabel.
    """
    from allocation import QPAllocator, WheelArray, available_solvers

    show = progress or _progress_fn(False)
    arr = (WheelArray.pyramid(h_max=4.0, m_max=0.2) if spacecraft is None
           else load_spacecraft(spacecraft).wheels)
    A = np.asarray(arr.axes)
    n = arr.n_wheels
    m_cap = arr.m_max * arr.active
    rng = np.random.default_rng(seed)
    demands = [A @ (0.97 * m_cap * rng.uniform(-1, 1, n))
               for _ in range(reps)]
    names = (list(backends) if backends
             else list(available_solvers()) + list(CONTROLS))
    P = 2.0 * np.eye(n)
    C = np.vstack([A, np.eye(n)])

    def cert(M, m):
        cl = np.r_[M, -m_cap]
        cu = np.r_[M, m_cap]
        return kkt_residual(P, np.zeros(n), C, cl, cu, m)

    ref_name = next((s for s in ("quadprog", "daqp", "clarabel")
                     if s in available_solvers()), names[0])
    ref_alloc = QPAllocator(arr, solver=ref_name)
    refs = []
    for M in demands:
        m = ref_alloc.allocate(M).torques
        if cert(M, m) > TOL:
            raise AdcsError(f"wheels: reference {ref_name} failed its KKT "
                            "check")
        refs.append(m)
    rows = []
    for name in names:
        base, opts = _split(name)
        try:
            alloc = QPAllocator(arr, solver=base, solver_options=opts)
        except (AdcsError, TypeError, ValueError) as exc:
            show(f"[wheels] {name}: not available ({exc})")
            continue
        rows.append(_timed_row(
            "wheels", name, demands, refs,
            lambda M: alloc.allocate(M).torques, cert, show, progress))
    return rows


def _timed_row(problem: str, name: str, cases: list, refs: list,
               solve: Callable, certify: Callable, show: Callable,
               progress: bool) -> BenchRow:
    """Time ``solve`` on every case; compare with ``refs``, certify.

    ``solve(case)`` returns the point (None or a toolbox error: a
    failure); ``certify(case, point)`` its KKT residual.
    """
    reps = len(cases)
    times, err, kkt, fails, wrong = [], 0.0, 0.0, 0, 0
    for k, (case, ref) in enumerate(zip(cases, refs)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            try:
                x = solve(case)
            except AdcsError:
                x = None
            dt = time.perf_counter() - t0
        if x is None:
            fails += 1
            continue
        e = float(np.max(np.abs(x - ref)))
        c = certify(case, x)
        err, kkt = max(err, e), max(kkt, c)
        wrong += int((e > TOL) or (c > TOL))
        times.append(dt)
        if progress and (k + 1) % max(reps // 4, 1) == 0:
            show(f"[{problem}] {name} {k + 1}/{reps}")
    med, p99 = _stats(times)
    return BenchRow(problem, name, reps, med, p99, err, kkt, fails, wrong)


# ----------------------------------------------------------------- thrusters
def bench_thrusters(backends: Sequence[str] | None = None, reps: int = 200,
                    seed: int = 0,
                    progress: Callable[[str], None] | None = None,
                    spacecraft=None) -> list[BenchRow]:
    """Time the thruster duty-cycle QP across backends.

    The spacecraft's thruster set (none: no rows), by default the
    six-thruster unit of [4], T_T = 2 s, ``h_max = 0.012`` N·m·s,
    weighted torque tracking, momentum box; random cycles with P_T in
    [0, 0.739] N, torques up to 0.05 N·m, momenta inside the bound.
    Each answer (duties and slack) is KKT-certified on the canonical QP
    and compared with the reference backend (quadprog, else clarabel).
    """
    from thrusters import (DutyCycleAllocator, available_solvers,
                           six_thruster_unit)
    from thrusters.qp.problem import INF

    show = progress or _progress_fn(False)
    unit = (six_thruster_unit() if spacecraft is None
            else load_spacecraft(spacecraft).thrusters)
    if unit is None:
        show("[thrusters] skipped: the spacecraft has no thrusters")
        return []
    h_max = 0.012
    rng = np.random.default_rng(seed)
    cases = [(rng.choice([0.0, rng.uniform(0.0, 0.739)]),
              rng.uniform(-0.05, 0.05, 2),
              np.r_[rng.uniform(-1, 1) * h_max, 0.0,
                    rng.uniform(-1, 1) * h_max],
              np.r_[rng.normal(scale=5e-4), 0.0, rng.normal(scale=5e-4)])
             for _ in range(reps)]
    names = (list(backends) if backends
             else list(available_solvers()) + list(CONTROLS))
    kw = dict(tracking="weighted", bound="box")
    ref_name = next((s for s in ("quadprog", "clarabel", "daqp")
                     if s in available_solvers()), names[0])
    ref_alloc = DutyCycleAllocator(unit, 2.0, h_max, solver=ref_name, **kw)
    qp = ref_alloc.qp
    nx = qp.nx
    C = np.vstack([qp.A, np.eye(nx)])

    def data(th):
        q, l, u = qp.vectors(th)
        l = np.where(l <= -INF / 2, -np.inf, l)
        u = np.where(u >= INF / 2, np.inf, u)
        return q, np.r_[l, qp.lb], np.r_[u, qp.ub]

    def point(r):
        return np.r_[r.duty, r.momentum_excess / h_max]

    def duty_point(r):
        return point(r) if r.success else None

    thetas, refs = [], []
    for P_T, M, H, tau in cases:
        th = ref_alloc.theta(P_T, M, H, tau)
        r = ref_alloc.solve_theta(th)
        q, cl, cu = data(th)
        if not r.success or kkt_residual(qp.P, q, C, cl, cu,
                                       point(r)) > TOL:
            raise AdcsError(f"thrusters: reference {ref_name} failed its "
                            "KKT check")
        thetas.append(th)
        refs.append(point(r))
    rows = []
    for name in names:
        base, opts = _split(name)
        try:
            alloc = DutyCycleAllocator(unit, 2.0, h_max, solver=base,
                                       solver_options=opts, **kw)
        except (AdcsError, TypeError, ValueError) as exc:
            show(f"[thrusters] {name}: not available ({exc})")
            continue
        rows.append(_timed_row(
            "thrusters", name, thetas, refs,
            lambda th: duty_point(alloc.solve_theta(th)),
            lambda th, x: kkt_residual(qp.P, data(th)[0], C, data(th)[1],
                                       data(th)[2], x), show, progress))
    return rows


# ---------------------------------------------------------------------- slew
def bench_slew(backends: Sequence[str] | None = None, reps: int = 5,
               progress: Callable[[str], None] | None = None,
               quick: bool = False, spacecraft=None) -> list[BenchRow]:
    """Time the MPC slew NLP (horizon 20, 90° from rest), cold-started.

    On the spacecraft's inertia and wheels (default: the ``demo`` craft).

    Backends: ``"ipopt"``, ``"sqpmethod"`` (Gauss–Newton + qrqp),
    ``"sqpmethod-daqp"`` (dense: ~10 s per cold solve, left out with
    ``quick``) and ``"fatrop"`` where installed. Error: the
    relative cost difference to IPOPT at ``tol = 1e-12`` (plus the scaled
    bound violation of the plan).
    """
    from adcs_common.quaternion import quat_from_axis_angle
    from ocp.models.rigid import rigid_spacecraft
    from ocp.mpc import AttitudeMPC, available_mpc_solvers

    show = progress or _progress_fn(False)
    sc = load_spacecraft("demo" if spacecraft is None else spacecraft)
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    x0 = model.state([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
    ref = AttitudeMPC(model, solver="ipopt", max_iter=3000,
                      solver_options={"ipopt": {"tol": 1e-12}}).step(x0, qf)
    avail = available_mpc_solvers()
    default = [s for s in ("ipopt", "sqpmethod", "sqpmethod-daqp",
                           "fatrop") if s.split("-")[0] in avail
               and not (quick and s == "sqpmethod-daqp")]
    names = list(backends) if backends else default
    rows = []
    for name in names:
        solver, _, qp = name.partition("-")
        try:
            mpc = AttitudeMPC(model, solver=solver,
                              **({"qp_solver": qp} if qp else {}))
        except AdcsError as exc:
            show(f"[slew] {name}: not available ({exc})")
            continue
        times, err, fails, wrong = [], 0.0, 0, 0
        for k in range(reps):
            mpc.reset()
            try:
                s = mpc.step(x0, qf, check=False)
            except AdcsError:
                fails += 1
                continue
            e = max(abs(s.cost - ref.cost) / ref.cost, s.violation,
                    s.defect)
            err = max(err, e)
            wrong += int(e > TOL)
            times.append(s.solve_time)
            show(f"[slew] {name} {k + 1}/{reps}")
        med, p99 = _stats(times)
        rows.append(BenchRow("slew", name, reps, med, p99, err,
                             float("nan"), fails, wrong))
    return rows


# ------------------------------------------------------------------- driver
def format_table(rows: Sequence[BenchRow]) -> str:
    """Markdown table: median/p99 time, error, KKT, failures, wrong."""
    lines = ["| problem | backend | median [µs] | p99 [µs] | max error | "
             "max KKT | failed | wrong |", "|" + "---|" * 8]
    for r in rows:
        kkt = "–" if np.isnan(r.max_kkt) else f"{r.max_kkt:.1e}"
        lines.append(
            f"| {r.problem} | {r.backend} | {1e6 * r.median_s:.1f} | "
            f"{1e6 * r.p99_s:.1f} | {r.max_error:.1e} | {kkt} | "
            f"{r.failures}/{r.n} | {r.wrong}/{r.n} |")
    return "\n".join(lines)


def _plot(rows: Sequence[BenchRow], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    problems = [p for p in PROBLEMS if any(r.problem == p for r in rows)]
    fig, axes = plt.subplots(len(problems), 1, squeeze=False,
                             figsize=(7, 2.2 + 0.35 * len(rows)))
    for ax, prob in zip(axes[:, 0], problems):
        sub = [r for r in rows if r.problem == prob]
        y = np.arange(len(sub))
        t = [1e6 * r.median_s if np.isfinite(r.median_s) else 0.0
             for r in sub]
        colors = ["tab:green" if r.ok else "tab:red" for r in sub]
        ax.barh(y, t, color=colors)
        ax.set_yticks(y, [r.backend for r in sub])
        ax.set_xscale("log")
        ax.set_title(f"{prob} (red: failed or wrong answers)")
        ax.set_xlabel("median time per solve [µs]")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_bench(out_dir=None, *, problems: Sequence[str] = PROBLEMS,
              backends: Sequence[str] | None = None,
              repetitions: int | None = None, quick: bool = False,
              progress: bool = True, seed: int = 0,
              spacecraft=None) -> list[BenchRow]:
    """Run the benchmark, print the table, write JSON and PNG.

    Parameters
    ----------
    out_dir : str or pathlib.Path, optional
        Folder for ``bench.json`` and ``bench.png`` (nothing written when
        None).
    problems : sequence of str
        Subset of `PROBLEMS`.
    backends : sequence of str, optional
        Backend names (default every installed one); names a problem does
        not know are reported as not available for that problem.
    repetitions : int, optional
        Solves per backend for the QPs (default 200, 20 with ``quick``);
        the slew uses a fifth of it (at least 2).
    quick : bool
        Small settings.
    progress : bool
        Print progress to stderr.
    seed : int
        Seed of the random problems.
    spacecraft : ocp.spacecraft.Spacecraft, str or pathlib.Path, optional
        The craft whose wheels, thrusters and inertia are benchmarked (a
        catalogue name or a TOML file); default: the pyramid, the
        six-thruster unit and the ``demo`` craft of earlier figures.

    Returns
    -------
    list of BenchRow

    Raises
    ------
    InvalidValueError
        Unknown problem or bad repetitions.
    """
    probs = list(problems)
    bad = [p for p in probs if p not in PROBLEMS]
    if bad or not probs:
        raise InvalidValueError(
            f"problems must be among {', '.join(PROBLEMS)}, got "
            f"{bad or probs}")
    reps = repetitions if repetitions is not None else (20 if quick
                                                        else 200)
    if int(reps) < 1:
        raise InvalidValueError(f"repetitions must be >= 1, got {reps!r}")
    reps = int(reps)
    _check_backends(backends)
    if spacecraft is not None:
        spacecraft = load_spacecraft(spacecraft)
    out = None if out_dir is None else output_folder(out_dir, "out")
    show = _progress_fn(progress)
    rows: list[BenchRow] = []
    stopped = None
    try:
        if "wheels" in probs:
            stopped = "wheels"
            show("[wheels] bounded allocation QP")
            rows += bench_wheels(backends, reps, seed, show, spacecraft)
        if "thrusters" in probs:
            stopped = "thrusters"
            show("[thrusters] duty-cycle QP, six-thruster unit")
            rows += bench_thrusters(backends, reps, seed, show, spacecraft)
        if "slew" in probs:
            stopped = "slew"
            show("[slew] MPC slew NLP, horizon 20")
            rows += bench_slew(backends, max(reps // 5, 2) if not quick
                               else 2, show, quick, spacecraft)
        stopped = None
    except KeyboardInterrupt:
        pass
    print(format_table(rows))
    if out is not None:
        (out / "bench.json").write_text(json.dumps(
            {"tolerance": TOL, "repetitions": reps,
             "interrupted_during": stopped,
             "provenance": dict(provenance()),
             "rows": [asdict(r) for r in rows]}, indent=2))
        if rows:
            _plot(rows, out / "bench.png")
        print(f"wrote {out / 'bench.json'}" + (
            f" and {out / 'bench.png'}" if rows else ""))
    if stopped is not None:
        raise KeyboardInterrupt(
            f"benchmark stopped during {stopped!r}; {len(rows)} finished "
            "rows kept" + (f" in {out / 'bench.json'}" if out else ""))
    return rows
