"""Peers on the same problems, timed in the same run beside ours.

Run from the repository root: ``python -m benchmarks.peers``. Each peer
runs only where it is importable (a clear message otherwise):

* cvxpygen (``pip install cvxpygen``): the bounded wheel QP of the
  pyramid (``min |m|²`` s.t. ``A m = M``, ``|m_i| <= m_max``) generated
  as C for OSQP, at its default tolerance and at 1e-6 and 1e-9; its C
  solve time (``solver_stats.solve_time``) against the exported
  ``wheel_qp`` of `ocp.export_c` timed by its own C driver, and the
  largest difference from `QPAllocator` on 300 demands with a bound
  active.

* cvxpygen: the duty-cycle QP of `thrusters.build_qp` (hard tracking,
  T_T = 2 s) the same way, against the exported ``duty_qp``.

do-mpc and acados (the MPC) are not covered by this script yet; it says
so when run.
"""

from __future__ import annotations

import importlib.util
import shutil
import statistics
import tempfile

import numpy as np

from allocation import QPAllocator, WheelArray


def _ours_c(arr: WheelArray) -> dict:
    """Driver medians [µs] of the exported ``wheel_qp`` and ``duty_qp``."""
    from ocp import export_c, run_driver
    from thrusters import six_thruster_unit

    with tempfile.TemporaryDirectory() as out:
        res = export_c(out, wheels=arr, thrusters=six_thruster_unit(),
                       mpc_variants=(), build=True, repeats=20000)
        t = run_driver(res)
        return {k: t[k]["median_us"] for k in ("wheel_qp", "duty_qp")}


def cvxpygen_wheel_qp(arr: WheelArray, n: int = 300) -> list[tuple]:
    """Rows (label, C solve median [µs], max |Δm| [N·m]) of cvxpygen."""
    import cvxpy as cp

    A = np.asarray(arr.axes)
    m_max = float(arr.m_max.max())
    m = cp.Variable(arr.n_wheels, name="m")
    t = cp.Parameter(3, name="t")
    prob = cp.Problem(cp.Minimize(cp.sum_squares(m)),
                      [A @ m == t, cp.abs(m) <= m_max])
    code, cpg_solve = _generate(prob, "wheel_cpg")

    prob.register_solve("CPG", cpg_solve)
    ref = QPAllocator(arr)
    rng = np.random.default_rng(0)
    rows = []
    for eps in (None, 1e-6, 1e-9):
        kw = {} if eps is None else {"eps_abs": eps, "eps_rel": eps,
                                     "max_iter": 100000}
        times, err = [], 0.0
        for _ in range(n):
            M = A @ (0.97 * m_max * rng.uniform(-1, 1, arr.n_wheels))
            t.value = M
            prob.solve(method="CPG", **kw)
            times.append(prob.solver_stats.solve_time)
            err = max(err, float(np.abs(m.value
                                        - ref.allocate(M).torques).max()))
        label = "default" if eps is None else f"eps {eps:g}"
        rows.append((f"cvxpygen OSQP C ({label})",
                     1e6 * statistics.median(times), err))
    shutil.rmtree(code, ignore_errors=True)
    return rows


def _generate(prob, name: str) -> tuple[str, object]:
    """Generate OSQP C for ``prob`` with cvxpygen; its solve function."""
    import importlib
    import os
    import sys

    from cvxpygen import cpg

    code = tempfile.mkdtemp(prefix="adcs_cpg_")
    here = os.getcwd()
    os.chdir(code)           # cvxpygen names its module after code_dir
    try:
        cpg.generate_code(prob, code_dir=name, solver="OSQP", wrapper=True)
    finally:
        os.chdir(here)
    sys.path.insert(0, code)
    return code, importlib.import_module(f"{name}.cpg_solver").cpg_solve


def cvxpygen_duty_qp(n: int = 200) -> list[tuple]:
    """Rows (label, C solve median [µs], max |Δduty|) of cvxpygen.

    The canonical duty-cycle QP of `thrusters.build_qp` (hard tracking,
    momentum box, T_T = 2 s) with ``q``, ``l``, ``u`` as parameters.
    """
    import cvxpy as cp

    from thrusters import DutyCycleAllocator, six_thruster_unit
    from thrusters.qp.problem import INF

    alloc = DutyCycleAllocator(six_thruster_unit(), 2.0, 0.012)
    qp = alloc.qp
    x = cp.Variable(qp.nx, name="x")
    q = cp.Parameter(qp.nx, name="q")
    lo = cp.Parameter(qp.A.shape[0], name="lo")
    hi = cp.Parameter(qp.A.shape[0], name="hi")
    ne = qp.n_eq
    up = np.flatnonzero(qp.upper_rows[ne:]) + ne
    dn = np.flatnonzero(qp.lower_rows[ne:]) + ne
    cons = [qp.A[:ne] @ x == lo[:ne], qp.A[up] @ x <= hi[up],
            qp.A[dn] @ x >= lo[dn], x >= qp.lb, x <= qp.ub]
    prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(x, cp.psd_wrap(qp.P))
                                  + q @ x), cons)
    code, solve = _generate(prob, "duty_cpg")
    prob.register_solve("CPG", solve)
    rng = np.random.default_rng(1)
    rows = []
    for eps in (None, 1e-6, 1e-9):
        kw = {} if eps is None else {"eps_abs": eps, "eps_rel": eps,
                                     "max_iter": 100000}
        times, err, done = [], 0.0, 0
        while done < n:
            th = alloc.theta(rng.choice([0.0, rng.uniform(0, 0.7)]),
                             rng.uniform(-0.004, 0.004, 2),
                             (rng.uniform(-0.01, 0.01), 0.0,
                              rng.uniform(-0.01, 0.01)))
            ref = alloc.solve_theta(th)
            if not ref.success:
                continue
            qv, lv, uv = qp.vectors(th)
            q.value = qv
            lo.value = np.where(lv <= -INF / 2, 0.0, lv)
            hi.value = np.where(uv >= INF / 2, 0.0, uv)
            prob.solve(method="CPG", **kw)
            times.append(prob.solver_stats.solve_time)
            err = max(err, float(np.abs(x.value[:-1] - ref.duty).max()))
            done += 1
        label = "default" if eps is None else f"eps {eps:g}"
        rows.append((f"cvxpygen OSQP C ({label})",
                     1e6 * statistics.median(times), err))
    shutil.rmtree(code, ignore_errors=True)
    return rows


def _in_subprocess(fn, *args):
    """Run ``fn(*args)`` in a fresh (spawned) process; its result."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as ex:
        return ex.submit(fn, *args).result()


def main() -> None:
    """Print the table."""
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    if importlib.util.find_spec("cvxpygen") is None:
        print("cvxpygen: not installed (pip install cvxpygen): skipped")
        return
    # each generated module registers the same pybind11 types: one
    # process per problem
    wheel = _in_subprocess(cvxpygen_wheel_qp, arr)
    duty = _in_subprocess(cvxpygen_duty_qp)
    ours = _ours_c(arr)
    for title, key, unit, rows in (
            ("wheel QP (pyramid, bound active)", "wheel_qp", "N·m", wheel),
            ("duty QP (six-thruster unit)", "duty_qp", "duty", duty)):
        print(f"\n| {title} | C median [µs] | max |Δ| vs the toolbox "
              f"[{unit}] | ratio to ours |")
        print("|---|---:|---:|---:|")
        print(f"| ours: exported {key} | {ours[key]:.3g} | ≤ 1e-10 "
              "(tests) | 1 |")
        for label, us, err in rows:
            print(f"| {label} | {us:.3g} | {err:.1e} | "
                  f"{us / ours[key]:.0f} |")
    for peer in ("do_mpc", "acados_template"):
        state = ("installed" if importlib.util.find_spec(peer)
                 else "not installed")
        print(f"{peer}: {state}; the MPC peers are not covered by this "
              "script yet")


if __name__ == "__main__":
    main()
