"""Robustness of every allocator backend on random problems (a benchmark).

Run from the repository root::

    python -m benchmarks.robustness [--wheels 4800] [--duties 2250]
                                    [--backends all | daqp,osqp,...]

Wheel cases: random arrays of 3–8 wheels (random axes; beyond four wheels
one failed), unequal weights, wheel momenta up to ±1.2 h_max with a 0.5 s
step (so some wheels are pinned by their momentum bound), demands inside
and beyond the attainable set. Duty cycles: the six-thruster unit with the
box and the norm momentum bound, and random custom sets of six to eight
thrusters with weighted tracking.

Every answer a backend calls a success is checked against references
written independently of the toolbox's solvers:

* the scale α: HiGHS's LP ``max α s.t. A m = α M, lo <= m <= hi``
  (also: the allocator must keep the direction whenever the LP finds an
  α, and must not when it finds none);
* the least-squares substitute: scipy's bounded least squares distance;
* the torques: quadprog's optimum for the allocator's own target, or,
  where quadprog refuses a boundary target, the KKT residual with
  sign-constrained multipliers (`adcs.bench.kkt_residual`);
* the duties: quadprog's optimum of the canonical QP and the KKT residual.

"wrong" counts answers reported as a success that a reference rejects
(torques off by more than 1e-6 m_max, duties by more than 1e-6, α by more
than 1e-6). Prints one Markdown row per problem set and backend.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy.optimize import linprog, lsq_linear
from tqdm.auto import tqdm

from adcs.bench import kkt_residual
from adcs_common.exceptions import AdcsError, SolverError
from allocation import QPAllocator, WheelArray
from allocation import available_solvers as wheel_solvers
from allocation.qp.problem import torque_bounds
from thrusters import DutyCycleAllocator, ThrusterSet, six_thruster_unit
from thrusters import available_solvers as duty_solvers

TOL = 1e-6
#: Per-wheel momentum bound and torque bound of the random arrays.
H_MAX, M_MAX = 1.0, 0.1
DT = 0.5


# ------------------------------------------------------------ references
def lp_alpha(A, lo, hi, M) -> float | None:
    """Largest α in [0, 1] with α M = A m, lo <= m <= hi (HiGHS), or None."""
    n = A.shape[1]
    res = linprog(np.r_[np.zeros(n), -1.0],
                  A_eq=np.hstack([A, -M[:, None]]), b_eq=np.zeros(3),
                  bounds=list(zip(lo, hi)) + [(0.0, 1.0)], method="highs")
    return float(res.x[-1]) if res.status == 0 else None


def ls_distance(A, lo, hi, M) -> float:
    """Distance from M to the attainable set (scipy's bounded lsq)."""
    free = lo < hi
    b = M - A[:, ~free] @ lo[~free]
    if not free.any():
        return float(np.linalg.norm(b))
    ref = lsq_linear(A[:, free], b, bounds=(lo[free], hi[free]), tol=1e-14)
    return float(np.linalg.norm(A[:, free] @ ref.x - b))


def qp_torques(A, w, target, lo, hi) -> np.ndarray | None:
    """quadprog's min Σ w m² s.t. A m = target, lo <= m <= hi (or None)."""
    import quadprog

    fixed = lo >= hi
    free = ~fixed
    m = np.where(fixed, lo, 0.0)
    if not free.any():
        return m
    b = target - A[:, fixed] @ m[fixed]
    Af = A[:, free]
    U, s, _ = np.linalg.svd(Af)
    r = int((s > 1e-10 * s.max()).sum())
    k = int(free.sum())
    C = np.vstack([U[:, :r].T @ Af, np.eye(k), -np.eye(k)]).T
    bq = np.r_[U[:, :r].T @ b, lo[free], -hi[free]]
    try:
        m[free] = quadprog.solve_qp(2 * np.diag(w[free]), np.zeros(k), C,
                                    bq, meq=r)[0]
    except ValueError:          # quadprog: a boundary target "infeasible"
        return None
    return m


# ------------------------------------------------------------- wheels
def wheel_cases(n: int, rng, per_array: int = 100) -> list:
    """``(array, weights, M, h)`` of n random cases, 100 per array."""
    out = []
    while len(out) < n:
        k = int(rng.integers(3, 9))
        try:
            arr = WheelArray.from_axes(rng.normal(size=(3, k)), h_max=H_MAX,
                                       m_max=M_MAX, normalize=True)
            if k > 4:
                arr = arr.with_failed(int(rng.integers(k)))
            arr.require_full_rank()
        except AdcsError:
            continue
        w = rng.uniform(0.5, 3.0, k)
        for _ in range(min(per_array, n - len(out))):
            m = arr.m_max * arr.active * rng.uniform(-1, 1, k)
            M = arr.axes @ m * rng.choice([0.5, 1.0, 1.5, 3.0])
            h = arr.h_max * rng.uniform(-1.2, 1.2, k)
            out.append((arr, w, M, h))
    return out


def wheel_reference(arr, M, h) -> dict:
    """What the references say of one case (independent of the backend)."""
    A = arr.axes * arr.active
    lo, hi, _ = torque_bounds(arr, h, DT)
    lo, hi = lo * arr.active, hi * arr.active
    return {"A": A, "lo": lo, "hi": hi, "alpha": lp_alpha(A, lo, hi, M),
            "distance": None}


def check_wheel(alloc, arr, w, M, h, ref) -> tuple[str, float]:
    """``("ok" | "failed" | "wrong", error)`` of one wheel allocation."""
    try:
        r = alloc.allocate(M, h, DT)
    except SolverError:
        return "failed", np.inf
    A, lo, hi, a_ref = ref["A"], ref["lo"], ref["hi"], ref["alpha"]
    m_scale = float(arr.m_max.max())
    if r.mode == "least_squares":
        if a_ref is not None and a_ref > TOL:
            return "wrong", a_ref       # the direction could be kept
        if ref["distance"] is None:
            ref["distance"] = ls_distance(A, lo, hi, M)
        err = abs(np.linalg.norm(M - r.achieved) - ref["distance"])
        if err > TOL * max(1.0, np.linalg.norm(M)):
            return "wrong", err
    else:
        if a_ref is None:
            return "wrong", np.inf      # scale claimed, none attainable
        err = abs(a_ref - r.alpha)
        if err > TOL:
            return "wrong", err
    m_ref = qp_torques(A, w, r.achieved, lo, hi)
    if m_ref is not None:
        err = float(np.abs(r.torques - m_ref).max()) / m_scale
    else:
        n = arr.n_wheels
        err = kkt_residual(2 * np.diag(w), np.zeros(n),
                           np.vstack([A, np.eye(n)]), np.r_[r.achieved, lo],
                           np.r_[r.achieved, hi], r.torques)
    return ("ok" if err <= TOL else "wrong"), err


# -------------------------------------------------------------- duties
def custom_unit(rng) -> ThrusterSet:
    """A random set of 6–8 0.5 N thrusters on a 0.3 m box, each pointing
    along ±Y tilted by up to about 30°."""
    k = int(rng.integers(6, 9))
    d = np.vstack([rng.uniform(-0.6, 0.6, k), rng.choice([-1.0, 1.0], k),
                   rng.uniform(-0.6, 0.6, k)])
    pressure = six_thruster_unit().pressure
    return ThrusterSet(rng.uniform(-0.3, 0.3, (3, k)),
                       d / np.linalg.norm(d, axis=0),
                       pressure_slope=np.full(k, 0.5 / pressure),
                       thrust_offset=np.zeros(k), pressure=pressure)


def duty_cycles(n: int, rng) -> list:
    """Random cycles: burns and holds, momentum inside the bound."""
    return [(rng.choice([0.0, rng.uniform(0.0, 0.739)]),
             rng.uniform(-0.01, 0.01, 2),
             np.r_[rng.uniform(-0.012, 0.012), 0.0,
                   rng.uniform(-0.012, 0.012)],
             np.r_[rng.normal(scale=5e-4), 0.0, rng.normal(scale=5e-4)])
            for _ in range(n)]


def duty_reference(alloc, cycle, quadprog):
    """quadprog's optimum of the canonical duty QP (None: infeasible)."""
    qp = alloc.qp
    q, l, u = qp.vectors(alloc.theta(*cycle))
    l, u = np.where(l <= -1e29, -np.inf, l), np.where(u >= 1e29, np.inf, u)
    e = qp.n_eq
    G = np.vstack([qp.A[e:][np.isfinite(u[e:])],
                   -qp.A[e:][np.isfinite(l[e:])]])
    h = np.r_[u[e:][np.isfinite(u[e:])], -l[e:][np.isfinite(l[e:])]]
    ub = np.minimum(qp.ub, 1e3)
    Cq = np.vstack([qp.A[:e], -G, np.eye(qp.nx), -np.eye(qp.nx)])
    bq = np.r_[l[:e], -h, qp.lb, -ub]
    try:
        x = quadprog.solve_qp(qp.P, -q, Cq.T, bq, meq=e)[0]
    except ValueError:          # quadprog: the QP is infeasible
        x = None
    return x, (q, l, u, ub)


def check_duty(alloc, cycle, ref) -> tuple[str, float]:
    """``("ok" | "failed" | "wrong", error)`` of one duty cycle."""
    r = alloc.solve(*cycle)
    x_ref, (q, l, u, ub) = ref
    if x_ref is None:
        return ("ok" if r.status == "infeasible" else "wrong"), 0.0
    if not r.success:
        return "failed", np.inf
    qp = alloc.qp
    x = np.r_[r.duty, r.momentum_excess / alloc.h_max]
    err = float(np.max(np.abs(x - x_ref)))
    kkt = kkt_residual(qp.P, q, np.vstack([qp.A, np.eye(qp.nx)]),
                       np.r_[l, qp.lb], np.r_[u, ub], x)
    return ("ok" if err <= TOL and kkt <= TOL else "wrong"), max(err, kkt)


# ---------------------------------------------------------------- run
def tally(checks) -> dict:
    """Count the verdicts of a run."""
    verdicts = [v for v, _ in checks]
    errs = [e for v, e in checks if v == "ok"]
    return {"n": len(checks), "ok": verdicts.count("ok"),
            "failed": verdicts.count("failed"),
            "wrong": verdicts.count("wrong"),
            "max_error": max(errs) if errs else float("nan")}


def _backends(names, offered) -> list[str]:
    """The names of ``names`` this QP offers (``"all"``: every one)."""
    if names == ["all"]:
        # a bare qpsolvers name and "qpsolvers:NAME" are the same backend
        return [b for b in offered if not (
            b.startswith("qpsolvers:") and b.split(":")[1] in offered
            and b.split(":")[1] not in ("osqp", "daqp"))]
    return [b for b in names if b in offered]


def run(n_wheels: int, n_duties: int, backends: list[str],
        seed: int = 0) -> list[tuple[str, str, dict, float]]:
    """Run every case and backend; rows ``(problems, backend, tally, s)``."""
    import quadprog

    rows = []
    rng = np.random.default_rng(seed)
    cases = wheel_cases(n_wheels, rng)
    refs = [wheel_reference(arr, M, h) for arr, _, M, h in cases]
    for b in _backends(backends, wheel_solvers()):
        t0 = time.perf_counter()
        allocs: dict[int, QPAllocator] = {}
        res = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for (arr, w, M, h), ref in tqdm(
                    zip(cases, refs), total=len(cases), disable=None,
                    desc=f"wheels {b}", leave=False):
                key = id(arr)
                if key not in allocs:
                    allocs = {key: QPAllocator(arr, w, solver=b)}
                res.append(check_wheel(allocs[key], arr, w, M, h, ref))
        rows.append(("wheels: 3-8 random wheels", b, tally(res),
                     time.perf_counter() - t0))
    cycles = duty_cycles(n_duties, rng)
    units = [("six-thruster unit, box bound", six_thruster_unit(), "box"),
             ("six-thruster unit, norm bound", six_thruster_unit(), "norm")]
    units += [(f"custom set {i + 1} ({u.n} thrusters)", u, "box")
              for i, u in enumerate(custom_unit(rng) for _ in range(2))]
    per_unit = max(1, n_duties // len(units))
    for name, unit, bound in units:
        some = cycles[:per_unit] if "custom" in name else cycles
        ref_alloc = DutyCycleAllocator(unit, 2.0, 0.012, solver="daqp",
                                       tracking="weighted", bound=bound)
        refs = [duty_reference(ref_alloc, c, quadprog) for c in some]
        for b in _backends(backends, duty_solvers()):
            alloc = DutyCycleAllocator(unit, 2.0, 0.012, solver=b,
                                       tracking="weighted", bound=bound)
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = [check_duty(alloc, c, r) for c, r in tqdm(
                    zip(some, refs), total=len(some), disable=None,
                    desc=f"duties {b}", leave=False)]
            rows.append((f"duties: {name}", b, tally(res),
                         time.perf_counter() - t0))
    return rows


def totals(rows) -> list[tuple[str, str, dict, float]]:
    """Rows summed per QP (wheels, duties) and backend."""
    out: dict[tuple[str, str], dict] = {}
    for case, b, t, s in rows:
        key = (case.split(":")[0], b)
        acc = out.setdefault(key, {"n": 0, "ok": 0, "failed": 0, "wrong": 0,
                                   "max_error": 0.0, "s": 0.0})
        for k in ("n", "ok", "failed", "wrong"):
            acc[k] += t[k]
        if np.isfinite(t["max_error"]):
            acc["max_error"] = max(acc["max_error"], t["max_error"])
        acc["s"] += s
    return [(k[0], k[1], v, v["s"]) for k, v in out.items()]


def format_rows(rows) -> str:
    """Format the rows of `run` as a Markdown table."""
    out = ["| problems | backend | n | solved and right | failed | "
           "wrong (success reported) | largest error |",
           "|---|---|---:|---:|---:|---:|---:|"]
    for case, b, t, _ in rows:
        out.append(f"| {case} | {b} | {t['n']} | {t['ok']} | {t['failed']}"
                   f" | {t['wrong']} | {t['max_error']:.1e} |")
    return "\n".join(out)


def main(argv=None) -> None:
    """Print the robustness table (per problem set, then per QP)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wheels", type=int, default=4800)
    ap.add_argument("--duties", type=int, default=2250)
    ap.add_argument("--backends", default="all")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rows = run(args.wheels, args.duties, args.backends.split(","), args.seed)
    print(format_rows(rows))
    print()
    print(format_rows(totals(rows)))


if __name__ == "__main__":
    main()
