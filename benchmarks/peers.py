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

do-mpc and acados (the MPC) and the duty-cycle QP through cvxpygen are
not covered by this script yet; it says so when run.
"""

from __future__ import annotations

import importlib.util
import shutil
import statistics
import tempfile

import numpy as np

from allocation import QPAllocator, WheelArray


def _ours_c(arr: WheelArray) -> float:
    """Median [µs] of the exported ``wheel_qp`` in its C driver."""
    from ocp import export_c, run_driver

    with tempfile.TemporaryDirectory() as out:
        res = export_c(out, wheels=arr, mpc_variants=(), build=True,
                       repeats=20000)
        return run_driver(res)["wheel_qp"]["median_us"]


def cvxpygen_wheel_qp(arr: WheelArray, n: int = 300) -> list[tuple]:
    """Rows (label, C solve median [µs], max |Δm| [N·m]) of cvxpygen."""
    import sys

    import cvxpy as cp
    from cvxpygen import cpg

    A = np.asarray(arr.axes)
    m_max = float(arr.m_max.max())
    m = cp.Variable(arr.n_wheels, name="m")
    t = cp.Parameter(3, name="t")
    prob = cp.Problem(cp.Minimize(cp.sum_squares(m)),
                      [A @ m == t, cp.abs(m) <= m_max])
    import os

    code = tempfile.mkdtemp(prefix="adcs_cpg_")
    here = os.getcwd()
    os.chdir(code)           # cvxpygen names its module after code_dir
    try:
        cpg.generate_code(prob, code_dir="wheel_cpg", solver="OSQP",
                          wrapper=True)
    finally:
        os.chdir(here)
    sys.path.insert(0, code)
    from wheel_cpg.cpg_solver import cpg_solve

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


def main() -> None:
    """Print the table."""
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    if importlib.util.find_spec("cvxpygen") is None:
        print("cvxpygen: not installed (pip install cvxpygen): skipped")
        return
    rows = cvxpygen_wheel_qp(arr)
    ours = _ours_c(arr)
    print("| wheel QP (pyramid, bound active) | C median [µs] | "
          "max |Δm| vs QPAllocator [N·m] | ratio to ours |")
    print("|---|---:|---:|---:|")
    print(f"| ours: exported wheel_qp (closed form) | {ours:.3g} | "
          "≤ 1e-10 (tests) | 1 |")
    for label, us, err in rows:
        print(f"| {label} | {us:.3g} | {err:.1e} | {us / ours:.0f} |")
    for peer in ("do_mpc", "acados_template"):
        state = ("installed" if importlib.util.find_spec(peer)
                 else "not installed")
        print(f"{peer}: {state}; the MPC peers are not covered by this "
              "script yet")


if __name__ == "__main__":
    main()
