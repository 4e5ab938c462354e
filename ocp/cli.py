"""The ``adcs`` command line."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from adcs_common.exceptions import AdcsError


def _report(args: argparse.Namespace) -> int:
    from .report import STUDIES, run_report

    if args.list:
        for key, (_, title) in STUDIES.items():
            print(f"{key:12s} {title}")
        return 0
    studies = None
    if args.studies:
        studies = [s.strip() for s in args.studies.split(",") if s.strip()]
    run_report(args.out, quick=args.quick, studies=studies)
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
