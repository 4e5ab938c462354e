"""Robust against nominal MPC over a Monte Carlo of plants (a benchmark).

Run from the repository root::

    python -m benchmarks.robust_mc [--draws 200] [--workers 2]
                                   [--t-final 50] [--rate-max 0]
                                   [--rate-margin 0] [--basilisk]

Each draw is a plant of the demo craft's uncertainty set (principal
moments ±20 %, products of inertia up to 5 % of the largest moment,
wheel axes tilted within ±0.5°: `adcs.robust_mc.draw_plant`), flown
from rest, a 90° slew about (1, 1, 0) and the hold after it, by the
nominal stage-wise MPC and by `RobustMPC` over the nominal inertia and
its 8 corners (RTI both, horizon 20, 0.5 s). The draws run on a local
Dask cluster (`adcs.sweep`). Prints the counts side by side (loops
broken, bound violations, settled loops), the settling time, final
error, energy and step time of each and robust / nominal: the cost of
robustness, measured in this run. ``--basilisk`` flies the same draws in
Basilisk instead (`adcs.basilisk.robust_mc.run_basilisk_mc`: the drawn
hub and tilted wheels, the MPCs in `AttitudeMPCModule`; needs the
``basilisk`` extra).
"""

from __future__ import annotations

import argparse
import time

from adcs.robust_mc import robust_mc_table, run_robust_mc
from adcs.sweep import close, connect


def run(draws: int = 200, workers: int = 2, t_final: float = 50.0,
        rate_max: float = 0.0, seed: int = 0,
        rate_margin: float = 0.0, basilisk: bool = False,
        tree_products: float = 0.0, keep_out_deg: float = 0.0) -> str:
    """Fly the draws on ``workers`` local workers; the Markdown table."""
    mc = run_robust_mc
    if basilisk:
        from adcs.basilisk.robust_mc import run_basilisk_mc as mc
    client, cluster = connect(workers=workers)
    try:
        t0 = time.perf_counter()
        ds = mc(draws, client=client, progress=True, seed=seed,
                t_final=t_final, rate_max=rate_max, rate_margin=rate_margin,
                tree_products=tree_products, keep_out_deg=keep_out_deg)
        wall = time.perf_counter() - t0
    finally:
        close(client, cluster)
    failed = int((ds["error"] != "").sum())
    head = (("In Basilisk: " if basilisk else "")
            + f"{draws} draws (seed {seed}), {t_final:g} s loops, rate "
            f"bound {'none' if rate_max <= 0 else f'{rate_max:g} rad/s'}"
            + (f" (planned {100 * rate_margin:g} % below it)"
               if rate_max > 0 and rate_margin > 0 else "")
            + (f", the robust tree spanning products ±{tree_products:g}"
               if tree_products > 0 else "")
            + (f", a {keep_out_deg:g}° keep-out cone across the slew"
               if keep_out_deg > 0 else "") + ", "
            f"{workers} workers: {wall:.0f} s wall; {failed} draws "
            "raised outside the loops")
    return head + "\n\n" + robust_mc_table(ds)


def main() -> None:
    """Parse the options, print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--t-final", type=float, default=50.0)
    ap.add_argument("--rate-max", type=float, default=0.0,
                    help="body-rate bound of both MPCs [rad/s] (0: none)")
    ap.add_argument("--rate-margin", type=float, default=0.0,
                    help="both MPCs plan the rate bound this fraction "
                    "below it; violations count against the bound [1]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--basilisk", action="store_true",
                    help="fly the draws in Basilisk")
    ap.add_argument("--tree-products", type=float, default=0.0,
                    help="the robust tree also spans these products of "
                    "inertia, ± of the largest moment (17 scenarios)")
    ap.add_argument("--keep-out-deg", type=float, default=0.0,
                    help="half-angle of a keep-out cone across the slew, "
                    "held by both MPCs [deg] (0: none)")
    a = ap.parse_args()
    print(run(a.draws, a.workers, a.t_final, a.rate_max, a.seed,
              a.rate_margin, a.basilisk, a.tree_products, a.keep_out_deg))


if __name__ == "__main__":
    main()
