"""Closed loops whose QPs a primal active set stopped after a cap solves.

Run from the repository root::

    python -m benchmarks.primal_loops [--spacecraft demo]
                                      [--horizon 20] [--draws 20]
                                      [--steps 120] [--caps 10,20,40,0]

The question `benchmarks.horizon_qps` leaves: a primal active set's
iterates keep every bound, so stopping it bounds the QP; does the closed
loop still reach the target? Each loop flies the demo craft (or
``--spacecraft``, a built-in name or a TOML file; dt 0.5 s)
from the random starts of `benchmarks.mpc_worst_case` in Python: at each
step the condensed step's QP (`qp_factor_function`, at the last plan
moved one stage ahead) solved by `benchmarks.primal_active_set` from
δu = 0 with the last working set moved one stage ahead, at most ``cap``
iterations (0: to the optimum). Where δu = 0 breaks a bound (a loop's
first step, a defect) the QP is solved by DAQP instead and counted. The
new plan is the torques rolled out by RK4 from the measured state (not
the step's linear prediction), so the loops are a study of the capped
QP, not of the exported step. Prints per cap: the steps that hit it,
the DAQP steps, the time after which the pointing error stays below
`SETTLED_DEG`, and the final pointing errors.
"""

from __future__ import annotations

import argparse

import daqp
import numpy as np
from tqdm.auto import tqdm

from adcs_common.quaternion import quat_error_angle
from benchmarks import primal_active_set
from benchmarks.horizon_qps import (add_loop_arguments, study_setup,
                                    du_form, plan_controls, row_scales,
                                    shift_stages, stage_parts,
                                    warm_working_set)
from benchmarks.mpc_worst_case import random_states

#: A loop has settled once its pointing error stays below this [deg].
SETTLED_DEG = 0.1


def fly(horizon: int, x0: np.ndarray, steps: int, cap: int,
        setup: tuple) -> dict:
    """One closed loop; ``cap`` 0 runs each QP to its optimum."""
    sc, model, mpc, qp = setup
    N, nu, nw = horizon, model.nu, sc.wheels.n_wheels
    parts = stage_parts(N, nu, nw, mpc.rate_max is not None)
    scale = row_scales(sc, mpc)
    controls = plan_controls(mpc)
    u_lo, u_hi = (np.tile(b, N) for b in model.control_bounds())
    rk4 = model.rk4_step(1)
    qf, tau = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3)
    x, z = x0.copy(), mpc.initial_guess(x0)
    nz0 = np.zeros(mpc.nz), np.zeros(mpc.ng)
    signs = None
    capped = daqp_steps = 0
    errors = []
    for _ in range(steps):
        z0 = np.array(mpc.shift_function(x, z, *nz0)[0]).ravel()
        winv, rows, g, *bounds = (np.array(v) for v in
                                  qp(z0, np.r_[x, qf, tau]))
        lo = np.r_[bounds[0].ravel(), bounds[2].ravel()]
        hi = np.r_[bounds[1].ravel(), bounds[3].ravel()]
        _, H, C = du_form(winv, rows)
        tol = 1e-9 * scale
        if signs is None or np.any(lo > tol) or np.any(hi < -tol):
            y, _, flag, info = daqp.solve(np.eye(N * nu), winv.T @ g.ravel(),
                                          np.vstack([winv, rows]), hi.copy(),
                                          lo.copy(), np.zeros(len(lo),
                                                              np.int32))
            if flag < 1:
                raise RuntimeError(f"DAQP failed ({flag})")
            du, daqp_steps = winv @ y, daqp_steps + 1
            signs = np.sign(np.array(info["lam"])).astype(int)
        else:
            W = warm_working_set(C, lo, hi, shift_stages(signs, parts),
                                 tol)
            r = primal_active_set.solve(H, g.ravel(), C, lo, hi,
                                        np.zeros(N * nu), W,
                                        max_iter=cap or 10_000)
            du, capped = r["x"], capped + (not r["optimal"])
            signs = np.zeros(len(lo), int)
            for j, side in r["working"].items():
                signs[j] = side
        u = np.clip(z0[controls] + du, u_lo, u_hi).reshape(N, nu)
        z = _rollout(mpc, rk4, x, u, tau)
        x = np.asarray(rk4(x, u[0], tau, 0.5)).ravel()
        errors.append(float(quat_error_angle(x[:4], qf)))
    outside = np.flatnonzero(np.rad2deg(errors) > SETTLED_DEG)
    return {"capped": capped, "daqp": daqp_steps,
            "final_error": errors[-1],
            "settle_time": mpc.dt * (outside[-1] + 1 if outside.size else 0)}


def _rollout(mpc, rk4, x: np.ndarray, u: np.ndarray, tau) -> np.ndarray:
    """The plan of the torques ``u`` (N, n_u) integrated from ``x``."""
    z = np.zeros(mpc.nz)
    z[mpc._xs[0]] = x
    for k, (xs, us) in enumerate(zip(mpc._xs[1:], mpc._us)):
        z[us] = u[k]
        x = np.asarray(rk4(x, u[k], tau, mpc.dt)).ravel()
        z[xs] = x
    return z


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_loop_arguments(ap)
    ap.add_argument("--caps", default="10,20,40,0")
    a = ap.parse_args(argv)
    setup = study_setup(a.horizon, a.spacecraft)
    starts = random_states(setup[1], a.draws, np.random.default_rng(a.seed))
    print("| cap | loops | steps | steps stopped at the cap | DAQP steps "
          f"| settled within {SETTLED_DEG}°, median [s] | worst [s] "
          "| final error, median [deg] | worst [deg] |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for cap in (int(v) for v in a.caps.split(",") if v):
        runs = [fly(a.horizon, x0, a.steps, cap, setup) for x0 in tqdm(
            starts, desc=f"cap {cap}", disable=None, leave=False)]
        err = np.rad2deg([r["final_error"] for r in runs])
        settle = [r["settle_time"] for r in runs]
        print(f"| {cap or 'none'} | {len(runs)} | {len(runs) * a.steps} | "
              f"{sum(r['capped'] for r in runs)} | "
              f"{sum(r['daqp'] for r in runs)} | {np.median(settle):.1f} | "
              f"{max(settle):.1f} | {np.median(err):.1e} | "
              f"{err.max():.1e} |", flush=True)


if __name__ == "__main__":
    main()
