"""Closed loops of the condensed step whose QP pqp stops after a cap.

Run from the repository root::

    python -m benchmarks.capped_step [--horizons 10,20] [--caps 5,8,12]
                                     [--draws 20] [--steps 120]

`benchmarks.primal_loops` asked whether a capped primal active set can
fly the loops, on a study of the QP. This flies the step itself, as it
is exported: `AttitudeMPC(..., solver="condensed", rti=True,
qp_solver="pqp", solver_options={"qp_max_iter": cap})`, one real-time
step per sample, from the random starts of `benchmarks.mpc_worst_case`
(demo craft, dt 0.5 s) to the identity, the plant integrated by RK4 in
Python. A capped step applies a point that keeps every bound and lowers
the QP's cost (status ``":qp_capped"``), and the next step starts from
its working set. Prints per horizon and cap, against the uncapped step
in the same run: the share of capped steps, the time after which the
pointing error stays below `SETTLED_DEG` (median, worst, loops that do
not settle within ``--steps``), and the closed loop's cost Σ angle² dt
as a ratio to the uncapped loop's (median, worst).
"""

from __future__ import annotations

import argparse

import numpy as np
from tqdm.auto import tqdm

from adcs_common.quaternion import quat_error_angle
from benchmarks.mpc_worst_case import random_states
from benchmarks.primal_loops import SETTLED_DEG
from ocp.models.rigid import rigid_spacecraft
from ocp.mpc import AttitudeMPC
from ocp.spacecraft import load_spacecraft

DT = 0.5


def fly(mpc: AttitudeMPC, x0: np.ndarray, steps: int) -> dict:
    """One closed loop of ``mpc`` from ``x0`` to the identity."""
    rk4 = mpc.model.rk4_step(1)
    qf, tau = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3)
    mpc.reset()
    x, errors, capped = x0.copy(), [], 0
    for _ in range(steps):
        res = mpc.step(x, qf)
        capped += res.status.endswith(":qp_capped")
        x = np.asarray(rk4(x, res.u, tau, DT)).ravel()
        errors.append(quat_error_angle(x[:4], qf))
    deg = np.rad2deg(errors)
    outside = np.flatnonzero(deg > SETTLED_DEG)
    settled = outside.size == 0 or outside[-1] < steps - 1
    return {"capped": capped, "settled": settled,
            "settle_time": DT * (outside[-1] + 1 if outside.size else 0),
            "cost": float(np.sum(deg ** 2) * DT)}


def run(horizons, caps, draws: int, steps: int) -> list[dict]:
    """Rows per horizon and cap (0: uncapped, the baseline)."""
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    starts = random_states(model, draws, np.random.default_rng(0))
    rows = []
    for N in horizons:
        base = None
        for cap in (0, *caps):
            mpc = AttitudeMPC(model, horizon=N, dt=DT, solver="condensed",
                              rti=True, qp_solver="pqp", solver_options=(
                                  {"qp_max_iter": cap} if cap else {}))
            runs = [fly(mpc, x0, steps) for x0 in tqdm(
                starts, desc=f"N {N} cap {cap or 'none'}", disable=None,
                leave=False)]
            base = base or runs
            ok = [r["settle_time"] for r in runs if r["settled"]]
            ratio = [r["cost"] / b["cost"] for r, b in zip(runs, base)]
            rows.append({
                "horizon": N, "cap": cap, "capped": sum(
                    r["capped"] for r in runs) / (draws * steps),
                "settle_median": float(np.median(ok)) if ok else np.nan,
                "settle_worst": max(ok, default=np.nan),
                "unsettled": sum(not r["settled"] for r in runs),
                "cost_median": float(np.median(ratio)),
                "cost_worst": float(np.max(ratio))})
    return rows


def format_rows(rows: list[dict], draws: int, steps: int) -> str:
    """`run`'s rows as a Markdown table."""
    out = [f"Condensed RTI step with pqp, demo craft, dt {DT} s: {draws} "
           f"loops of {steps} steps from random attitudes and rates "
           f"(seed 0)", "",
           f"| N | QP cap | capped steps | settled within {SETTLED_DEG}°: "
           "median [s] | worst [s] | loops not settled | cost Σ angle² dt "
           "/ uncapped: median | worst |",
           "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        out.append(
            f"| {r['horizon']} | {r['cap'] or 'none'} | "
            f"{100 * r['capped']:.0f} % | {r['settle_median']:.1f} | "
            f"{r['settle_worst']:.1f} | {r['unsettled']} | "
            f"{r['cost_median']:.3f} | {r['cost_worst']:.3f} |")
    return "\n".join(out)


def main(argv=None) -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizons", default="10,20")
    ap.add_argument("--caps", default="5,8,12",
                    help="QP iteration caps (the uncapped step always runs)")
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--steps", type=int, default=120)
    a = ap.parse_args(argv)
    horizons = [int(v) for v in a.horizons.split(",") if v]
    caps = [int(v) for v in a.caps.split(",") if v]
    print(format_rows(run(horizons, caps, a.draws, a.steps), a.draws,
                      a.steps))


if __name__ == "__main__":
    main()
