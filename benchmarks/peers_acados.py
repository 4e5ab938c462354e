"""acados on the toolbox's MPC problem, at long horizons, beside ours.

Run from the repository root, in an environment with acados
(``pip install comma-deps-acados``; its wheel pins another casadi:
``pip install --force-reinstall --no-deps casadi==<ours>`` afterwards)::

    python -m benchmarks.peers_acados [--horizons 20,50,100] [--steps 80]

`acados_ocp_solver` poses exactly the toolbox's OCP: explicit RK4 (one
step per interval), the nonlinear least-squares costs with acados's
scaling undone (stage weight 2/dt, terminal weight 2), the
Levenberg–Marquardt term ρ/dt and the wheel-momentum bound on the last
state too. For each horizon N the 80-step closed loop of the exported
driver (90° slew and hold, RK4 plant, dt 0.5 s) is flown by acados's
SQP_RTI with partial condensing HPIPM (``qp_solver_cond_N`` N/5 and
N/2), full condensing HPIPM and qpOASES, and by the toolbox's
stage-wise RTI in lockstep from the same states: the table gives
acados's own solve time (``time_tot``, C), its median and worst, the
largest difference of its commands from ours (must stay ≤ 1e-6 N·m),
its build time and generated C; ours comes from
`benchmarks.long_horizon` (C driver) in the same run.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import statistics
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

#: acados QP configurations tried at every N: (label, qp_solver, cond_N
#: as a fraction of N or None).
CONFIGS = (("partial condensing HPIPM, N/5", "PARTIAL_CONDENSING_HPIPM",
            0.2),
           ("partial condensing HPIPM, N/2", "PARTIAL_CONDENSING_HPIPM",
            0.5),
           ("full condensing HPIPM", "FULL_CONDENSING_HPIPM", None),
           ("full condensing qpOASES", "FULL_CONDENSING_QPOASES", None))


def _load_acados():
    """Import acados_template with its shared libraries loaded first."""
    import acados

    lib = acados.LIB_DIR
    for name in ("libblasfeo.so", "libhpipm.so", "libqpOASES_e.so.3.1"):
        if os.path.exists(os.path.join(lib, name)):
            ctypes.CDLL(os.path.join(lib, name), mode=ctypes.RTLD_GLOBAL)
    os.environ.setdefault("ACADOS_SOURCE_DIR", acados.DIR)
    os.environ.setdefault("ACADOS_PYTHON_INTERFACE_PATH",
                          acados.TEMPLATE_DIR)
    os.environ.setdefault("TERA_PATH", acados.TERA_PATH)
    from acados import acados_template
    return acados_template


def acados_ocp_solver(model, qf, horizon: int, dt: float, rti: bool = True,
                      qp_solver: str = "PARTIAL_CONDENSING_HPIPM",
                      cond_n: int | None = None):
    """``(solver, info)``: the toolbox's MPC OCP as an acados solver.

    ``info`` holds the build time [s] and the generated C [bytes].
    """
    from adcs_common.quaternion import quat_conj, quat_mul
    from ocp.mpc import MPCWeights

    at = _load_acados()
    w, wh = MPCWeights(), model.wheels
    x = ca.SX.sym("x", model.nx)
    u = ca.SX.sym("u", model.nu)
    am = at.AcadosModel()
    am.name, am.x, am.u = f"adcs_mpc_{horizon}", x, u
    am.xdot = ca.SX.sym("xdot", model.nx)
    am.f_expl_expr = model.dynamics(x, u, ca.DM.zeros(3))
    am.f_impl_expr = am.xdot - am.f_expl_expr
    qe = quat_mul(quat_conj(qf), x[:4])
    mm, hm = np.asarray(wh.m_max), np.asarray(wh.h_max)
    am.cost_y_expr = ca.vertcat(
        np.sqrt(w.torque) * u / ca.DM(mm),
        np.sqrt(w.momentum) * x[7:] / ca.DM(hm),
        np.sqrt(w.attitude) * qe[1:], np.sqrt(w.rate) * x[4:7])
    am.cost_y_expr_e = ca.vertcat(np.sqrt(w.terminal * w.attitude) * qe[1:],
                                  np.sqrt(w.terminal * w.rate) * x[4:7])
    o = at.AcadosOcp()
    o.model = am
    o.dims.N = horizon
    o.cost.cost_type = o.cost.cost_type_e = "NONLINEAR_LS"
    # acados's stage cost is ½|y|²_W times the interval dt, its terminal
    # cost ½|y_e|²_We; ours is the plain sum of squares: W = 2/dt, We = 2
    o.cost.W = (2.0 / dt) * np.eye(am.cost_y_expr.shape[0])
    o.cost.W_e = 2.0 * np.eye(am.cost_y_expr_e.shape[0])
    o.cost.yref = np.zeros(am.cost_y_expr.shape[0])
    o.cost.yref_e = np.zeros(am.cost_y_expr_e.shape[0])
    o.constraints.lbu, o.constraints.ubu = -mm, mm
    o.constraints.idxbu = np.arange(model.nu)
    o.constraints.lbx, o.constraints.ubx = -hm, hm
    o.constraints.idxbx = np.arange(7, model.nx)
    # ours bounds the last state's wheel momenta too
    o.constraints.lbx_e, o.constraints.ubx_e = -hm, hm
    o.constraints.idxbx_e = np.arange(7, model.nx)
    x0 = model.state([1.0, 0.0, 0.0, 0.0])
    o.constraints.x0 = x0
    opts = o.solver_options
    opts.tf = horizon * dt
    opts.qp_solver = qp_solver
    if cond_n is not None:
        opts.qp_solver_cond_N = int(cond_n)
    opts.hessian_approx = "GAUSS_NEWTON"
    opts.integrator_type = "ERK"
    opts.sim_method_num_stages, opts.sim_method_num_steps = 4, 1
    opts.nlp_solver_type = "SQP_RTI" if rti else "SQP"
    # our Gauss–Newton Hessian's Levenberg–Marquardt term, in acados's
    # per-interval scaling
    opts.levenberg_marquardt = 1e-4 / dt
    if not rti:
        opts.nlp_solver_max_iter, opts.tol = 50, 1e-8
    folder = tempfile.mkdtemp(prefix=f"adcs_acados_{horizon}_")
    o.code_export_directory = folder
    t0 = time.perf_counter()
    solver = at.AcadosOcpSolver(o, json_file=os.path.join(folder,
                                                          "ocp.json"),
                                verbose=False)
    build = time.perf_counter() - t0
    size = sum(p.stat().st_size for p in Path(folder).rglob("*.c"))
    for k in range(horizon + 1):
        solver.set(k, "x", x0)
    return solver, {"build_s": build, "c_bytes": size}


def _shift(solver, horizon: int, x) -> None:
    """Our warm start (`ocp.mpc.plan.shift_function`) on acados's iterate.

    The plan moves one interval ahead, its last interval repeated, its
    first state the measured ``x``; acados's RTI would otherwise start
    from the unshifted plan.
    """
    xs = [solver.get(k, "x") for k in range(horizon + 1)]
    us = [solver.get(k, "u") for k in range(horizon)]
    solver.set(0, "x", x)
    for k in range(1, horizon):
        solver.set(k, "x", xs[k + 1])
    for k in range(horizon - 1):
        solver.set(k, "u", us[k + 1])


def lockstep_loop(horizon: int, label: str, qp_solver: str, frac,
                  steps: int = 80) -> dict:
    """acados's RTI closed loop beside our stage-wise RTI (same states)."""
    from benchmarks.peers import _mpc_problem
    from ocp.mpc import AttitudeMPC

    model, qf = _mpc_problem()
    cond_n = None if frac is None else max(1, int(round(frac * horizon)))
    solver, info = acados_ocp_solver(model, qf, horizon, 0.5, True,
                                     qp_solver, cond_n)
    ours = AttitudeMPC(model, horizon=horizon, dt=0.5, rti=True,
                       solver="stagewise")
    rk4 = model.rk4_step(1)
    xk = model.state([1.0, 0.0, 0.0, 0.0])
    times, du = [], 0.0
    for _ in range(steps):
        solver.set(0, "lbx", xk)
        solver.set(0, "ubx", xk)
        solver.solve()
        times.append(float(np.ravel(solver.get_stats("time_tot"))[0]))
        u0 = solver.get(0, "u")
        du = max(du, float(np.abs(u0 - ours.step(xk, qf).u).max()))
        xk = np.array(rk4(xk, u0, np.zeros(3), 0.5)).ravel()
        _shift(solver, horizon, xk)
    return {"label": f"acados SQP_RTI, {label}", "N": horizon,
            "median_ms": 1e3 * statistics.median(times),
            "worst_ms": 1e3 * max(times), "du": du, **info}


def _in_subprocess(fn, *args):
    """Run ``fn(*args)`` in a fresh (spawned) process; its result."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as ex:
        return ex.submit(fn, *args).result()


def run(horizons=(20, 50, 100), steps: int = 80) -> list[dict]:
    """Every acados configuration at every N (one process each)."""
    return [_in_subprocess(lockstep_loop, N, label, qp, frac, steps)
            for N in horizons for label, qp, frac in CONFIGS]


def main(argv=None) -> None:
    """Print acados's rows beside ours (`benchmarks.long_horizon`)."""
    from benchmarks.long_horizon import format_rows, run as ours_run

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizons", default="20,50,100")
    ap.add_argument("--steps", type=int, default=80)
    ap.add_argument("--condensed-max", type=int, default=50)
    args = ap.parse_args(argv)
    horizons = tuple(int(h) for h in args.horizons.split(","))
    ours = ours_run(horizons, args.condensed_max, 3)
    rows = run(horizons, args.steps)
    print(format_rows(ours))
    print("\n| acados (same OCP, same closed loop) | N | median [ms] | "
          "worst [ms] | max |Δu| vs ours [N·m] | build [s] | C [kB] | "
          "our stage-wise median / this |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        mine = next(o for o in ours if o["N"] == r["N"]
                    and o["variant"] == "mpc_sw_rti_step")
        print(f"| {r['label']} | {r['N']} | {r['median_ms']:.3f} | "
              f"{r['worst_ms']:.3f} | {r['du']:.1e} | {r['build_s']:.1f} | "
              f"{r['c_bytes'] / 1e3:.0f} | "
              f"{mine['median_ms'] / r['median_ms']:.2f} |")
    for N in horizons:
        best = min((r for r in rows if r["N"] == N),
                   key=lambda r: r["median_ms"])
        print(f"\nN = {N}: acados's fastest is {best['label']} "
              f"({best['median_ms']:.3f} ms median, {best['worst_ms']:.3f} "
              "ms worst)")


if __name__ == "__main__":
    main()
