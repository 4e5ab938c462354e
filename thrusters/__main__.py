"""``python -m thrusters``: the burn and reorientation tables beside ours."""

from __future__ import annotations

from .scenarios import burn_scenario, reorientation_scenario
from .tables import (
    burn_table,
    format_table,
    plot_scenario,
    reorientation_table,
)


def main(argv=None) -> None:
    """Print Tables 3 and 5 beside ours; ``--plots DIR`` saves the plots.

    Run as ``python -m thrusters [--allocation law|qp] [--solver NAME]
    [--plots DIR]``.
    """
    import argparse
    from pathlib import Path

    ap = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    ap.add_argument("--allocation", choices=("law", "qp"), default="law")
    ap.add_argument("--solver", default="daqp")
    ap.add_argument("--plots", default=None)
    args = ap.parse_args(argv)
    burn = burn_scenario(allocation=args.allocation, solver=args.solver)
    print(format_table(burn_table(burn),
                       f"[4] Table 3 (burn, {args.allocation})"))
    print()
    reo = reorientation_scenario(allocation=args.allocation,
                                 solver=args.solver)
    print(format_table(reorientation_table(reo),
                       f"[4] Table 5 (reorientation, "
                       f"{args.allocation})"))
    if args.plots:
        out = Path(args.plots)
        out.mkdir(parents=True, exist_ok=True)
        plot_scenario(burn, out / "thrusters_burn.png")
        plot_scenario(reo, out / "thrusters_reorientation.png")


if __name__ == "__main__":
    main()
