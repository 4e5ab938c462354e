"""Worst MPC step of the exported C over a Monte Carlo of closed loops.

Run from the repository root::

    python -m benchmarks.mpc_worst_case [--loops 200] [--steps 120]
                                        [--max-iter 8] [--seed 0]

Exports the condensed MPC steps (`mpc_cond_rti_step`, and
`mpc_cond_step` with at most ``--max-iter`` SQP iterations) for the demo
craft (horizon 20, dt 0.5 s), builds them on the host and flies closed
loops from random attitudes (uniform on the sphere of rotations) and
random body rates (each component uniform in ±0.02 rad/s, wheels at
rest) to the identity, the plant integrated by RK4 in Python. Each call
of the compiled Function is timed (wall time of one buffered call, so a
few µs of Python are in it) and its certificate ``qp_kkt`` kept. Prints
per variant: loops, steps, the median, the 99th percentile and the worst
step after the first of each loop, the worst first (cold) step, the
largest ``qp_kkt``, SQP iterations (largest), and the final errors.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import casadi as ca
import numpy as np
from tqdm.auto import tqdm

from adcs_common.buffers import BoundCall
from adcs_common.quaternion import quat_error_angle
from ocp.codegen.export import export_c
from ocp.models.rigid import rigid_spacecraft
from ocp.spacecraft import load_spacecraft

VARIANTS = ("mpc_cond_rti_step", "mpc_cond_step")


def random_states(model, n: int, rng) -> list[np.ndarray]:
    """``n`` states: uniform random attitudes, rates in ±0.02 rad/s."""
    out = []
    for _ in range(n):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        out.append(model.state(q * np.sign(q[0]),
                               w=rng.uniform(-0.02, 0.02, 3)))
    return out


def fly(f: ca.Function, model, x0: np.ndarray, steps: int,
        dt: float) -> dict:
    """One closed loop of the compiled step ``f``: times and checks."""
    ins = tuple(np.zeros(f.nnz_in(i)) for i in range(f.n_in()))
    outs = tuple(np.zeros(f.nnz_out(i)) for i in range(f.n_out()))
    call = BoundCall(f, ins, outs)
    names = [f.name_out(i) for i in range(f.n_out())]
    kkt_i, it_i = names.index("qp_kkt"), names.index("iterations")
    rk4 = model.rk4_step(1)
    x = x0.copy()
    qf = np.array([1.0, 0.0, 0.0, 0.0])
    z = np.zeros(f.nnz_in(3))
    nx, nu = model.nx, model.nu
    for k in range(21):
        z[k * (nx + nu):k * (nx + nu) + nx] = x
    lx, lg = np.zeros(f.nnz_in(4)), np.zeros(f.nnz_in(5))
    times, kkts, iters = [], [], []
    for _ in range(steps):
        ins[0][:], ins[1][:], ins[2][:] = x, qf, 0.0
        ins[3][:], ins[4][:], ins[5][:] = z, lx, lg
        t0 = time.perf_counter()
        call.trigger()
        times.append(time.perf_counter() - t0)
        kkts.append(float(outs[kkt_i][0]))
        iters.append(float(outs[it_i][0]))
        z, lx, lg = outs[1].copy(), outs[2].copy(), outs[3].copy()
        x = np.asarray(rk4(x, outs[0], np.zeros(3), dt)).ravel()
    return {"times": np.array(times), "kkt": np.array(kkts),
            "iters": np.array(iters),
            "final_error": float(quat_error_angle(x[:4], qf))}


def run(loops: int, steps: int, max_iter: int, seed: int = 0) -> list:
    """Rows ``(variant, summary dict)`` of the Monte Carlo."""
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    rng = np.random.default_rng(seed)
    starts = random_states(model, loops, rng)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        res = export_c(tmp, sc, horizon=20, dt=0.5, mpc_max_iter=max_iter,
                       mpc_variants=VARIANTS, build=True)
        for name in VARIANTS:
            f = ca.external(name, str(res.shared_library))
            runs = [fly(f, model, x0, steps, 0.5) for x0 in tqdm(
                starts, desc=name, disable=None, leave=False)]
            warm = np.concatenate([r["times"][1:] for r in runs])
            rows.append((name, {
                "loops": loops, "steps": loops * steps,
                "median_ms": 1e3 * float(np.median(warm)),
                "p99_ms": 1e3 * float(np.percentile(warm, 99)),
                "worst_ms": 1e3 * float(warm.max()),
                "worst_cold_ms": 1e3 * max(r["times"][0] for r in runs),
                "max_kkt": max(float(r["kkt"].max()) for r in runs),
                "max_iterations": max(float(r["iters"].max())
                                      for r in runs),
                "final_error_max_deg": float(np.rad2deg(max(
                    r["final_error"] for r in runs))),
                "final_error_median_deg": float(np.rad2deg(np.median(
                    [r["final_error"] for r in runs])))}))
    return rows


def format_rows(rows) -> str:
    """The rows of `run` as a Markdown table."""
    out = ["| step | loops × steps | median | p99 | worst after the cold "
           "step | worst cold step | largest qp_kkt | SQP iterations "
           "(max) | final error (median / max) |",
           "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in rows:
        out.append(
            f"| `{name}` | {r['loops']} × {r['steps'] // r['loops']} | "
            f"{r['median_ms']:.3f} ms | {r['p99_ms']:.3f} ms | "
            f"{r['worst_ms']:.3f} ms | {r['worst_cold_ms']:.3f} ms | "
            f"{r['max_kkt']:.1e} | {r['max_iterations']:.0f} | "
            f"{r['final_error_median_deg']:.1e}° / "
            f"{r['final_error_max_deg']:.1e}° |")
    return "\n".join(out)


def main(argv=None) -> None:
    """Print the Monte Carlo table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loops", type=int, default=200)
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--max-iter", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    print(format_rows(run(args.loops, args.steps, args.max_iter,
                          args.seed)))


if __name__ == "__main__":
    main()
