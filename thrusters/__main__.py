"""``python -m thrusters``: the burn and reorientation tables beside ours."""

from __future__ import annotations

import sys

from .exceptions import AdcsError
from .scenarios import burn_scenario, reorientation_scenario
from .tables import (
    burn_table,
    format_table,
    plot_scenario,
    reorientation_table,
)


def _parser():
    import argparse

    ap = argparse.ArgumentParser(
        prog="python -m thrusters",
        description="Print Tables 3 and 5 of [4] beside ours (the burn "
        "and the reorientation of the six-thruster unit).")
    ap.add_argument("--allocation", choices=("law", "qp"), default="law",
                    help="duty cycles from the closed-form laws of [4] "
                    "(default) or from the duty-cycle QP")
    ap.add_argument("--solver", default=None,
                    help="QP backend with --allocation qp (default daqp; "
                    "see thrusters.available_solvers())")
    ap.add_argument("--plots", default=None, metavar="DIR",
                    help="also save the scenario plots in DIR")
    return ap


def main(argv=None) -> int:
    """Print Tables 3 and 5 beside ours; ``--plots DIR`` saves the plots.

    Returns the exit status: 0, or 2 after a one-line message for a user
    mistake (an unknown solver, ``--solver`` without ``--allocation qp``,
    an unwritable plot folder).
    """
    from pathlib import Path

    ap = _parser()
    args = ap.parse_args(argv)
    if args.solver is not None and args.allocation != "qp":
        ap.error("--solver needs --allocation qp (the closed-form laws "
                 "use no solver)")
    solver = args.solver or "daqp"
    try:
        burn = burn_scenario(allocation=args.allocation, solver=solver)
        print(format_table(burn_table(burn),
                           f"[4] Table 3 (burn, {args.allocation})"))
        print()
        reo = reorientation_scenario(allocation=args.allocation,
                                     solver=solver)
        print(format_table(reorientation_table(reo),
                           f"[4] Table 5 (reorientation, "
                           f"{args.allocation})"))
        if args.plots:
            out = Path(args.plots)
            try:
                out.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise AdcsError(f"--plots {out}: {exc.strerror}") from exc
            plot_scenario(burn, out / "thrusters_burn.png")
            plot_scenario(reo, out / "thrusters_reorientation.png")
    except AdcsError as exc:
        print(f"python -m thrusters: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("python -m thrusters: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
