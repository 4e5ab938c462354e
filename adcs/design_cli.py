"""``adcs design``: choose the wheel array, print it, write it as a craft."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from adcs_common.exceptions import InvalidValueError


def design_json(d, units: str) -> dict:
    """The fields of an `allocation.ArrayDesign` as JSON-ready values.

    Axes are one row per wheel (wheel 1 first), angles in radians.
    """
    return {
        "radius": d.radius,
        "worst_failure_radius": d.worst_failure_radius,
        "objective": d.objective,
        "units": units,
        "axes": d.axes.T.tolist(),
        "capacity": d.capacity.tolist(),
        "quantity": d.quantity,
        "family": d.family,
        "params": d.params.tolist(),
        "failures": d.failures,
        "nominal_weight": d.nominal_weight,
        "starts": int(d.start_objectives.size),
        "reached": d.reached,
        "time_per_start_s": float(np.median(d.start_times)),
    }


def _print_design(d, units: str) -> None:
    k = max(d.failures, 1)
    print(f"adcs design: {d.axes.shape[1]} wheels, family {d.family}, "
          f"{d.quantity} envelope, {d.start_objectives.size} starts "
          f"({d.reached:.0%} reached the best)")
    print(f"  inscribed radius, nominal:          {d.radius:.6f} {units}")
    print(f"  worst radius, any {k} wheel(s) failed: "
          f"{d.worst_failure_radius:.6f} {units}")
    print(f"  {'wheel':>5s} {'x':>10s} {'y':>10s} {'z':>10s} "
          f"{'capacity':>10s}")
    for i, (a, c) in enumerate(zip(d.axes.T, d.capacity)):
        print(f"  {i + 1:5d} {a[0]:10.6f} {a[1]:10.6f} {a[2]:10.6f} "
              f"{c:10.6g}")


def run_design(args: argparse.Namespace) -> int:
    """Run ``adcs design`` from parsed arguments; exit status 0."""
    from allocation import design_array
    from allocation.envelope import UNITS

    from ocp.spacecraft import Spacecraft, load_spacecraft

    base = load_spacecraft(args.spacecraft) if args.out else None
    if args.out and not Path(args.out).parent.is_dir():
        raise InvalidValueError(f"--out {args.out}: its folder does not "
                                "exist")
    capacity = args.h_max if args.quantity == "momentum" else args.m_max
    if not capacity > 0 or not np.isfinite(capacity):
        raise InvalidValueError(f"--h-max and --m-max must be positive, "
                                f"got {capacity}")
    d = design_array(args.wheels, failures=args.failures,
                     family=args.family, quantity=args.quantity,
                     nominal_weight=args.nominal_weight,
                     capacity=capacity, budget=args.budget,
                     starts=args.starts, seed=args.seed)
    units = UNITS[args.quantity]
    if args.json:
        print(json.dumps(design_json(d, units), indent=1))
    else:
        _print_design(d, units)
    if args.out:
        assert base is not None        # loaded when --out is given
        scale = d.capacity / capacity       # 1 unless a budget sized them
        wheels = d.wheel_array(h_max=args.h_max * scale,
                               m_max=args.m_max * scale)
        craft = Spacecraft(
            name=f"{base.name}-{args.wheels}-wheel-design",
            inertia=base.inertia, wheels=wheels,
            thrusters=base.thrusters, rate_max=base.rate_max,
            description=f"{base.name} with the {args.wheels}-wheel array "
            f"of adcs design (radius {d.radius:.6g} {units})")
        craft.save(args.out)
        if not args.json:
            print(f"  wrote {args.out}")
    return 0


def add_design(sub) -> None:
    """Add the ``adcs design`` subcommand."""
    from allocation import FAMILIES

    des = sub.add_parser("design", help="choose the wheel array (axes, "
                         "optionally sizes) with the largest worst-case "
                         "envelope, nominal or after failures")
    des.add_argument("--wheels", type=int, required=True,
                     help="number of wheels N (3 to 12)")
    des.add_argument("--failures", type=int, default=0,
                     help="maximise the worst radius over every K-wheel "
                     "failure (default 0: the nominal radius)")
    des.add_argument("--quantity", choices=("momentum", "torque"),
                     default="momentum", help="the envelope maximised")
    des.add_argument("--family", choices=sorted(FAMILIES), default="free",
                     help="layout family: " + "; ".join(
                         f"{k}: {v[1]}" for k, v in FAMILIES.items()))
    des.add_argument("--nominal-weight", type=float, default=0.0,
                     help="with --failures: weight w of the nominal radius "
                     "in (1 - w) r_fail + w r_nom (default 0)")
    des.add_argument("--budget", type=float, default=None,
                     help="size the wheels too: total capacity of the "
                     "quantity [N·m·s or N·m] shared among them")
    des.add_argument("--h-max", type=float, default=1.0,
                     help="each wheel's momentum capacity [N·m·s] "
                     "(default 1)")
    des.add_argument("--m-max", type=float, default=1.0,
                     help="each wheel's torque capacity [N·m] (default 1)")
    des.add_argument("--starts", type=int, default=20,
                     help="random starts of the optimiser (default 20)")
    des.add_argument("--seed", type=int, default=0,
                     help="seed of the starts (default 0)")
    des.add_argument("--json", action="store_true",
                     help="print the answer as JSON")
    des.add_argument("--out", default=None,
                     help="write the best layout as a spacecraft TOML file")
    des.add_argument("--spacecraft", default="demo",
                     help="the craft (built-in name or TOML file) whose "
                     "body and thrusters the --out file keeps (default "
                     "demo)")
    des.set_defaults(func=run_design)
