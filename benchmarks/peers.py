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

* do-mpc (``pip install do-mpc``): the toolbox's MPC problem written
  for do-mpc (`do_mpc_model`: the same dynamics, costs and bounds), in
  the benchmark's closed loop beside the toolbox's MPCs, each command
  compared with the toolbox's IPOPT MPC from the same state.

* acados (``pip install comma-deps-acados``, which ships
  ``acados_template``, HPIPM and BLASFEO): the same problem as an
  acados OCP (`acados_closed_loop`: explicit RK4, nonlinear least
  squares, the same bounds), SQP_RTI and SQP, in the same closed loop.
"""

from __future__ import annotations

import importlib.util
import shutil
import statistics
import tempfile

import numpy as np

from allocation import QPAllocator, WheelArray


def _ours_c(arr: WheelArray) -> dict:
    """Driver medians [µs] of the exported ``wheel_qp`` and ``duty_qp``.

    And the driver's closed loops of ``mpc_rti_step`` (sqpmethod + qrqp),
    ``mpc_cond_rti_step`` and ``mpc_cond_step`` (the condensed SQP, DAQP:
    one iteration per sample, and to convergence) on the MPC
    problem's pyramid (generated RK4 as plant): rows for the MPC table.
    """
    from ocp import export_c, run_driver
    from thrusters import six_thruster_unit

    with tempfile.TemporaryDirectory() as out:
        res = export_c(out, wheels=WheelArray.pyramid(h_max=0.2, m_max=0.05),
                       thrusters=six_thruster_unit(),
                       mpc_variants=("mpc_rti_step", "mpc_cond_rti_step",
                                     "mpc_cond_step"),
                       build=True, repeats=20000)
        t = run_driver(res)
        mpc = []
        for name in ("mpc_rti_step", "mpc_cond_rti_step", "mpc_cond_step"):
            loop = t[f"closed_loop:{name}"]
            mpc.append((f"ours: exported C {name} (driver's loop)",
                        1e-3 * loop["median_us"], 1e-3 * loop["max_us"],
                        float("nan"), loop["final_error_deg"]))
        return {"wheel_qp": t["wheel_qp"]["median_us"],
                "duty_qp": t["duty_qp"]["median_us"], "mpc": mpc}


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


def _mpc_problem():
    """Return the MPC benchmark's model and target."""
    from ocp import quat_from_axis_angle, rigid_spacecraft

    wheels = WheelArray.pyramid(h_max=0.2, m_max=0.05)
    model = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), wheels)
    return model, quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))


def do_mpc_controller(model, qf, step, *, dt: float = 0.5,
                      horizon: int = 20, scales: np.ndarray | None = None):
    """do-mpc's MPC of the toolbox's problem, with the discrete step ``step``.

    The one do-mpc setup of the peers' benchmarks (`do_mpc_model`,
    `benchmarks.peers_robust.do_mpc_robust_model`): stage cost with the
    toolbox's weights (`MPCWeights`: attitude and rate, wheel momentum
    and torque), the terminal factor on the last attitude and rate
    terms, the torque box ``|u_i| <= m_max`` [N·m] and the momentum box
    ``|h_i| <= h_max`` [N·m·s], IPOPT at tol 1e-8. do-mpc adds the
    stage-0 attitude term, a constant (x_0 is fixed).

    Parameters
    ----------
    model : SpacecraftModel
        The wheeled craft (its ``nx``, ``nu`` and wheels).
    qf : array_like (4,)
        Target quaternion (scalar-first).
    step : callable
        ``step(x, u) -> x⁺`` (nominal) or ``step(x, u, s) -> x⁺`` with
        the uncertain parameters ``s`` (``scales`` given); CasADi
        expressions, one interval of ``dt`` [s].
    dt : float
        Sample time [s].
    horizon : int
        Stages N.
    scales : numpy.ndarray (S, k), optional
        Scenarios of the uncertain parameters: a multi-stage MPC with
        robust horizon 1 over them (do-mpc's ``n_robust = 1``; set
        through its parameter template, so any set, not only a Cartesian
        product, can be given). None: the nominal MPC.
    """
    import casadi as ca
    import do_mpc

    from adcs_common.quaternion import quat_conj, quat_mul
    from ocp.mpc import MPCWeights

    w = MPCWeights()
    wh = model.wheels
    m = do_mpc.model.Model("discrete")
    x = m.set_variable("_x", "x", (model.nx, 1))
    u = m.set_variable("_u", "u", (model.nu, 1))
    if scales is None:
        m.set_rhs("x", step(x, u))
    else:
        s = m.set_variable("_p", "s", (np.shape(scales)[1], 1))
        m.set_rhs("x", step(x, u, s))
    qe = quat_mul(quat_conj(qf), x[:4])
    att = w.attitude * ca.sumsqr(qe[1:]) + w.rate * ca.sumsqr(x[4:7])
    m.set_expression("att", att)
    m.set_expression("stage", att + w.momentum * ca.sumsqr(
        x[7:] / ca.DM(wh.h_max)) + w.torque * ca.sumsqr(u / ca.DM(wh.m_max)))
    m.setup()
    mpc = do_mpc.controller.MPC(m)
    mpc.settings.n_horizon = horizon
    mpc.settings.t_step = dt
    if scales is not None:
        mpc.settings.n_robust = 1
    mpc.settings.store_full_solution = False
    mpc.settings.nlpsol_opts = {"ipopt.print_level": 0, "print_time": 0,
                                "ipopt.sb": "yes", "ipopt.tol": 1e-8}
    mpc.set_objective(mterm=w.terminal * m.aux["att"], lterm=m.aux["stage"])
    mpc.set_rterm(u=0.0)
    mpc.bounds["lower", "_u", "u"] = -np.asarray(wh.m_max)
    mpc.bounds["upper", "_u", "u"] = np.asarray(wh.m_max)
    lo = np.full(model.nx, -np.inf)
    hi = np.full(model.nx, np.inf)
    lo[7:], hi[7:] = -np.asarray(wh.h_max), np.asarray(wh.h_max)
    mpc.bounds["lower", "_x", "x"] = lo
    mpc.bounds["upper", "_x", "x"] = hi
    if scales is not None:
        template = mpc.get_p_template(len(scales))
        for i, row in enumerate(scales):
            template["_p", i] = np.asarray(row, float)
        mpc.set_p_fun(lambda _t: template)
    mpc.setup()
    return mpc


def do_mpc_model(model, qf, dt: float = 0.5, horizon: int = 20):
    """Write the toolbox's MPC problem for do-mpc (the same NLP).

    Discrete model by the toolbox's RK4 step; costs and bounds of
    `do_mpc_controller`.
    """
    import casadi as ca

    rk4 = model.rk4_step(1)
    return do_mpc_controller(
        model, qf, lambda x, u: rk4(x, u, ca.DM.zeros(3), dt), dt=dt,
        horizon=horizon)


def mpc_closed_loops(steps: int = 80) -> list[tuple]:
    """Rows (label, median [ms], worst [ms], max |Δu| vs ours, final [deg]).

    One closed loop (90° slew and hold, CVODES plant, dt 0.5 s): do-mpc
    and the toolbox's MPCs. Each step's command is compared with the
    toolbox's IPOPT MPC from the same state.
    """
    import time
    import warnings

    from adcs_common.quaternion import quat_conj, quat_mul
    from ocp.mpc import AttitudeMPC

    model, qf = _mpc_problem()
    F = model.integrator(0.5)
    ref = AttitudeMPC(model, solver="ipopt")
    rows = []
    ctrls = {"ours: AttitudeMPC ipopt": AttitudeMPC(model, solver="ipopt"),
             "ours: AttitudeMPC sqpmethod+qrqp (RTI)":
                 AttitudeMPC(model, solver="sqpmethod", rti=True)}
    if importlib.util.find_spec("do_mpc") is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ctrls["do-mpc 5 (IPOPT, the same NLP)"] = do_mpc_model(model, qf)
    for label, ctl in ctrls.items():
        x = model.state([1.0, 0.0, 0.0, 0.0])
        if hasattr(ctl, "x0"):
            ctl.x0 = x
            ctl.set_initial_guess()
        ref.reset()
        times, du = [], 0.0
        for _ in range(steps):
            t0 = time.perf_counter()
            u = (np.asarray(ctl.make_step(x)).ravel() if hasattr(
                ctl, "make_step") else ctl.step(x, qf).u)
            times.append(time.perf_counter() - t0)
            du = max(du, float(np.abs(u - ref.step(x, qf).u).max()))
            x = np.asarray(F(x0=x, p=np.r_[u, 0, 0, 0])["xf"]).ravel()
        e = quat_mul(quat_conj(qf), x[:4])
        final = np.degrees(2 * np.arctan2(np.linalg.norm(e[1:]), abs(e[0])))
        rows.append((label, 1e3 * statistics.median(times),
                     1e3 * max(times), du, final))
    return rows


def acados_closed_loop(rti: bool = True, steps: int = 80) -> tuple:
    """Row of acados (HPIPM, Gauss–Newton) on the toolbox's MPC problem.

    The same dynamics (explicit RK4, one step per interval), the same
    least-squares costs and weights, the same bounds
    (`benchmarks.peers_acados.acados_ocp_solver`); SQP_RTI or SQP to
    1e-8, in the closed loop of `mpc_closed_loops` (CVODES plant), each
    command compared with the toolbox's IPOPT MPC from the same state.
    """
    import time

    from adcs_common.quaternion import quat_conj, quat_mul
    from benchmarks.peers_acados import acados_ocp_solver
    from ocp.mpc import AttitudeMPC

    model, qf = _mpc_problem()
    solver, _ = acados_ocp_solver(model, qf, 20, 0.5, rti=rti)
    F = model.integrator(0.5)
    ref = AttitudeMPC(model, solver="ipopt")
    xk = model.state([1.0, 0.0, 0.0, 0.0])
    times, du = [], 0.0
    for _ in range(steps):
        solver.set(0, "lbx", xk)
        solver.set(0, "ubx", xk)
        t0 = time.perf_counter()
        solver.solve()
        times.append(time.perf_counter() - t0)
        u0 = solver.get(0, "u")
        du = max(du, float(np.abs(u0 - ref.step(xk, qf).u).max()))
        xk = np.asarray(F(x0=xk, p=np.r_[u0, 0, 0, 0])["xf"]).ravel()
    e = quat_mul(quat_conj(qf), xk[:4])
    final = np.degrees(2 * np.arctan2(np.linalg.norm(e[1:]), abs(e[0])))
    label = "acados SQP_RTI (HPIPM)" if rti else "acados SQP (HPIPM)"
    return (label, 1e3 * statistics.median(times), 1e3 * max(times), du,
            final)


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
    print("\n| MPC closed loop (horizon 20, 90° slew) | median [ms] | worst "
          "[ms] | max |Δu| vs ours [N·m] | final error [deg] | median / "
          "our C condensed RTI |")
    print("|---|---:|---:|---:|---:|---:|")
    rows = mpc_closed_loops() + ours["mpc"]
    if importlib.util.find_spec("acados") is not None:
        rows += [_in_subprocess(acados_closed_loop, True),
                 _in_subprocess(acados_closed_loop, False)]
    else:
        print("acados: not installed (pip install comma-deps-acados): "
              "skipped")
    base = ours["mpc"][1][1]
    for label, med, worst, du, final in rows:
        print(f"| {label} | {med:.3g} | {worst:.3g} | {du:.1e} | "
              f"{final:.1e} | {med / base:.2f} |")
    if importlib.util.find_spec("do_mpc") is None:
        print("do-mpc: not installed (pip install do-mpc): skipped")


if __name__ == "__main__":
    main()
