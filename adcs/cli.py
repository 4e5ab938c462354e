"""The ``adcs`` command line."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from adcs_common.exceptions import AdcsError


def _report(args: argparse.Namespace) -> int:
    from adcs.report import STUDIES, run_report

    if args.list:
        for key, (_, title) in STUDIES.items():
            print(f"{key:12s} {title}")
        return 0
    studies = None
    if args.studies:
        studies = [s.strip() for s in args.studies.split(",") if s.strip()]
    run_report(args.out, quick=args.quick, studies=studies)
    return 0


def _export(args: argparse.Namespace) -> int:
    from allocation import WheelArray
    from thrusters import six_thruster_unit

    from ocp.codegen.export import export_c, run_driver

    wheels = WheelArray.pyramid(h_max=args.h_max, m_max=args.m_max)
    variants = [v.strip() for v in args.mpc.split(",") if v.strip()]
    print(f"adcs export: generating C in {args.out} ...", flush=True)
    res = export_c(args.out, wheels=wheels, thrusters=six_thruster_unit(),
                   dt=args.dt, horizon=args.horizon, mpc_variants=variants,
                   build=args.build or args.run)
    for p in (res.source, res.header, res.driver, res.makefile,
              res.readme):
        print(f"  wrote {p}")
    if args.run:
        times = run_driver(res)
        print(f"{'function':32s} {'median [us]':>12s} {'max [us]':>12s}")
        for name, t in times.items():
            if name.startswith("_"):
                continue
            print(f"{name:32s} {t['median_us']:12.3f} {t['max_us']:12.3f}")
    return 0


def _bench(args: argparse.Namespace) -> int:
    from adcs.bench import run_bench

    problems = [s.strip() for s in args.problems.split(",") if s.strip()]
    backends = ([s.strip() for s in args.backends.split(",") if s.strip()]
                or None)
    run_bench(args.out, problems=problems, backends=backends,
              repetitions=args.repetitions, quick=args.quick,
              progress=not args.no_progress)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of ``adcs``."""
    parser = argparse.ArgumentParser(
        prog="adcs", description="ADCS optimal-control and allocation "
        "toolbox: design studies, benchmarks, code export.")
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("report", help="run the design studies and write "
                         "an HTML + Markdown report")
    rep.add_argument("--out", default="adcs-report",
                     help="output folder (default ./adcs-report)")
    rep.add_argument("--quick", action="store_true",
                     help="small settings (for CI and a first look)")
    rep.add_argument("--studies", default="",
                     help="comma-separated study keys (default: all); see "
                     "--list")
    rep.add_argument("--list", action="store_true",
                     help="list the studies and exit")
    rep.set_defaults(func=_report)

    exp = sub.add_parser("export", help="generate C code (allocation "
                         "laws, QPs, dynamics, MPC step) with a test "
                         "driver")
    exp.add_argument("--out", default="adcs-c",
                     help="output folder (default ./adcs-c)")
    exp.add_argument("--h-max", type=float, default=0.2,
                     help="wheel momentum bound [N·m·s] (pyramid)")
    exp.add_argument("--m-max", type=float, default=0.05,
                     help="wheel torque bound [N·m] (pyramid)")
    exp.add_argument("--dt", type=float, default=0.5,
                     help="sample time [s]")
    exp.add_argument("--horizon", type=int, default=20,
                     help="MPC horizon (intervals)")
    exp.add_argument("--mpc", default="mpc_step,mpc_rti_step",
                     help="MPC variants to export (comma-separated; "
                     "empty for none)")
    exp.add_argument("--build", action="store_true",
                     help="compile the driver and a shared library (gcc)")
    exp.add_argument("--run", action="store_true",
                     help="build and run the driver, print timings")
    exp.set_defaults(func=_export)

    ben = sub.add_parser("bench", help="time and check every installed "
                         "QP/NLP backend on the allocation and slew "
                         "problems")
    ben.add_argument("--out", default="adcs-bench",
                     help="output folder for JSON and PNG")
    ben.add_argument("--problems", default="wheels,thrusters,slew",
                     help="comma-separated: wheels, thrusters, slew")
    ben.add_argument("--backends", default="",
                     help="comma-separated backend names (default: all "
                     "installed)")
    ben.add_argument("--repetitions", type=int, default=None,
                     help="solves per backend (default 200, 20 quick)")
    ben.add_argument("--quick", action="store_true",
                     help="small settings (CI, a first look)")
    ben.add_argument("--no-progress", action="store_true",
                     help="do not print progress")
    ben.set_defaults(func=_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``adcs`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except AdcsError as exc:
        print(f"adcs: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
