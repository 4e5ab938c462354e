"""The bench's three problems: wheel QP, duty-cycle QP, MPC slew NLP."""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from adcs_common.interrupts import Interrupted, interrupted
from adcs_common.exceptions import AdcsError
from ocp.spacecraft import load_spacecraft

from .core import (
    CONTROLS,
    TOL,
    BenchRow,
    Corrections,
    Progress,
    _split,
    explain,
    kkt_residual,
    quiet,
    timed_row,
)

#: Seconds each backend may spend on one problem before it is cut short
#: and marked "too slow".
BUDGET = 8.0


# -------------------------------------------------------------------- wheels
def wheel_problem(spacecraft: Any | None = None, reps: int = 200,
                  seed: int = 0) -> tuple[Any, list[np.ndarray]]:
    """The wheel bench's array and demands (``(WheelArray, [M (3,)])``).

    The spacecraft's wheels (axes, ``m_max``, failed wheels; default the
    pyramid δ = 55°, γ = 45°, 0.2 N·m); ``reps`` demands ``M = A m`` [N·m]
    with ``m`` uniform in ``0.97 · [-m_max, m_max]`` (0 for a failed
    wheel).
    """
    from allocation import WheelArray

    arr = (WheelArray.pyramid(h_max=4.0, m_max=0.2) if spacecraft is None
           else load_spacecraft(spacecraft).wheels)
    A = np.asarray(arr.axes)
    m_cap = arr.m_max * arr.active
    rng = np.random.default_rng(seed)
    return arr, [A @ (0.97 * m_cap * rng.uniform(-1, 1, arr.n_wheels))
                 for _ in range(reps)]


def bench_wheels(backends: Sequence[str] | None = None, reps: int = 200,
                 seed: int = 0, progress: Progress | None = None,
                 spacecraft: Any | None = None,
                 budget: float = BUDGET) -> list[BenchRow]:
    """Time the bounded wheel-allocation QP across backends.

    The spacecraft's wheel array (default: the pyramid δ = 55°, γ = 45°,
    ``m_max = 0.2`` N·m); ``reps`` attainable demands ``M = A m`` with
    ``m`` uniform in ``0.97 · [-m_max, m_max]`` (0 for a failed wheel;
    most leave the minimum-norm law's reach, so bounds are active).
    Reference: the first certified backend among quadprog, daqp, clarabel.
    """
    from allocation import QPAllocator, available_solvers

    bar = progress or quiet()
    arr, demands = wheel_problem(spacecraft, reps, seed)
    A = np.asarray(arr.axes)
    n = arr.n_wheels
    m_cap = arr.m_max * arr.active
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
    return _backend_rows(
        "wheels", names,
        lambda base, opts: QPAllocator(arr, solver=base,
                                       solver_options=opts),
        lambda alloc, watch: (lambda M: watch(alloc.allocate(M)).torques),
        demands, refs, cert, bar, budget)


def _backend_rows(problem: str, names: list[str], build: Any,
                  solver_of: Any, cases: list, refs: list, certify: Any,
                  bar: Progress, budget: float) -> list[BenchRow]:
    """Time every backend of ``names`` on ``cases`` (one row each).

    ``build(base, options)`` makes the allocator (a backend it cannot
    make is reported as not available and skipped); ``solver_of(alloc,
    watch)`` returns the function `timed_row` times, passing each result
    through ``watch`` (a `Corrections`: a control row's note says what
    the certificate corrected, as counted).
    """
    bar.add(len(names) * len(cases))
    rows: list[BenchRow] = []
    for name in names:
        base, opts = _split(name)
        try:
            alloc = build(base, opts)
            watch = Corrections()
            row = timed_row(problem, name, cases, refs,
                            solver_of(alloc, watch), certify, bar, budget)
            if name.endswith("@loose"):
                row = replace(row, note=explain(row, budget, watch))
        except (KeyboardInterrupt, RuntimeError, AdcsError, TypeError,
                ValueError) as exc:
            if not interrupted(exc):
                if isinstance(exc, (KeyboardInterrupt, RuntimeError)):
                    raise
                bar.say(f"[{problem}] {name}: not available ({exc})")
                bar.skip(len(cases))
                continue
            # Ctrl-C: the backends finished so far are kept
            raise Interrupted(str(problem), partial=rows) from None
        rows.append(row)
    return rows


# ----------------------------------------------------------------- thrusters
#: Momentum bound of the thruster bench's duty QP [N·m·s].
THRUSTER_H_MAX = 0.012


def thruster_problem(spacecraft: Any | None = None, reps: int = 200,
                     seed: int = 0) -> tuple[Any, list[tuple]]:
    """The thruster bench's unit and cycles: ``(ThrusterSet or None, cases)``.

    The spacecraft's thruster set (None when it has none; default the
    six-thruster unit of [4]); ``reps`` cycles ``(P_T [N], M (2,) [N·m],
    H (3,) [N·m·s], τ (3,) [N·m])``.
    """
    from thrusters import six_thruster_unit

    unit = (six_thruster_unit() if spacecraft is None
            else load_spacecraft(spacecraft).thrusters)
    h_max = THRUSTER_H_MAX
    rng = np.random.default_rng(seed)
    cases = [(rng.choice([0.0, rng.uniform(0.0, 0.739)]),
              rng.uniform(-0.05, 0.05, 2),
              np.r_[rng.uniform(-1, 1) * h_max, 0.0,
                    rng.uniform(-1, 1) * h_max],
              np.r_[rng.normal(scale=5e-4), 0.0, rng.normal(scale=5e-4)])
             for _ in range(reps)]
    return unit, cases


def bench_thrusters(backends: Sequence[str] | None = None, reps: int = 200,
                    seed: int = 0, progress: Progress | None = None,
                    spacecraft: Any | None = None, budget: float = BUDGET
                    ) -> list[BenchRow]:
    """Time the thruster duty-cycle QP across backends.

    The spacecraft's thruster set (none: no rows), by default the
    six-thruster unit of [4], T_T = 2 s, ``h_max = 0.012`` N·m·s,
    weighted torque tracking, momentum box; random cycles with P_T in
    [0, 0.739] N, torques up to 0.05 N·m, momenta inside the bound.
    Each answer (duties and slack) is KKT-certified on the canonical QP
    and compared with the reference backend (quadprog, else clarabel).
    """
    from thrusters import DutyCycleAllocator, available_solvers
    from thrusters.qp.problem import INF

    bar = progress or quiet()
    unit, cases = thruster_problem(spacecraft, reps, seed)
    if unit is None:
        bar.say("[thrusters] skipped: the spacecraft has no thrusters")
        return []
    h_max = THRUSTER_H_MAX
    names = (list(backends) if backends
             else list(available_solvers()) + list(CONTROLS))
    kw: dict[str, Any] = dict(tracking="weighted", bound="box")
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
    return _backend_rows(
        "thrusters", names,
        lambda base, opts: DutyCycleAllocator(
            unit, 2.0, h_max, solver=base, solver_options=opts, **kw),
        lambda alloc, watch: (lambda th: duty_point(
            watch(alloc.solve_theta(th)))),
        thetas, refs,
        lambda th, x: kkt_residual(qp.P, data(th)[0], C, data(th)[1],
                                   data(th)[2], x), bar, budget)


# ---------------------------------------------------------------------- slew
def slew_controller(spacecraft: Any | None = None, **options: Any
                    ) -> tuple[Any, np.ndarray, np.ndarray]:
    """The slew bench's MPC and its case: ``(AttitudeMPC, x0, qf)``.

    The spacecraft's inertia, wheels and ``rate_max`` [rad/s] (default:
    the ``demo`` craft); from rest (``x0`` (7 + N,)) to 90° about
    (1, 1, 0) (``qf`` (4,)); ``options`` go to `ocp.mpc.AttitudeMPC`
    (solver, qp_solver, max_iter, solver_options).
    """
    from adcs_common.quaternion import quat_from_axis_angle
    from ocp.models.rigid import rigid_spacecraft
    from ocp.mpc import AttitudeMPC

    sc = load_spacecraft("demo" if spacecraft is None else spacecraft)
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    x0 = model.state([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
    return AttitudeMPC(model, rate_max=sc.rate_max, **options), x0, qf


def bench_slew(backends: Sequence[str] | None = None, reps: int = 5,
               progress: Progress | None = None, quick: bool = False,
               spacecraft: Any | None = None,
               budget: float = BUDGET) -> list[BenchRow]:
    """Time the MPC slew NLP (horizon 20, 90° from rest), cold-started.

    On the spacecraft's inertia, wheels and rate limit (default: the
    ``demo`` craft; `slew_controller`).

    Backends: ``"ipopt"``, ``"sqpmethod"`` (Gauss–Newton + qrqp),
    ``"sqpmethod-daqp"`` (dense: ~10 s per cold solve, left out with
    ``quick``) and ``"fatrop"`` where installed. Error: the
    relative cost difference to IPOPT at ``tol = 1e-12`` (plus the scaled
    bound violation of the plan). Each backend stops when ``budget``
    [s] is spent (a cold ``sqpmethod-daqp`` solve alone takes ~10 s).
    """
    from ocp.mpc import available_mpc_solvers

    bar = progress or quiet()
    ref_mpc, x0, qf = slew_controller(
        spacecraft, solver="ipopt", max_iter=3000,
        solver_options={"ipopt": {"tol": 1e-12}})
    ref = ref_mpc.step(x0, qf)
    avail = available_mpc_solvers()
    default = [s for s in ("ipopt", "condensed", "sqpmethod",
                           "sqpmethod-daqp", "fatrop")
               if s.split("-")[0] in avail
               and not (quick and s == "sqpmethod-daqp")]
    names = list(backends) if backends else default
    rows: list[BenchRow] = []
    bar.add(len(names) * reps)
    for name in names:
        solver, _, qp = name.partition("-")
        try:
            mpc, _, _ = slew_controller(
                spacecraft, solver=solver, **({"qp_solver": qp} if qp
                                              else {}))
        except AdcsError as exc:
            bar.say(f"[slew] {name}: not available ({exc})")
            bar.skip(reps)
            continue

        def solve(_case, mpc=mpc):
            mpc.reset()
            s = mpc.step(x0, qf, check=False)
            return np.array([max(abs(s.cost - ref.cost) / ref.cost,
                                 s.violation, s.defect)])

        try:
            row = timed_row("slew", name, [None] * reps,
                            [np.zeros(1)] * reps, solve,
                            lambda _c, x: float("nan"), bar, budget)
        except (KeyboardInterrupt, RuntimeError) as exc:
            if not interrupted(exc):
                raise
            raise Interrupted("slew", partial=rows) from None
        rows.append(row)
    return [BenchRow(**{**r.__dict__, "max_kkt": float("nan")})
            for r in rows]
