"""Exported C on emulated Cortex-M cores: instruction counts and memory.

Run from the repository root: ``python -m benchmarks.embedded [--target
cortex-m7] [--mpc mpc_cond_rti_step] [--precision single]
[--horizon 20] [--qp pqp [--qp-max-iter 8]] [--quick]``; the stage-wise
step with the Riccati active set: ``--mpc mpc_sw_rti_step --qp rqp
[--qp-max-iter 8]``. Exports the demo craft
(`ocp.codegen.export_c`, horizon 20, dt 0.5 s; DAQP's C sources travel
in the export, its workspace static) for the target, cross-compiles it
(arm-none-eabi-gcc -O3, -Wall -Wextra -Werror) and runs the bare-metal
driver on qemu-system-arm (``-icount shift=0``): the figures are
instruction counts (SysTick, one tick per 40 instructions, checked on a
known loop), not cycles. Prints the first call, median, worst and mean
count per function, the closed loop of the MPC step (sized from the
craft: `ocp.codegen.checks`), and the memory table
(`ocp.codegen.memory`). ``--quick``: no MPC step.
``--precision single``: the float export (`ocp.codegen.precision`;
DAQP's float build), e.g. with ``--target cortex-m4f``, whose FPU is
single precision only. ``--qp pqp``: the condensed steps' QP by the
toolbox's primal active set (`ocp.mpc.primal_qp`), ``--qp-max-iter``
its cap (`export_c`'s ``condensed_qp_max_iter``); ``--qp rqp``: the
stage-wise steps' QP by the toolbox's Riccati active set
(`ocp.mpc.riccati_qp`, ``stagewise_qp_plugin``), capped the same way.
"""

from __future__ import annotations

import argparse
import tempfile
import time

from ocp.codegen.export import export_c
from ocp.codegen.memory import format_memory
from ocp.codegen.result import ExportResult
from ocp.codegen.target import format_counts, run_target, toolchain_missing


def target_export(out: str, craft: str, mpc: tuple[str, ...],
                  args: argparse.Namespace) -> ExportResult:
    """Export ``craft``'s ``mpc`` steps into ``out``, built for
    ``args.target`` in ``args.precision``, horizon ``args.horizon`` (dt
    0.5 s), their QP ``args.qp`` (rqp: the stage-wise steps') capped at
    ``args.qp_max_iter``."""
    rqp = args.qp == "rqp"
    return export_c(out, craft, horizon=args.horizon, dt=0.5,
                    mpc_variants=mpc,
                    condensed_qp_plugin=None if rqp else args.qp,
                    condensed_qp_max_iter=None if rqp else args.qp_max_iter,
                    stagewise_qp_plugin="rqp" if rqp else None,
                    stagewise_qp_max_iter=args.qp_max_iter if rqp else None,
                    target=args.target, precision=args.precision,
                    build=True)


def main() -> None:
    """Print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target", default="cortex-m7",
                    choices=("cortex-m7", "cortex-m4f"))
    ap.add_argument("--mpc", default="mpc_cond_rti_step",
                    help="MPC variants (comma-separated; empty for none)")
    ap.add_argument("--precision", default="double",
                    choices=("double", "single"),
                    help="C arithmetic of the export (single: float)")
    ap.add_argument("--horizon", type=int, default=20,
                    help="MPC horizon N of the export (stages)")
    ap.add_argument("--qp", default=None, choices=("daqp", "pqp", "rqp"),
                    help="QP of the condensed steps (default daqp; pqp) "
                    "or of the stage-wise steps (rqp; default their "
                    "interior point)")
    ap.add_argument("--qp-max-iter", type=int, default=None,
                    help="with --qp pqp or rqp: its iteration cap per QP")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    reason = toolchain_missing()
    if reason:
        raise SystemExit(f"benchmarks.embedded: {reason}")
    mpc = () if args.quick else tuple(
        v.strip() for v in args.mpc.split(",") if v.strip())
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        res = target_export(out, "demo", mpc, args)
        t1 = time.perf_counter()
        times = run_target(res, timeout=3600)
        t2 = time.perf_counter()
    stagewise = any("_sw_" in v for v in mpc)
    qp = args.qp or ("interior point" if stagewise else "daqp")
    if args.qp_max_iter:
        qp += f" capped at {args.qp_max_iter}"
    print(f"demo craft, horizon {args.horizon}, {args.target}, "
          f"{args.precision}, {'stage-wise' if stagewise else 'condensed'} "
          f"QP {qp} "
          f"({' '.join(res.extras['memory']['core'])}), -O3; "
          f"export+build {t1 - t0:.0f} s, emulation {t2 - t1:.0f} s")
    print(format_counts(times, args.target))
    print(format_memory(res.extras["memory"], times))


if __name__ == "__main__":
    main()
