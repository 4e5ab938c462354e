"""Robustness of the allocators' backends on random problems (a benchmark).

Run from the repository root::

    python -m benchmarks.robustness [--wheels 10000] [--duties 10000]
                                    [--backends daqp,osqp]

Wheel demands (the δ = 55°, γ = 45° pyramid, and six wheels with one
failed and unequal weights), each with wheel momenta inside ±1.1 h_max and
a 0.5 s step, some beyond the attainable set; duty cycles of the
six-thruster unit with the box and the norm momentum bound. Every answer
is checked against an independent reference: for the wheels the KKT
certificate of the allocator's own QP (`adcs.bench.kkt_residual`),
when saturated HiGHS's largest attainable scale α (an LP), and for the
least-squares substitute scipy's bounded least squares; for the duties
quadprog's optimum of the canonical QP and the KKT certificate.
Prints, per case and backend: problems, solved, failed, wrong (an answer
the reference rejects), largest error.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy.optimize import linprog, lsq_linear

from adcs.bench import kkt_residual
from adcs_common.exceptions import SolverError
from allocation import QPAllocator, WheelArray
from allocation.qp.problem import torque_bounds
from thrusters import DutyCycleAllocator, six_thruster_unit

TOL = 1e-6


def wheel_arrays() -> dict[str, tuple[WheelArray, np.ndarray]]:
    """Return the arrays of the study and their weights."""
    six = WheelArray.from_axes(np.random.default_rng(6).normal(size=(3, 6)),
                               h_max=1.0, m_max=0.1,
                               normalize=True).with_failed(2)
    return {"pyramid": (WheelArray.pyramid(h_max=4.0, m_max=0.2),
                        np.ones(4)),
            "6 wheels, wheel 3 failed, unequal weights": (
                six, np.array([1.0, 2.0, 1.0, 0.5, 3.0, 1.5]))}


def _max_alpha(A, lo, hi, M) -> float | None:
    """Largest α in [0, 1] with α M = A m, lo <= m <= hi (HiGHS), or None."""
    n = A.shape[1]
    res = linprog(np.r_[np.zeros(n), -1.0],
                  A_eq=np.hstack([A, -M[:, None]]), b_eq=np.zeros(3),
                  bounds=list(zip(lo, hi)) + [(0.0, 1.0)], method="highs")
    return float(res.x[-1]) if res.status == 0 else None


def check_wheels(arr, weights, alloc, M, h, dt) -> tuple[str, float]:
    """``("ok" | "failed" | "wrong", error)`` of one wheel allocation."""
    try:
        r = alloc.allocate(M, h, dt)
    except SolverError:
        return "failed", np.inf
    A = arr.axes * arr.active
    lo, hi, _ = torque_bounds(arr, h, dt)
    lo, hi = lo * arr.active, hi * arr.active
    target = r.achieved
    if r.mode == "scale":
        ref = _max_alpha(A, lo, hi, M)
        err = np.inf if ref is None else abs(ref - r.alpha)
        if err > TOL:
            return "wrong", err
    n = arr.n_wheels
    C = np.vstack([A, np.eye(n)])
    kkt = kkt_residual(2 * np.diag(weights), np.zeros(n), C,
                       np.r_[target, lo], np.r_[target, hi], r.torques)
    if r.mode == "least_squares":
        # the attainable torque closest to M: scipy's bounded least
        # squares gives the same distance
        ref = lsq_linear(A, M, bounds=(lo, hi),
                         tol=1e-14) if np.all(lo < hi) else None
        if ref is None:     # pinned wheels: least squares on the free ones
            free = lo < hi
            b = M - A[:, ~free] @ lo[~free]
            ref = lsq_linear(A[:, free], b, bounds=(lo[free], hi[free]),
                             tol=1e-14)
        dist, ref_dist = (np.linalg.norm(M - r.achieved),
                          np.sqrt(2 * ref.cost))
        err = abs(dist - ref_dist) / max(np.linalg.norm(M), 1e-300)
        return ("ok" if err <= TOL else "wrong"), err
    return ("ok" if kkt <= TOL else "wrong"), kkt


def wheel_demands(arr: WheelArray, n: int, rng) -> list:
    """Random demands: within and beyond the envelope, momenta near h_max."""
    out = []
    for _ in range(n):
        m = arr.m_max * arr.active * rng.uniform(-1, 1, arr.n_wheels)
        M = arr.axes @ m * rng.choice([0.5, 1.0, 1.5])
        h = arr.h_max * rng.uniform(-1.1, 1.1, arr.n_wheels)
        out.append((M, h, 0.5))
    return out


def duty_cycles(n: int, rng) -> list:
    """Random cycles: burns and holds, momentum inside the bound."""
    return [(rng.choice([0.0, rng.uniform(0.0, 0.739)]),
             rng.uniform(-0.01, 0.01, 2),
             np.r_[rng.uniform(-0.012, 0.012), 0.0,
                   rng.uniform(-0.012, 0.012)],
             np.r_[rng.normal(scale=5e-4), 0.0, rng.normal(scale=5e-4)])
            for _ in range(n)]


def check_duty(alloc, cycle, quadprog) -> tuple[str, float]:
    """``("ok" | "failed" | "wrong", error)`` of one duty cycle."""
    r = alloc.solve(*cycle)
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
        x_ref = quadprog.solve_qp(qp.P, -q, Cq.T, bq, meq=e)[0]
    except ValueError:          # quadprog: the QP is infeasible
        return ("ok" if r.status == "infeasible" else "wrong"), 0.0
    if not r.success:
        return "failed", np.inf
    x = np.r_[r.duty, r.momentum_excess / alloc.h_max]
    err = float(np.max(np.abs(x - x_ref)))
    kkt = kkt_residual(qp.P, q, np.vstack([qp.A, np.eye(qp.nx)]),
                       np.r_[l, qp.lb], np.r_[u, ub], x)
    return ("ok" if err <= TOL and kkt <= TOL else "wrong"), max(err, kkt)


def tally(checks) -> dict:
    """Count the verdicts of a run."""
    verdicts = [v for v, _ in checks]
    errs = [e for v, e in checks if v == "ok"]
    return {"n": len(checks), "ok": verdicts.count("ok"),
            "failed": verdicts.count("failed"),
            "wrong": verdicts.count("wrong"),
            "max_error": max(errs) if errs else float("nan")}


def run(n_wheels: int, n_duties: int, backends: list[str],
        seed: int = 0) -> list[tuple[str, str, dict, float]]:
    """Run every case and backend; rows ``(case, backend, tally, s)``."""
    import quadprog

    rows = []
    rng = np.random.default_rng(seed)
    for name, (arr, w) in wheel_arrays().items():
        demands = wheel_demands(arr, n_wheels, rng)
        for b in backends:
            alloc = QPAllocator(arr, w, solver=b)
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = [check_wheels(arr, w, alloc, *d) for d in demands]
            rows.append((f"wheels: {name}", b, tally(res),
                         time.perf_counter() - t0))
    unit = six_thruster_unit()
    cycles = duty_cycles(n_duties, rng)
    for bound in ("box", "norm"):
        for b in backends:
            alloc = DutyCycleAllocator(unit, 2.0, 0.012, solver=b,
                                       tracking="weighted", bound=bound)
            t0 = time.perf_counter()
            res = [check_duty(alloc, c, quadprog) for c in cycles]
            rows.append((f"duties: {bound} bound", b, tally(res),
                         time.perf_counter() - t0))
    return rows


def format_rows(rows) -> str:
    """Format the rows of `run` as a Markdown table."""
    out = ["| problems | backend | n | solved and right | failed | wrong "
           "| largest error |", "|---|---|---:|---:|---:|---:|---:|"]
    for case, b, t, _ in rows:
        out.append(f"| {case} | {b} | {t['n']} | {t['ok']} | {t['failed']}"
                   f" | {t['wrong']} | {t['max_error']:.1e} |")
    return "\n".join(out)


def main(argv=None) -> None:
    """Print the robustness table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wheels", type=int, default=10000)
    ap.add_argument("--duties", type=int, default=10000)
    ap.add_argument("--backends", default="daqp,osqp")
    args = ap.parse_args(argv)
    rows = run(args.wheels, args.duties, args.backends.split(","))
    print(format_rows(rows))


if __name__ == "__main__":
    main()
