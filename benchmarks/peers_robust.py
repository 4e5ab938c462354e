"""Robust multi-stage MPC: do-mpc against the toolbox's RobustMPC.

Run from the repository root::

    python -m benchmarks.peers_robust [--steps 20]

The same multi-stage problem on the demo craft (J = diag(3.0, 2.5,
3.5) kg·m², the 0.2 N·m·s / 0.05 N·m pyramid, horizon 20, 0.5 s, the
MPC weights and bounds of `benchmarks.peers.do_mpc_model`): the
uncertain parameters are the three principal-inertia scale factors, the
robust horizon 1 (the tree branches at the first stage; every scenario
shares the first command), equal scenario weights. Two scenario sets:
the nominal craft and the 8 corners of 1 ± 0.2 (9,
`ocp.mpc.inertia_corners`) and {0.8, 1, 1.2}^3 (27, do-mpc's Cartesian
product, `ocp.mpc.scenario_grid`).

do-mpc 5 writes the tree as one NLP and solves it by IPOPT; its model
here is written apart from the toolbox's (its own RK4 of the rigid
craft with the scaled inertia). In one run, per scenario set
(`compare_c`): the toolbox's robust steps are exported to C and built
(``mpc_robust_rti_step``, ``mpc_robust_step``), their C driver runs its
closed loop (generated RK4 plant, no Python: the C step time); do-mpc
flies 20 steps of a 90° slew about (1, 1, 0) from rest (CVODES plant at
the nominal inertia), and at each of its states the exported C steps
are called in this process (``casadi.external``), timed, and compared
with do-mpc's first command and, for the converged step, with its whole
tree (every scenario's states and commands). The toolbox's RobustMPC
RTI in Python flies its own loop for reference. Prints median and worst
step times [ms], do-mpc's median over each (goal of issue #25: ≥ 50×
for the C RTI step), and the agreements.

Run it where do-mpc is installed (``pip install do-mpc``) and a C
compiler is on PATH.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import tempfile
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from benchmarks.peers import _mpc_problem, do_mpc_controller
from ocp.codegen.build import run_driver

SPREAD = 0.2

#: The exported robust steps timed beside do-mpc.
C_VARIANTS = ("mpc_robust_rti_step", "mpc_robust_step")

if TYPE_CHECKING:
    from ocp.codegen.result import ExportResult
    from ocp.mpc import RobustMPC


def scale_sets() -> dict[int, np.ndarray]:
    """``{9: corners, 27: grid}``: scale factors (S, 3), nominal first.

    The factors scale the principal moments in ascending order (as
    `ocp.mpc.inertia_corners` and `scenario_grid` do).
    """
    corners = [(1.0, 1.0, 1.0)] + list(itertools.product(
        (1 - SPREAD, 1 + SPREAD), repeat=3))
    grid = list(itertools.product((1.0, 1 - SPREAD, 1 + SPREAD), repeat=3))
    return {9: np.array(corners), 27: np.array(grid)}


def our_scenarios(model, n: int) -> list:
    """The toolbox's scenarios of the same set (9 or 27)."""
    from ocp.mpc import inertia_corners, scenario_grid

    if n == 9:
        return inertia_corners(model.inertia, SPREAD)
    return scenario_grid(model.inertia,
                         inertia_scale=(1.0, 1 - SPREAD, 1 + SPREAD))


def _rk4_scaled(model, dt: float):
    """``f(x, u, s) -> x⁺``: RK4 of the craft with moments scaled by s.

    Written here (not the toolbox's `param_rk4`): J(s) = V diag(λ s) Vᵀ
    from ``numpy.linalg.eigh(J)``; the wheel equations of theory §3.
    """
    import casadi as ca

    lam, V = np.linalg.eigh(model.inertia)
    A = ca.DM(np.asarray(model.wheels.axes, float))
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    s = ca.SX.sym("s", 3)
    Vd = ca.DM(V)
    J = ca.mtimes([Vd, ca.diag(ca.DM(lam) * s), Vd.T])
    Jinv = ca.mtimes([Vd, ca.diag(1.0 / (ca.DM(lam) * s)), Vd.T])

    def f(z):
        q, w, h = z[:4], z[4:7], z[7:]
        qdot = 0.5 * ca.vertcat(-ca.dot(q[1:], w),
                                q[0] * w + ca.cross(q[1:], w))
        wdot = ca.mtimes(Jinv, -ca.cross(w, ca.mtimes(J, w)
                                          + ca.mtimes(A, h))
                         - ca.mtimes(A, u))
        return ca.vertcat(qdot, wdot, u)

    k1 = f(x)
    k2 = f(x + dt / 2 * k1)
    k3 = f(x + dt / 2 * k2)
    k4 = f(x + dt * k3)
    return ca.Function("rk4_s", [x, u, s],
                       [x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])


def do_mpc_robust_model(model, qf, scales: np.ndarray, dt: float = 0.5,
                        horizon: int = 20):
    """do-mpc's multi-stage MPC over the scale factors ``scales`` (S, 3).

    Robust horizon 1, its own RK4 of the scaled craft (`_rk4_scaled`);
    costs, bounds and the scenario template of
    `benchmarks.peers.do_mpc_controller`.
    """
    return do_mpc_controller(model, qf, _rk4_scaled(model, dt), dt=dt,
                             horizon=horizon, scales=np.asarray(scales))


def _do_mpc_loop(n: int, steps: int) -> dict:
    """do-mpc's loop over set ``n``: step times, Δu to our converged MPC.

    The reference is the toolbox's RobustMPC solved to convergence in
    Python (`compare_c` does the same with the exported C).
    """
    from ocp.mpc import RobustMPC

    model, qf = _mpc_problem()
    F = model.integrator(0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ctl = do_mpc_robust_model(model, qf, scale_sets()[n])
    ref = RobustMPC(model, our_scenarios(model, n), rti=False)
    x = model.state([1.0, 0.0, 0.0, 0.0])
    ctl.x0 = x
    ctl.set_initial_guess()
    times, ref_times, du = [], [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        u = np.asarray(ctl.make_step(x)).ravel()
        times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        du.append(float(np.abs(u - ref.step(x, qf).u).max()))
        ref_times.append(time.perf_counter() - t0)
        x = np.asarray(F(x0=x, p=np.r_[u, 0, 0, 0])["xf"]).ravel()
    return {"times": times, "ref_times": ref_times, "du": du}


def _ours_rti_loop(n: int, steps: int) -> list[float]:
    """The toolbox's RobustMPC (RTI) over its own loop: step times [s]."""
    from ocp.mpc import RobustMPC

    model, qf = _mpc_problem()
    F = model.integrator(0.5)
    mpc = RobustMPC(model, our_scenarios(model, n), rti=True)
    x = model.state([1.0, 0.0, 0.0, 0.0])
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        u = mpc.step(x, qf).u
        times.append(time.perf_counter() - t0)
        x = np.asarray(F(x0=x, p=np.r_[u, 0, 0, 0])["xf"]).ravel()
    return times


def do_mpc_median(scenarios: int = 9, steps: int = 20) -> float:
    """Median per-step time [s] of do-mpc's multi-stage MPC (9 or 27).

    For a table beside other implementations' timings of the same
    problem (the closed loop of this module).
    """
    return statistics.median(_do_mpc_loop(scenarios, steps)["times"])


def export_robust(model: Any, n: int, out: str | Path) -> ExportResult:
    """Export and build ``mpc_robust_rti_step`` and ``mpc_robust_step``.

    Scenario set ``n`` (9 or 27) of ``model``, horizon 20, dt 0.5 s,
    into folder ``out``; the built `ocp.codegen.result.ExportResult`.
    """
    from ocp.codegen.export import export_c

    return export_c(Path(out), wheels=model.wheels, inertia=model.inertia,
                    horizon=20, dt=0.5, build=True, repeats=20,
                    mpc_variants=C_VARIANTS,
                    mpc_scenarios=our_scenarios(model, n))


def c_controller(model: Any, n: int, res: ExportResult,
                 name: str) -> RobustMPC:
    """A RobustMPC over set ``n`` whose step is the exported C ``name``.

    The C function is loaded from the built shared library
    (``casadi.external``) in place of the CasADi step Function it was
    generated from: `RobustMPC.step` then runs the C (shift, SQP step(s)
    and checks) through its bound buffer, and its ``solve_time`` is the
    C call's [s].
    """
    import casadi as ca

    from ocp.mpc import RobustMPC

    mpc = RobustMPC(model, our_scenarios(model, n),
                    rti=name == "mpc_robust_rti_step")
    ext = ca.external(name, str(res.shared_library))
    mpc.step_function = mpc.rti_function = ext
    mpc._rti_buffer = None
    return mpc


def _c_equals_python(res: ExportResult, name: str) -> float:
    """Largest difference of the C ``name`` from its CasADi Function.

    On the export's sample input (the slew's first step, cold).
    """
    import casadi as ca

    args = list(res.samples[name])
    ext = ca.external(name, str(res.shared_library))
    return max(float(np.abs(np.asarray(a) - np.asarray(b)).max())
               for a, b in zip(res.functions[name].call(args),
                               ext.call(args)))


def _plan_difference(ctl: Any, plans: list[np.ndarray], nx: int,
                     nu: int, horizon: int) -> float:
    """Largest |Δ| between do-mpc's tree and our scenario plans.

    ``plans``: our plan per scenario (`RobustMPC.scenario_plans`, the
    layout x_0, u_0, …, x_N), in the order of do-mpc's scenarios
    (branch b of the root uses do-mpc's parameter row b). States and
    commands of every scenario and stage [mixed units: 1, rad/s, N·m·s,
    N·m].
    """
    o, worst = ctl.opt_x_num, 0.0
    for b, P in enumerate(plans):
        for k in range(horizon + 1):
            branch = b if k > 0 else 0
            xk = np.asarray(o["_x", k, branch, -1]).ravel()
            worst = max(worst, float(np.abs(
                P[k * (nx + nu):k * (nx + nu) + nx] - xk).max()))
            if k < horizon:
                uk = np.asarray(o["_u", k, branch]).ravel()
                worst = max(worst, float(np.abs(
                    P[k * (nx + nu) + nx:(k + 1) * (nx + nu)] - uk).max()))
    return worst


def compare_c(n: int, steps: int, out: str | Path) -> dict[str, Any]:
    """do-mpc and our exported C on scenario set ``n``, in one run.

    Exports and builds the two robust C steps (`export_robust`), runs
    their driver (its closed loop with the generated RK4 as plant: the
    C step time with no Python), then flies do-mpc's closed loop
    (`steps` steps of the 90° slew, CVODES plant at the nominal
    inertia); at each of its states the C full-SQP step and the C RTI
    step (warm-started from its own previous plan, one SQP iteration)
    are called in this process (`c_controller`) and timed.

    Returns
    -------
    dict
        ``do_mpc``, ``c_full``, ``c_rti`` (per-step times [s]),
        ``du_full``, ``du_rti`` (per step: max |Δu_0| from do-mpc's
        first command [N·m]), ``plan_full`` (per step: the largest
        difference of the converged C plans of every scenario from
        do-mpc's tree, `_plan_difference`), ``driver`` (the driver's
        ``closed_loop:<name>`` records by C name, times [µs]) and
        ``c_vs_python`` (`_c_equals_python` by C name).
    """
    model, qf = _mpc_problem()
    res = export_robust(model, n, out)
    driver = run_driver(res)
    F = model.integrator(0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ctl = do_mpc_robust_model(model, qf, scale_sets()[n])
    full = c_controller(model, n, res, "mpc_robust_step")
    rti = c_controller(model, n, res, "mpc_robust_rti_step")
    x = model.state([1.0, 0.0, 0.0, 0.0])
    ctl.x0 = x
    ctl.set_initial_guess()
    d: dict = {k: [] for k in ("do_mpc", "c_full", "c_rti", "du_full",
                               "du_rti", "plan_full")}
    for _ in range(steps):
        t0 = time.perf_counter()
        u = np.asarray(ctl.make_step(x)).ravel()
        d["do_mpc"].append(time.perf_counter() - t0)
        a = full.step(x, qf)
        b = rti.step(x, qf)
        d["c_full"].append(a.solve_time)
        d["c_rti"].append(b.solve_time)
        d["du_full"].append(float(np.abs(a.u - u).max()))
        d["du_rti"].append(float(np.abs(b.u - u).max()))
        d["plan_full"].append(_plan_difference(
            ctl, full.scenario_plans(a.plan), model.nx, model.nu, 20))
        x = np.asarray(F(x0=x, p=np.r_[u, 0, 0, 0])["xf"]).ravel()
    d["driver"] = {name: driver[f"closed_loop:{name}"]
                   for name in C_VARIANTS}
    d["c_vs_python"] = {name: _c_equals_python(res, name)
                        for name in C_VARIANTS}
    return d


def rows(steps: int = 20, python: bool = True) -> tuple[list[dict], dict]:
    """The table's rows and the C-equals-Python figures, one run.

    Each row: ``label``, ``S`` (scenarios), ``median_ms``, ``worst_ms``,
    ``ratio`` (do-mpc's median over this row's), ``du_median`` and
    ``du`` (median and max over the steps of |Δu_0|, the largest
    component, from do-mpc's [N·m], NaN where not at do-mpc's states)
    and ``plan``
    (max |Δ| of every scenario's plan, NaN where not compared).
    ``python`` adds the toolbox's RobustMPC RTI in Python (own loop).
    """
    out, agree = [], {}
    nan = float("nan")
    with tempfile.TemporaryDirectory(prefix="adcs_peers_robust_") as tmp:
        for n in (9, 27):
            d = compare_c(n, steps, Path(tmp) / f"robust_{n}")
            base = statistics.median(d["do_mpc"])
            agree[n] = d["c_vs_python"]

            def row(label, t, du=(), plan=nan, med=None, worst=None):
                med = statistics.median(t) if med is None else med
                worst = max(t) if worst is None else worst
                return {"label": label, "S": n, "median_ms": 1e3 * med,
                        "worst_ms": 1e3 * worst, "ratio": base / med,
                        "du_median": statistics.median(du) if du else nan,
                        "du": max(du) if du else nan, "plan": plan}

            out.append(row("do-mpc 5 multi-stage (IPOPT)", d["do_mpc"]))
            out.append(row("ours: C mpc_robust_step (full SQP), at "
                           "do-mpc's states", d["c_full"],
                           d["du_full"], max(d["plan_full"])))
            out.append(row("ours: C mpc_robust_rti_step, at do-mpc's "
                           "states", d["c_rti"], d["du_rti"]))
            for name in C_VARIANTS:
                rec = d["driver"][name]
                out.append(row(f"ours: C {name}, C driver's loop "
                               "(no Python)", [], med=1e-6 * rec["median_us"],
                               worst=1e-6 * rec["max_us"]))
            if python:
                out.append(row("ours: RobustMPC RTI in Python (own loop)",
                               _ours_rti_loop(n, steps)))
    return out, agree


def format_rows(table: list[dict]) -> str:
    """The markdown table of `rows`."""
    def e(v):
        return "–" if not np.isfinite(v) else f"{v:.1e}"

    lines = ["| MPC (horizon 20) | scenarios | median [ms] | worst [ms] "
             "| do-mpc median ÷ median | abs(Δu₀) vs do-mpc, median / max "
             "[N·m] | max abs(Δ plan) vs do-mpc |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for r in table:
        du = (f"{e(r['du_median'])} / {e(r['du'])}"
              if np.isfinite(r["du"]) else "–")
        lines.append(f"| {r['label']} | {r['S']} | {r['median_ms']:.3g} | "
                     f"{r['worst_ms']:.3g} | {r['ratio']:.0f} | {du} | "
                     f"{e(r['plan'])} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20,
                    help="closed-loop steps of do-mpc's loop")
    ap.add_argument("--no-python", action="store_true",
                    help="leave out the Python RTI rows")
    a = ap.parse_args(argv)
    table, agree = rows(a.steps, python=not a.no_python)
    print(f"{a.steps} steps of do-mpc's closed loop (90° slew, horizon 20, "
          "0.5 s, CVODES plant at the nominal inertia); the C steps "
          "called at its states in this process; the C driver's own "
          "closed loop (86 steps, generated RK4 plant) in the same run\n")
    print(format_rows(table))
    for n, d in agree.items():
        print(f"\nC equals Python ({n} scenarios, sample input): "
              + ", ".join(f"{k} {v:.1e}" for k, v in d.items()))


if __name__ == "__main__":
    main()
