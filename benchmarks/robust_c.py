"""The robust MPC's RTI step in C, beside the nominal step, one run.

Run from the repository root::

    python -m benchmarks.robust_c [--runs 3] [--horizon 20] [--keep-out-deg 20]

Exports, for the demo craft's wheels (dt 0.5 s), the nominal stage-wise
RTI step (`mpc_sw_rti_step`) and the robust RTI step on 9 scenarios (the
nominal inertia and the 8 corners of ±20 % principal inertia,
`ocp.mpc.inertia_corners`) and on 27 ({0.8, 1, 1.2} per principal axis,
`ocp.mpc.scenario_grid`), builds each and runs its driver ``--runs``
times in turn (the driver's closed loop: the 90° slew and hold, RK4 plant
with the nominal inertia). Prints the median of the runs' medians and
their worst step per variant, the ratio to the nominal step, and the
time per scenario.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

import numpy as np

from adcs.robust_mc import slew_keep_out
from allocation import WheelArray
from ocp.codegen.export import export_c, run_driver
from ocp.mpc import inertia_corners, scenario_grid

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
INERTIA = np.diag([3.0, 2.5, 3.5])


def run(horizon: int = 20, runs: int = 3,
        keep_out_deg: float = 0.0) -> list[dict]:
    """Rows: variant label, scenarios, median and worst step [ms]; with
    ``keep_out_deg`` > 0 the nominal and 9-scenario steps again, holding
    a keep-out cone of that half-angle across the slew [deg]."""
    corners = inertia_corners(INERTIA, 0.2)
    cases = [("nominal stage-wise RTI", "mpc_sw_rti_step", 1, None, None),
             ("robust RTI, 9 scenarios", "mpc_robust_rti_step", 9,
              corners, None),
             ("robust RTI, 27 scenarios", "mpc_robust_rti_step", 27,
              scenario_grid(INERTIA, inertia_scale=(0.8, 1.0, 1.2)), None)]
    if keep_out_deg > 0:
        cone = slew_keep_out(np.pi / 2, np.deg2rad(keep_out_deg))
        cases += [(f"nominal stage-wise RTI, {keep_out_deg:g}° keep-out",
                   "mpc_sw_rti_step", 1, None, cone),
                  (f"robust RTI, 9 scenarios, {keep_out_deg:g}° keep-out",
                   "mpc_robust_rti_step", 9, corners, cone)]
    rows = []
    with tempfile.TemporaryDirectory(prefix="adcs_robust_") as tmp:
        built = []
        for i, (label, name, S, scen, cone) in enumerate(cases):
            res = export_c(Path(tmp) / f"{name}_{i}", wheels=WHEELS,
                           inertia=INERTIA, horizon=horizon, build=True,
                           repeats=20, mpc_variants=(name,),
                           mpc_scenarios=scen, mpc_keep_out=cone)
            built.append((label, name, S, res, []))
        for _ in range(runs):
            for label, name, S, res, recs in built:
                recs.append(run_driver(res)[f"closed_loop:{name}"])
        for label, name, S, res, recs in built:
            rows.append({
                "label": label, "S": S,
                "median_ms": 1e-3 * statistics.median(
                    r["median_us"] for r in recs),
                "worst_ms": 1e-3 * statistics.median(
                    r["max_us"] for r in recs),
                "final_deg": recs[0]["final_error_deg"]})
    return rows


def format_rows(rows: list[dict]) -> str:
    """The table (ratios to the nominal row)."""
    base = rows[0]["median_ms"]
    out = ["| C step, horizon 20 | scenarios | median [ms] | worst [ms] | "
           "÷ nominal | median per scenario [ms] | final error [deg] |",
           "|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        out.append(f"| {r['label']} | {r['S']} | {r['median_ms']:.3f} | "
                   f"{r['worst_ms']:.3f} | {r['median_ms'] / base:.1f} | "
                   f"{r['median_ms'] / r['S']:.3f} | "
                   f"{r['final_deg']:.1e} |")
    return "\n".join(out)


def main(argv=None) -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--horizon", type=int, default=20)
    ap.add_argument("--keep-out-deg", type=float, default=0.0,
                    help="also time the nominal and 9-scenario steps "
                    "holding a keep-out cone of this half-angle across the "
                    "slew [deg]")
    args = ap.parse_args(argv)
    print(format_rows(run(args.horizon, args.runs, args.keep_out_deg)))


if __name__ == "__main__":
    main()
