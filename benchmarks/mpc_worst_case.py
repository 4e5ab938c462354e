"""Worst MPC step of the exported C over a Monte Carlo of closed loops.

Run from the repository root::

    python -m benchmarks.mpc_worst_case [--loops 200] [--steps 120]
                                        [--max-iter 8] [--seed 0]
                                        [--horizon 20] [--qp pqp]
                                        [--qp-max-iter 5]
    python -m benchmarks.mpc_worst_case --target cortex-m7
                                        [--draws-on-target 20]

Exports the condensed MPC steps (`mpc_cond_rti_step`, and
`mpc_cond_step` with at most ``--max-iter`` SQP iterations) for the demo
craft (horizon 20 or ``--horizon``, dt 0.5 s), builds them on the host
and flies closed loops from random attitudes (uniform on the sphere of
rotations) and
random body rates (each component uniform in ±0.02 rad/s, wheels at
rest) to the identity, the plant integrated by RK4 in Python. Each call
of the compiled Function is timed (wall time of one buffered call, so a
few µs of Python are in it) and its certificate ``qp_kkt`` kept. Prints
per variant: loops, steps, the median, the 99th percentile and the worst
step after the first of each loop, the worst first (cold) step, the
largest ``qp_kkt``, SQP iterations (largest), and the final errors.

``--target cortex-m7`` (or ``cortex-m4f``) flies the first
``--draws-on-target`` of those draws (same seed, so the same states) with
`mpc_cond_rti_step` (with ``--qp rqp``: the stage-wise
`mpc_sw_rti_step` with the Riccati active set, and on the host the
stage-wise steps) on the emulated core instead
(`ocp.codegen.loop_starts`: the bare-metal driver flies one closed loop
per start, the generated RK4 as plant, counting instructions per step on
qemu ``-icount``), and the same starts with the host's C driver and the
host benchmark's Python loop: per loop, the median, 99th percentile and
worst step after the cold one, the cold step, the final error, the
largest applied-step violation (scaled: torque over m_max, momentum over
h_max), and the largest difference between the target's final state and
the host driver's.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np
from tqdm.auto import tqdm

from adcs_common.buffers import BoundCall
from adcs_common.quaternion import quat_error_angle
from ocp.codegen.export import export_c
from ocp.models.rigid import rigid_spacecraft
from ocp.spacecraft import load_spacecraft

VARIANTS = ("mpc_cond_rti_step", "mpc_cond_step")
#: The stage-wise steps, flown with ``--qp rqp``.
SW_VARIANTS = ("mpc_sw_rti_step", "mpc_sw_step")


def qp_export(qp: str | None, qp_max_iter: int | None) -> dict:
    """`export_c`'s QP arguments for ``--qp``: the condensed steps' QP
    (daqp, pqp) and its cap, or with ``"rqp"`` the stage-wise steps'."""
    if qp == "rqp":
        return {"stagewise_qp_plugin": "rqp",
                "stagewise_qp_max_iter": qp_max_iter}
    return {"condensed_qp_plugin": qp, "condensed_qp_max_iter": qp_max_iter}


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
    v_i = names.index("first_violation")
    cap_i = names.index("qp_capped") if "qp_capped" in names else None
    rk4 = model.rk4_step(1)
    x = x0.copy()
    qf = np.array([1.0, 0.0, 0.0, 0.0])
    z = np.zeros(f.nnz_in(3))
    nx, nu = model.nx, model.nu
    for k in range((z.size - nx) // (nx + nu) + 1):
        z[k * (nx + nu):k * (nx + nu) + nx] = x
    lx, lg = np.zeros(f.nnz_in(4)), np.zeros(f.nnz_in(5))
    times, kkts, iters, viols, capped = [], [], [], [], 0
    for _ in range(steps):
        ins[0][:], ins[1][:], ins[2][:] = x, qf, 0.0
        ins[3][:], ins[4][:], ins[5][:] = z, lx, lg
        t0 = time.perf_counter()
        call.trigger()
        times.append(time.perf_counter() - t0)
        kkts.append(float(outs[kkt_i][0]))
        iters.append(float(outs[it_i][0]))
        viols.append(float(outs[v_i][0]))
        capped += cap_i is not None and bool(outs[cap_i][0] > 0)
        z, lx, lg = outs[1].copy(), outs[2].copy(), outs[3].copy()
        x = np.asarray(rk4(x, outs[0], np.zeros(3), dt)).ravel()
    return {"times": np.array(times), "kkt": np.array(kkts),
            "iters": np.array(iters), "violation": max(viols),
            "capped": capped,
            "final_error": float(quat_error_angle(x[:4], qf))}


def run(loops: int, steps: int, max_iter: int, seed: int = 0,
        horizon: int = 20, qp: str | None = None,
        qp_max_iter: int | None = None) -> list:
    """Rows ``(variant, summary dict)`` of the Monte Carlo (``qp``: the
    condensed QP, `export_c`'s ``condensed_qp_plugin``; ``qp_max_iter``
    its ``condensed_qp_max_iter``, pqp's cap)."""
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    rng = np.random.default_rng(seed)
    starts = random_states(model, loops, rng)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        variants = SW_VARIANTS if qp == "rqp" else VARIANTS
        res = export_c(tmp, sc, horizon=horizon, dt=0.5,
                       mpc_max_iter=max_iter, mpc_variants=variants,
                       build=True, **qp_export(qp, qp_max_iter))
        for name in variants:
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
                "capped": sum(r["capped"] for r in runs),
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
    capped = {name: r["capped"] for name, r in rows if r["capped"]}
    if capped:
        out += ["", "Steps whose last QP was capped (pqp, a feasible "
                "descent point): " + ", ".join(f"`{k}` {v}" for k, v in
                                               capped.items())]
    return "\n".join(out)


def _loop_figures(steps: np.ndarray) -> dict:
    """Median, p99, worst after the cold step and cold step of one loop's
    per-step figures (any unit)."""
    warm = steps[1:]
    return {"median": float(np.median(warm)),
            "p99": float(np.percentile(warm, 99)),
            "worst": float(warm.max()), "cold": float(steps[0])}


def pool_loops(loops: list) -> dict:
    """Figures of every loop's steps pooled: ``median``, ``p99`` and
    ``worst`` of the steps after each loop's cold first one,
    ``worst_cold`` the worst of the first steps (any unit)."""
    fig = _loop_figures(np.concatenate(
        [[max(r[0] for r in loops)]] + [np.asarray(r[1:]) for r in loops]))
    fig["worst_cold"] = fig.pop("cold")
    return fig


def run_target_draws(draws: int, steps: int, seed: int = 0,
                     target: str = "cortex-m7",
                     name: str = "mpc_cond_rti_step",
                     precision: str = "double",
                     horizon: int = 20, qp: str | None = None,
                     qp_max_iter: int | None = None) -> dict:
    """The first ``draws`` states of `run`'s Monte Carlo flown by ``name``
    on the emulated ``target`` and on the host.

    One export of the demo craft (``horizon``, dt 0.5 s) for ``target``,
    its drivers rewritten to fly a loop per start to the identity
    (`ocp.codegen.loop_starts.write_loop_starts`); the ELF run on qemu
    (instructions per step), the host driver built from the same folder
    (µs per step, ``clock_gettime``) and its shared library flown by
    `fly` (the host benchmark's Python loop).

    Returns
    -------
    dict
        ``loops``: one dict per start (``angle_deg`` of the start from the
        target, ``rate`` [rad/s] norm of its body rate, ``target`` and
        ``host`` `_loop_figures` [instructions, µs], ``final_error_deg``
        and ``violation`` on the target, ``host_final_error_deg``,
        ``python_final_error_deg``, ``state_diff`` max |x_target −
        x_host| of the final states, ``target_steps`` and
        ``host_steps_us`` every step's figure in step order); ``all``: `_loop_figures` of every
        target step pooled (``worst_cold``: the worst cold step),
        ``host_all`` the same in µs; ``seconds``: build and emulation
        wall times [s]; ``ok``: every loop passed the driver's check.
    ``precision`` "single" exports the target's (and its host driver's)
    C in float (`--precision single`); the Python loop stays double.
    ``qp``: the condensed QP (`export_c`'s ``condensed_qp_plugin``),
    ``qp_max_iter`` its cap (``condensed_qp_max_iter``); ``capped``
    counts the Python loop's capped steps.
    """
    from ocp.codegen.build import build_exported, run_driver
    from ocp.codegen.loop_starts import loop_key, write_loop_starts
    from ocp.codegen.target import build_target, run_target

    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    starts = np.array(random_states(model, draws,
                                    np.random.default_rng(seed)))
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = export_c(tmp, sc, horizon=horizon, dt=0.5,
                       mpc_variants=(name,), target=target, repeats=10,
                       precision=precision, **qp_export(qp, qp_max_iter))
        res = write_loop_starts(res, starts, steps=steps)
        elf = build_target(res)
        t1 = time.perf_counter()
        emu = run_target(elf, timeout=3600, check=False)
        t2 = time.perf_counter()
        host_res = build_exported(res)
        host = run_driver(host_res, timeout=600, check=False)
        # the Python loop loads a host export: a Cortex-M export's
        # casadi_int is int, which casadi.external cannot load
        lib = export_c(Path(tmp) / "host", sc, horizon=horizon, dt=0.5,
                       mpc_variants=(name,), build=True,
                       **qp_export(qp, qp_max_iter)).shared_library
        f = ca.external(name, str(lib))
        py = [fly(f, model, x0, steps, 0.5) for x0 in starts]
    loops = []
    for k, x0 in enumerate(starts):
        t, h = emu[loop_key(name, k)], host[loop_key(name, k)]
        loops.append({
            "angle_deg": float(np.rad2deg(quat_error_angle(
                x0[:4], np.array([1.0, 0.0, 0.0, 0.0])))),
            "rate": float(np.linalg.norm(x0[4:7])),
            "target": _loop_figures(np.array(t["steps"])),
            "host": _loop_figures(np.array(h["steps_us"])),
            "target_steps": list(t["steps"]),
            "host_steps_us": np.asarray(h["steps_us"]).tolist(),
            "final_error_deg": t["loop_final_error_deg"],
            "violation": t["loop_worst_violation"],
            "ok": bool(t["loop_ok"]) and bool(h["loop_ok"]),
            "host_final_error_deg": h["loop_final_error_deg"],
            "python_final_error_deg": float(np.rad2deg(
                py[k]["final_error"])),
            "python_violation": py[k]["violation"],
            "state_diff": float(np.abs(np.array(t["state"])
                                       - h["state"]).max())})
    pooled = {key: pool_loops([src[loop_key(name, k)][unit]
                               for k in range(draws)])
              for key, src, unit in (("all", emu, "steps"),
                                     ("host_all", host, "steps_us"))}
    return {"target": target, "name": name, "draws": draws,
            "horizon": horizon,
            "precision": precision,
            "steps": steps, "seed": seed, "loops": loops, **pooled,
            "qp": qp or "daqp", "qp_max_iter": qp_max_iter,
            "capped": sum(r["capped"] for r in py),
            "ok": all(r["ok"] for r in loops),
            "seconds": {"build": t1 - t0, "emulation": t2 - t1}}


def format_target(out: dict, rows_max: int = 20) -> str:
    """`run_target_draws`'s figures as a Markdown table: one row per loop
    (the first ``rows_max``), then every step of every loop pooled
    (instructions on the target, µs on the host) and the draws of the
    worst steps."""
    rows = [f"`{out['name']}` on the emulated {out['target']} "
            f"in {out.get('precision', 'double')} precision, horizon "
            f"{out.get('horizon', 20)} "
            f"(instructions per step, qemu -icount) and on the host (C "
            f"driver, µs): draws 0–{out['draws'] - 1} of seed "
            f"{out['seed']}, {out['steps']} steps of 0.5 s each; build "
            f"{out['seconds']['build']:.0f} s, emulation "
            f"{out['seconds']['emulation']:.0f} s",
            "",
            r"| draw | start: angle, \|ω\| | median | p99 | worst after "
            "the cold step | cold step | final error | largest violation "
            "| host median / worst / cold [µs] | host final error (C / "
            r"Python) | max \|Δx\| target − host |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for k, r in enumerate(out["loops"][:rows_max]):
        t, h = r["target"], r["host"]
        rows.append(
            f"| {k} | {r['angle_deg']:.0f}°, {r['rate']:.3f} rad/s | "
            f"{t['median']:,.0f} | {t['p99']:,.0f} | {t['worst']:,.0f} | "
            f"{t['cold']:,.0f} | {r['final_error_deg']:.1e}°"
            f"{'' if r['ok'] else ' (check failed)'} | "
            f"{r['violation']:.1e} | {h['median']:.0f} / {h['worst']:.0f}"
            f" / {h['cold']:.0f} | {r['host_final_error_deg']:.1e}° / "
            f"{r['python_final_error_deg']:.1e}° | {r['state_diff']:.1e} |")
    a, h = out["all"], out["host_all"]
    errs = [r["final_error_deg"] for r in out["loops"]]
    rows.append(
        f"| all {out['draws']} | | **{a['median']:,.0f}** | "
        f"{a['p99']:,.0f} | **{a['worst']:,.0f}** | "
        f"**{a['worst_cold']:,.0f}** | ≤ {max(errs):.1e}° | "
        f"≤ {max(r['violation'] for r in out['loops']):.1e} | "
        f"{h['median']:.0f} / {h['worst']:.0f} / {h['worst_cold']:.0f} | "
        f"| ≤ {max(r['state_diff'] for r in out['loops']):.1e} |")
    worst = max(range(out["draws"]),
                key=lambda k: out["loops"][k]["target"]["worst"])
    cold = max(range(out["draws"]),
               key=lambda k: out["loops"][k]["target"]["cold"])
    failed = [k for k, r in enumerate(out["loops"]) if not r["ok"]]
    rows += ["", f"Worst step after the cold one: draw {worst}; worst "
             f"cold step: draw {cold}; loops failing the driver's check: "
             f"{failed or 'none'}; p99: interpolated (numpy's default)."]
    if out.get("qp_max_iter"):
        rows.append(f"QP: {out['qp']} capped at {out['qp_max_iter']} "
                    f"iterations; capped steps in the Python loop: "
                    f"{out['capped']} of {out['draws'] * out['steps']}.")
    return "\n".join(rows)


def main(argv=None) -> None:
    """Print the Monte Carlo table (``--target``: the target's)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loops", type=int, default=200)
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--max-iter", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--horizon", type=int, default=20,
                    help="MPC horizon N of the export (stages)")
    ap.add_argument("--target", default="host",
                    choices=("host", "cortex-m7", "cortex-m4f"))
    ap.add_argument("--draws-on-target", type=int, default=20,
                    help="first draws flown on the target (--target)")
    ap.add_argument("--precision", default="double",
                    choices=("double", "single"),
                    help="the target export's arithmetic (single: float, "
                    "on the cortex-m4f); the Python loop stays double")
    ap.add_argument("--qp", default=None, choices=("daqp", "pqp", "rqp"),
                    help="the condensed steps' QP (default daqp; pqp: the "
                    "toolbox's primal active set, ocp.mpc.primal_qp), or "
                    "rqp: the stage-wise steps with the Riccati active "
                    "set (ocp.mpc.riccati_qp)")
    ap.add_argument("--qp-max-iter", type=int, default=None,
                    help="with --qp pqp or rqp: its iteration cap per QP "
                    "(default 1000); capped steps are counted")
    ap.add_argument("--json", default=None,
                    help="write --target's figures, every step's, here")
    args = ap.parse_args(argv)
    if args.target == "host":
        print(format_rows(run(args.loops, args.steps, args.max_iter,
                              args.seed, args.horizon, args.qp,
                              args.qp_max_iter)))
        return
    from ocp.codegen.target import toolchain_missing

    if (reason := toolchain_missing()) is not None:
        raise SystemExit(f"benchmarks.mpc_worst_case: {reason}")
    out = run_target_draws(args.draws_on_target, args.steps, args.seed,
                           args.target, name=SW_VARIANTS[0] if args.qp ==
                           "rqp" else "mpc_cond_rti_step",
                           precision=args.precision,
                           horizon=args.horizon, qp=args.qp,
                           qp_max_iter=args.qp_max_iter)
    print(format_target(out))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
