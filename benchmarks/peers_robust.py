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
craft with the scaled inertia). Each flies a short closed loop (a 90°
slew about (1, 1, 0) from rest, CVODES plant at the nominal inertia) and
its step is timed; at each of do-mpc's states the toolbox's RobustMPC
solved to convergence (full SQP) gives the first command it is compared
with. The toolbox's RobustMPC in RTI (one SQP step, as deployed) flies
its own loop, timed. Prints median and worst step times [ms] and the
largest first-command difference [N·m].
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time
import warnings

import numpy as np

from benchmarks.peers import _mpc_problem, do_mpc_controller

SPREAD = 0.2


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
    """do-mpc's loop over set ``n``: step times, Δu to our converged MPC."""
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


def rows(steps: int = 20) -> list[tuple]:
    """(label, scenarios, median [ms], worst [ms], max |Δu| [N·m])."""
    out = []
    for n in (9, 27):
        d = _do_mpc_loop(n, steps)
        out.append(("do-mpc 5 multi-stage (IPOPT)", n,
                    1e3 * statistics.median(d["times"]),
                    1e3 * max(d["times"]), max(d["du"])))
        out.append(("ours: RobustMPC, full SQP (Python)", n,
                    1e3 * statistics.median(d["ref_times"]),
                    1e3 * max(d["ref_times"]), 0.0))
        t = _ours_rti_loop(n, steps)
        out.append(("ours: RobustMPC, RTI (Python)", n,
                    1e3 * statistics.median(t), 1e3 * max(t),
                    float("nan")))
    return out


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20,
                    help="closed-loop steps timed per controller")
    a = ap.parse_args()
    print(f"{a.steps} closed-loop steps each (90° slew, horizon 20, "
          "0.5 s); Δu: do-mpc's first command against the full-SQP "
          "RobustMPC's from the same state\n")
    print("| MPC | scenarios | median [ms] | worst [ms] | max abs(Δu) "
          "[N·m] |")
    print("|---|---|---|---|---|")
    for label, n, med, worst, du in rows(a.steps):
        dus = "–" if not np.isfinite(du) or du == 0.0 else f"{du:.1e}"
        if label.startswith("ours: RobustMPC, full"):
            dus = "reference"
        print(f"| {label} | {n} | {med:.1f} | {worst:.1f} | {dus} |")


if __name__ == "__main__":
    main()
