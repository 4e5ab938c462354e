"""The ``adcs`` command line."""

from __future__ import annotations

import argparse
import contextlib
import errno
import math
import os
import sys
import warnings
from typing import Sequence

from adcs.design_cli import add_design
from adcs.provenance import version
from adcs_common.exceptions import AdcsError, InvalidValueError
from adcs_common.interrupts import install_handler, interrupted


def _report(args: argparse.Namespace) -> int:
    from adcs.report import STUDIES, run_report

    if args.list:
        for key, (_, title) in STUDIES.items():
            print(f"{key:12s} {title}")
        return 0
    studies = None
    if args.studies:
        studies = [s.strip() for s in args.studies.split(",") if s.strip()]
    with _dask_client(args, local=args.workers is not None) as client:
        run_report(args.out, quick=args.quick, studies=studies,
                   spacecraft=args.spacecraft, client=client)
    return 0


@contextlib.contextmanager
def _dask_client(args: argparse.Namespace, local: bool):
    """Yield the Dask client of the options, closed afterwards.

    That of ``--scheduler``, or of a local cluster of ``--workers`` when
    ``local``; else None (run in this process).
    """
    if args.scheduler is None and not local:
        yield None
        return
    from .sweep import close, connect

    if args.workers is not None and args.workers < 1:
        raise InvalidValueError(f"--workers must be >= 1, got {args.workers}")
    client, cluster = connect(args.scheduler, workers=args.workers,
                              tls_ca=args.tls_ca, tls_cert=args.tls_cert,
                              tls_key=args.tls_key)
    try:
        yield client
    except BaseException as exc:
        close(client, cluster, quiet=interrupted(exc))
        raise
    close(client, cluster)


def _add_cluster_options(parser: argparse.ArgumentParser,
                         workers_help: str) -> None:
    parser.add_argument("--workers", type=int, default=None,
                        help=workers_help)
    parser.add_argument("--scheduler", default=None,
                        help="address of a running Dask scheduler instead "
                        "of a local cluster (use tls:// and --tls-* off "
                        "this machine)")
    parser.add_argument("--tls-ca", default=None,
                        help="CA certificate file of a TLS scheduler")
    parser.add_argument("--tls-cert", default=None,
                        help="client certificate file (TLS)")
    parser.add_argument("--tls-key", default=None,
                        help="client private key file (TLS)")


def _export(args: argparse.Namespace) -> int:
    from allocation import WheelArray

    from ocp.codegen.checks import DriverCheckError
    from ocp.codegen.export import export_c, run_driver
    from ocp.codegen.target import CORES
    from ocp.mpc.certificate import LONG_HORIZON
    from ocp.spacecraft import load_spacecraft

    sc = load_spacecraft(args.spacecraft)
    if args.h_max is not None or args.m_max is not None:
        w = sc.wheels
        h = w.h_max if args.h_max is None else args.h_max
        m = w.m_max if args.m_max is None else args.m_max
        sc = sc.with_wheels(WheelArray(w.axes, h, m, w.failed, w.names,
                                       w.scale))
    mpc = args.mpc
    if mpc is None and args.stagewise_qp:     # the step it solves
        mpc = "mpc_sw_rti_step"
    if mpc is None:     # single: the condensed RTI step by default
        mpc = ("mpc_cond_rti_step" if args.precision == "single" else
               "mpc_step,mpc_rti_step,mpc_cond_rti_step")
        if args.precision != "single" and args.horizon > LONG_HORIZON:
            # the dense steps' C grows as N^1.2-1.5 and compiles as N^2.5
            mpc = "mpc_sw_step,mpc_sw_rti_step"
    variants = [v.strip() for v in mpc.split(",") if v.strip()]
    print(f"adcs export: generating C for {sc.name!r} in {args.out} ...",
          flush=True)
    res = export_c(args.out, sc, dt=args.dt, horizon=args.horizon,
                   mpc_variants=variants, precision=args.precision,
                   build=args.build or args.run,
                   cc=args.cc, progress=args.build or args.run,
                   target=args.target, loop_steps=args.loop_steps,
                   mpc_move_blocks=args.move_blocks,
                   condensed_qp_plugin=args.condensed_qp,
                   condensed_qp_max_iter=(
                       args.qp_max_iter if args.condensed_qp == "pqp"
                       or not args.stagewise_qp else None),
                   stagewise_qp_plugin=args.stagewise_qp,
                   stagewise_qp_max_iter=(args.qp_max_iter if
                                          args.stagewise_qp else None),
                   mpc_scenarios=_scenarios(args.scenarios, sc))
    for p in (res.source, res.header, res.driver, res.makefile,
              res.makefile.with_name("CMakeLists.txt"), res.readme):
        print(f"  wrote {p}")
    # the folder as the user named it (res.out_dir is resolved)
    shown = res.source.parent
    if (res.out_dir / "daqp" / "api.c").is_file():
        print(f"  wrote {shown / 'daqp'}/ (DAQP's C sources, MIT "
              f"licence; static workspace "
              f"{res.extras['daqp_static_bytes']} bytes)")
    if (res.out_dir / "pqp" / "pqp.c").is_file():
        print(f"  wrote {shown / 'pqp'}/ (the condensed QP's primal "
              "active set and its wrapper, BSD-3-Clause)")
    if (res.out_dir / "rqp" / "rqp.c").is_file():
        print(f"  wrote {shown / 'rqp'}/ (the stage-wise QP's Riccati "
              "active set and its wrapper, BSD-3-Clause)")
    if variants:
        print("  driver's closed loop: "
              + _loop_text(res.extras["closed_loop"]))
    if args.target in CORES:
        return _export_target(args, res)
    if "warnings" in res.extras:
        print(f"  built with {res.extras['built_with']} (-Wall -Wextra): "
              f"{res.extras['warnings']} warnings")
    if args.run and res.extras.get("runner"):
        print(f"  running under {' '.join(res.extras['runner'])}: the "
              "times are the emulator's on this machine, not the board's")
    if args.run:
        try:
            times = run_driver(res)
        except DriverCheckError as exc:     # the table, then the verdict
            times = exc.times
        return _print_driver(times, res.extras.get("closed_loop"))
    return 0


def _scenarios(name: str | None, sc) -> list | None:
    """The robust MPC's scenarios named on the command line (or None)."""
    from ocp.mpc import inertia_corners, scenario_grid

    if name is None:
        return None
    if name == "grid":
        return scenario_grid(sc.inertia, inertia_scale=(0.8, 1.0, 1.2))
    return inertia_corners(sc.inertia, 0.2)


def _loop_text(plan: dict) -> str:
    """The length of the driver's closed loop and where it comes from."""
    from ocp.codegen.checks import LOOP_SLEW_FACTOR

    text = (f"{plan['steps']} steps × {plan['dt']:g} s = "
            f"{plan['seconds']:g} s")
    if plan["slew_time"] == plan["slew_time"]:          # not NaN
        text += (f" (eigenaxis slew {plan['slew_time']:.3g} s; default "
                 f"{LOOP_SLEW_FACTOR:g} times that)")
    tol = math.degrees(plan["final_error_tol"])
    return text + f", passes within {tol:.2g}° of the target"


def _export_target(args: argparse.Namespace, res) -> int:
    """The Cortex-M part of ``adcs export``: files, build, run, tables."""
    from ocp.codegen.checks import DriverCheckError, driver_verdict
    from ocp.codegen.memory import format_memory
    from ocp.codegen.target import format_counts, run_target

    shown = res.source.parent  # the folder as the user named it
    for name in ("startup_cortex_m.c", "cortex_m.ld", "main_cortex_m.c"):
        print(f"  wrote {shown / name}")
    if res.executable is None:
        return 0
    print(f"  built {shown / res.executable.name} (arm-none-eabi-gcc "
          f"-Wall -Wextra -Werror): {res.extras['warnings']} warnings")
    print(f"  wrote {shown / f'memory_{args.target}.json'}")
    if args.run:
        try:
            times = run_target(res)
        except DriverCheckError as exc:     # the tables, then the verdict
            times = exc.times
        plan = res.extras.get("closed_loop")
        table = format_counts(times, args.target, plan).splitlines()
        print("\n".join(table[:-1]))
        print(format_memory(res.extras["memory"], times))
        passed, line = driver_verdict(times, plan)
        print(line)
        return 0 if passed else 1
    return 0


def _print_driver(times: dict, plan: dict | None = None) -> int:
    """Print the driver's timings (first call, median, worst) and the
    verdict of its checks; return the exit status (1: a check failed)."""
    from ocp.codegen.checks import driver_verdict, loop_line

    print(f"{'function':30s} {'first call':>11s} {'median':>10s} "
          f"{'worst':>10s}  [µs]")
    for name, t in times.items():
        if name.startswith("_"):
            continue
        first = t.get("first_us", float("nan"))
        print(f"{name:30s} {first:11.3f} {t['median_us']:10.3f} "
              f"{t['max_us']:10.3f}")
        if "final_error_deg" in t:
            print(f"{'':30s} {loop_line(t)}; worst step after the cold "
                  f"first: {t.get('max_warm_us', float('nan')):.1f} µs")
    passed, line = driver_verdict(times, plan)
    print(line)
    return 0 if passed else 1


def _bench(args: argparse.Namespace) -> int:
    from adcs.bench import run_bench

    problems = [s.strip() for s in args.problems.split(",") if s.strip()]
    backends = ([s.strip() for s in args.backends.split(",") if s.strip()]
                or None)
    run_bench(args.out, problems=problems, backends=backends,
              repetitions=args.repetitions, quick=args.quick,
              progress=not args.no_progress, spacecraft=args.spacecraft,
              budget=args.budget)
    return 0


def _sweep(args: argparse.Namespace) -> int:
    from adcs_common.paths import output_folder

    from .sweep import SWEEPS, SweepCacheWarning, run_sweep
    from .sweep.describe import describe
    from .sweep.plots import plot_sweep

    from ocp.spacecraft import load_spacecraft

    study, make_params, _ = SWEEPS[args.name]
    load_spacecraft(args.spacecraft)          # a bad name fails here
    if args.samples is not None and args.samples < 1:
        raise InvalidValueError(f"--samples must be >= 1, got {args.samples}")
    if args.t_fail is not None and not args.t_fail > 0:
        raise InvalidValueError(f"--t-fail must be > 0 s, got {args.t_fail}")
    if args.name == "robust-basilisk":
        from .basilisk import require_basilisk

        require_basilisk()
    params = make_params(args.quick, samples=args.samples,
                         spacecraft=args.spacecraft, t_fail=args.t_fail,
                         rate_max=args.rate_max,
                         rate_margin=args.rate_margin,
                         tree_products=args.tree_products,
                         keep_out_deg=args.keep_out_deg)
    out = output_folder(args.out, "out")      # once every input passed
    with _dask_client(args, local=not args.sync) as client, \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SweepCacheWarning)
        ds = run_sweep(study, params, client=client, out=out,
                       progress=not args.no_progress)
    for w in caught:          # saved chunks recomputed: one line each
        if issubclass(w.category, SweepCacheWarning):
            print(f"adcs sweep {args.name}: {w.message}")
        else:
            warnings.warn_explicit(w.message, w.category, w.filename,
                                   w.lineno)
    describe(args.name, ds, args.spacecraft if args.name in (
        "agility", "failures", "robust", "robust-basilisk") else None,
        SWEEPS[args.name][2])
    ds.to_netcdf(out / f"{args.name}.nc", engine="scipy")
    plot_sweep(args.name, ds, out / f"{args.name}.png")
    failed = int((ds["error"] != "").sum())
    print(f"adcs sweep {args.name}: {ds.sizes['case']} cases, {failed} "
          f"failed ({ds.attrs['chunks_loaded']} of {ds.attrs['chunks']} "
          f"chunks resumed); wrote {out / (args.name + '.nc')} and "
          f"{out / (args.name + '.png')}")
    return 0


def _spacecraft(args: argparse.Namespace) -> int:
    from ocp.spacecraft import list_spacecraft, spacecraft_toml

    if args.list or args.name is None:
        for name, description in list_spacecraft().items():
            print(f"{name:14s} {description}")
        return 0
    print(spacecraft_toml(args.name), end="")
    return 0


SPACECRAFT_HELP = ("the spacecraft: a built-in name (adcs spacecraft "
                   "--list) or a TOML file")


def _add_sweep(sub) -> None:
    """Add the ``adcs sweep`` subcommand."""
    swp = sub.add_parser("sweep", help="run a design-space sweep or Monte "
                         "Carlo campaign on Dask")
    swp.add_argument("name", choices=("geometry", "accuracy", "agility",
                                      "failures", "robust",
                                      "robust-basilisk"))
    swp.add_argument("--out", default="adcs-sweep",
                     help="output folder (dataset, plot, finished chunks: "
                     "a rerun resumes)")
    swp.add_argument("--quick", action="store_true",
                     help="small settings")
    swp.add_argument("--samples", type=int, default=None,
                     help="Monte Carlo samples (accuracy, default 1e6; "
                     "robust: draws, default 200)")
    swp.add_argument("--rate-max", type=float, default=0.0,
                     help="robust: body-rate bound of both MPCs [rad/s] "
                     "(default 0: none)")
    swp.add_argument("--rate-margin", type=float, default=0.0,
                     help="robust: both MPCs plan the rate bound this "
                     "fraction below it; violations count against the "
                     "bound (default 0)")
    swp.add_argument("--tree-products", type=float, default=0.0,
                     help="robust: the robust MPC's tree also spans these "
                     "products of inertia, ± of the largest moment (17 "
                     "scenarios; default 0: the 9 corners)")
    swp.add_argument("--keep-out-deg", type=float, default=0.0,
                     help="robust: half-angle of a keep-out cone across the "
                     "slew [deg], held by both MPCs and counted (default 0: "
                     "none)")
    swp.add_argument("--spacecraft", default="demo", help=SPACECRAFT_HELP)
    swp.add_argument("--t-fail", type=float, default=None,
                     help="failures: when the wheel fails [s] (default 10, "
                     "5 quick)")
    _add_cluster_options(swp, "local worker processes (default: one per "
                         "core)")
    swp.add_argument("--sync", action="store_true",
                     help="run in this process, in order (debugging)")
    swp.add_argument("--no-progress", action="store_true")
    swp.set_defaults(func=_sweep)


def _add_bench(sub) -> None:
    """Add the ``adcs bench`` subcommand and its options."""
    ben = sub.add_parser("bench", help="time and check every installed "
                         "QP/NLP backend on the allocation and slew "
                         "problems")
    ben.add_argument("--out", default="adcs-bench",
                     help="output folder for JSON and PNG")
    ben.add_argument("--problems", default="wheels,thrusters,slew",
                     help="comma-separated: wheels, thrusters, slew, methods "
                     "(the literature's allocation methods)")
    ben.add_argument("--backends", default="",
                     help="comma-separated backend names (default: all "
                     "installed)")
    ben.add_argument("--repetitions", type=int, default=None,
                     help="solves per backend (default 200, 20 quick)")
    ben.add_argument("--quick", action="store_true",
                     help="small settings (CI, a first look)")
    ben.add_argument("--budget", type=float, default=None,
                     help="seconds each backend may spend on a problem "
                     "before it is marked too slow (default 8, 2 quick)")
    ben.add_argument("--no-progress", action="store_true",
                     help="no progress bar")
    ben.add_argument("--spacecraft", default=None,
                     help=SPACECRAFT_HELP + " (default: the pyramid, the "
                     "six-thruster unit and the demo craft)")
    ben.set_defaults(func=_bench)


def _add_export_qps(exp) -> None:
    """The ``export`` subcommand's options of the MPC steps' QP solvers."""
    exp.add_argument("--condensed-qp", choices=("daqp", "pqp"),
                     default=None,
                     help="QP of the condensed MPC steps: daqp (the "
                     "default) or pqp, the toolbox's primal active set in "
                     "C started where the step starts, with a phase one "
                     "where that start breaks a bound (its sources go to "
                     "pqp/)")
    exp.add_argument("--stagewise-qp", choices=("rqp",), default=None,
                     help="QP of the stage-wise MPC steps (mpc_sw_step, "
                     "mpc_sw_rti_step): their Riccati interior point (the "
                     "default) or rqp, the toolbox's Riccati active set in "
                     "C, memory linear in the horizon (its sources go to "
                     "rqp/)")
    exp.add_argument("--qp-max-iter", type=int, default=None,
                     help="with --condensed-qp pqp or --stagewise-qp rqp: "
                     "its iteration cap per "
                     "QP (default 1000); a capped QP's point keeps every "
                     "bound and lowers the cost, and the step applies it "
                     "(output qp_capped)")


def _add_export(sub) -> None:
    """The ``export`` subcommand's parser."""
    exp = sub.add_parser("export", help="generate C code (allocation "
                         "laws, QPs, dynamics, MPC step) with a test "
                         "driver")
    exp.add_argument("--out", default="adcs-c",
                     help="output folder (default ./adcs-c)")
    exp.add_argument("--spacecraft", default="demo",
                     help=SPACECRAFT_HELP + " (default demo)")
    exp.add_argument("--h-max", type=float, default=None,
                     help="override every wheel's momentum bound [N·m·s]")
    exp.add_argument("--m-max", type=float, default=None,
                     help="override every wheel's torque bound [N·m]")
    exp.add_argument("--dt", type=float, default=0.5,
                     help="sample time [s]")
    exp.add_argument("--horizon", type=int, default=20,
                     help="MPC horizon (intervals)")
    exp.add_argument("--scenarios", choices=("corners", "grid"),
                     default=None,
                     help="robust MPC steps: the nominal craft and the 8 "
                     "corners of ±20 %% principal inertia (corners, 9; the "
                     "default) or {0.8, 1, 1.2} per principal axis (grid, "
                     "27)")
    exp.add_argument("--move-blocks", type=int, default=None,
                     help="stage-wise MPC steps: hold the control over this "
                     "many blocks of stages (move blocking)")
    exp.add_argument("--mpc", default=None,
                     help="MPC variants to export (comma-separated, from "
                     "mpc_step, mpc_rti_step, mpc_cond_step, "
                     "mpc_cond_rti_step, mpc_sw_step, mpc_sw_rti_step "
                     "(stage-wise: for long horizons), mpc_robust_step, "
                     "mpc_robust_rti_step (robust multi-stage, "
                     "--scenarios); empty for none; "
                     "default "
                     "mpc_step,mpc_rti_step,mpc_cond_rti_step; "
                     "mpc_sw_step,mpc_sw_rti_step beyond a horizon of 40; "
                     "mpc_cond_rti_step with --precision single; "
                     "mpc_sw_rti_step with --stagewise-qp)")
    exp.add_argument("--precision", choices=("double", "single"),
                     default="double",
                     help="C arithmetic: single makes casadi_real float "
                     "with float literals and float math (sqrtf, fabsf, "
                     "...; single-precision FPUs such as the Cortex-M4F), "
                     "QP and SQP tolerances chosen for float, DAQP in its "
                     "float build; MPC steps: mpc_cond_rti_step, and "
                     "mpc_sw_rti_step with --stagewise-qp rqp (default "
                     "double)")
    _add_export_qps(exp)
    exp.add_argument("--build", action="store_true",
                     help="compile the driver and a shared library (gcc)")
    exp.add_argument("--run", action="store_true",
                     help="build and run the driver, print timings")
    exp.add_argument("--loop-steps", type=int, default=None,
                     help="steps of the driver's closed loops (default: "
                     "2.5 times the craft's eigenaxis slew time of the "
                     "demo slew); the driver's check fails when a loop "
                     "ends off its target")
    exp.add_argument("--cc", default="gcc",
                     help="C compiler of --build/--run (default gcc)")
    exp.add_argument("--target", default="host",
                     choices=("host", "cortex-m7", "cortex-m4f", "aarch64"),
                     help="where the driver runs: host (--cc); aarch64 "
                     "(a Cortex-A Linux computer: aarch64-linux-gnu-gcc, "
                     "static, --run under qemu-aarch64; its times are the "
                     "emulator's); or a "
                     "Cortex-M7 (double FPU) / Cortex-M4F (single FPU, "
                     "double in software): cross-compiled with "
                     "arm-none-eabi-gcc (-Wall -Wextra -Werror), --run on "
                     "qemu-system-arm (mps2-an500 / mps2-an386, -icount "
                     "shift=0): instruction counts, not cycles, and a "
                     "memory report (memory_<target>.json)")
    exp.set_defaults(func=_export)


class _Parser(argparse.ArgumentParser):
    """argparse with the house rule: a usage mistake is one line, exit 2.

    The line names the command that was mistyped (``adcs report``, not
    ``adcs``) and carries that command's usage on the same line;
    subcommand parsers inherit the class.
    """

    def error(self, message: str):
        """Print ``<prog>: error: <message>; usage: ...`` and exit 2."""
        usage = " ".join(self.format_usage().split())
        self.exit(2, f"{self.prog}: error: {message}; {usage}\n")

    def parse_known_args(self, args=None, namespace=None):
        """As argparse's; stray arguments after a subcommand are its error.

        argparse reports them from the top-level parser, with the
        top-level usage; here the subcommand's parser does.
        """
        argv = list(sys.argv[1:] if args is None else args)
        ns, extras = super().parse_known_args(argv, namespace)
        for action in self._actions:
            if not extras or not isinstance(action,
                                            argparse._SubParsersAction):
                continue
            name = getattr(ns, action.dest, None)
            sub = action.choices.get(name)
            if sub is not None and name in argv and all(
                    x in argv[argv.index(name) + 1:] for x in extras):
                sub.error("unrecognized arguments: " + " ".join(extras))
        return ns, extras


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of ``adcs``."""
    parser = _Parser(
        prog="adcs", description="ADCS optimal-control and allocation "
        "toolbox: design studies, benchmarks, code export.")
    parser.add_argument("--version", action="version",
                        version=f"adcs-toolbox {version()}")
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
    rep.add_argument("--spacecraft", default=None,
                     help=SPACECRAFT_HELP + " (default demo), for the "
                     "studies that apply to any craft")
    _add_cluster_options(rep, "run the heavy studies' cases (Monte Carlo "
                         "blocks, slews against angle) on this many local "
                         "Dask worker processes (default: in this process)")
    rep.set_defaults(func=_report)

    _add_export(sub)

    _add_bench(sub)

    _add_sweep(sub)

    add_design(sub)

    scp = sub.add_parser("spacecraft", help="list the built-in spacecraft "
                         "or print one's TOML")
    scp.add_argument("name", nargs="?", default=None,
                     help="a built-in name or a TOML file to print")
    scp.add_argument("--list", action="store_true",
                     help="list the built-in spacecraft")
    scp.set_defaults(func=_spacecraft)
    return parser


#: errors of writing the output (full disk, closed pipe): a user's
#: redirection, answered with one line and status 2
_OUTPUT_ERRNOS = {errno.ENOSPC, errno.EPIPE, errno.EDQUOT, errno.EFBIG,
                  errno.EIO}


def _drop_stdout() -> None:
    """Point stdout at /dev/null: the exit-time flush must not fail again."""
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``adcs`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    install_handler()
    try:
        code = args.func(args)
        sys.stdout.flush()         # a full disk shows here, not at exit
        return code
    except AdcsError as exc:
        if interrupted(exc):           # a failure the Ctrl-C caused
            print("adcs: interrupted", file=sys.stderr)
            return 130
        print(f"adcs: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        if exc.errno not in _OUTPUT_ERRNOS:
            raise
        print(f"adcs: error: cannot write the output "
              f"({exc.strerror or exc})", file=sys.stderr)
        _drop_stdout()
        return 2
    except (KeyboardInterrupt, RuntimeError) as exc:
        if not interrupted(exc):
            raise
        note = f": {exc}" if isinstance(exc, KeyboardInterrupt) and str(
            exc) else ""
        print(f"adcs: interrupted{note}", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
