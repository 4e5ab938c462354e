"""Per-cycle allocation time of the thruster laws and QP backends.

Prints the median time per cycle [µs] of the closed forms ([4]
eqs. 2 and 8-9), of the allocator's certified fast path
(`DutyCycleAllocator.duty_fast`) and of every installed duty-cycle QP
backend, with the ratio to the closed form measured in the same run. Run:

    python benchmarks/thrusters.py [--repeat N]     (or: python -m
    benchmarks.thrusters from the repository root)
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

if not __package__:
    # run as a file, this script's folder comes first on sys.path and its
    # name would shadow the `thrusters` package
    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path
                   if Path(p or ".").resolve() != _here]

from thrusters import (
    DutyCycleAllocator,
    available_solvers,
    reorientation_law,
    six_thruster_unit,
    unloading_law,
)
from thrusters.laws import TORQUE_AXES


def median_us(fn, demands, repeat):
    """Median and minimum per-call time over the calls [µs].

    Each demand is timed ``repeat`` times; the minimum over repeats
    removes interruptions by other processes, then the median and the
    minimum are taken over the demands.
    """
    for d in demands[:20]:
        fn(d)
    best = np.full(len(demands), np.inf)
    clock = time.perf_counter
    for _ in range(repeat):
        for i, d in enumerate(demands):
            t0 = clock()
            fn(d)
            best[i] = min(best[i], clock() - t0)
    return 1e6 * float(np.median(best)), 1e6 * float(best.min())


def main(argv=None):
    """Run the benchmark and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--demands", type=int, default=200)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    unit = six_thruster_unit()
    rng = np.random.default_rng(0)
    T = 2.0
    # hold/reorientation demands (P_T = 0) with wheel momentum in bound
    dem = [(0.0, rng.uniform(-0.004, 0.004, 2),
            np.array([rng.uniform(-0.01, 0.01), 0.0,
                      rng.uniform(-0.01, 0.01)]))
           for _ in range(args.demands)]
    burn = [(0.739, None, np.array([rng.uniform(-0.01, 0.01), 0.0,
                                    rng.uniform(-0.01, 0.01)]))
            for _ in range(args.demands)]
    rows = []
    ref = median_us(lambda d: reorientation_law(unit, d[0], d[1]), dem,
                    args.repeat)
    rows.append(("closed form eqs. 8-9 (reorientation_law)", ref))
    rows.append(("closed form eq. 2 (unloading_law)", median_us(
        lambda d: unloading_law(unit, d[0], d[2], 10.0, 1.0), burn,
        args.repeat)))
    # the closed form as flight software runs it: one 3x3 gain product
    C = np.vstack([np.ones(3), unit.arms[TORQUE_AXES[0], :3],
                   unit.arms[TORQUE_AXES[1], :3]])
    G = np.linalg.inv(C)
    y = np.zeros(3)

    def gains(d):
        y[1:] = d[1]
        return G @ y
    rows.append(("closed form eq. 8, precomputed gains (F = G y)",
                 median_us(gains, dem, args.repeat)))
    # fast path: one Function.buffer trigger (CasADi daqp + KKT
    # certificate), falls back to solve() when the certificate fails
    fast = DutyCycleAllocator(unit, T, 0.012, solver="daqp",
                              tracking="weighted")
    rows.append(("QP fast path: DutyCycleAllocator.duty_fast", median_us(
        lambda d: fast.duty_fast(d[0], d[1], d[2]), dem, args.repeat)))
    out = np.zeros(unit.n)
    rows.append(("QP fast path: duty_fast(..., out=buffer)", median_us(
        lambda d: fast.duty_fast(d[0], d[1], d[2], out=out), dem,
        args.repeat)))
    # hard tracking (the allocator's default): torques as equalities,
    # eliminated before the conic; demands the unit can meet exactly
    hard = DutyCycleAllocator(unit, T, 0.012, solver="daqp",
                              tracking="hard")
    dem_hard = [(d[0], 0.25 * d[1], d[2]) for d in dem]
    rows.append(("QP fast path, hard tracking: duty_fast", median_us(
        lambda d: hard.duty_fast(d[0], d[1], d[2]), dem_hard,
        args.repeat)))
    n_fast_calls = 2 * (min(20, len(dem)) + args.repeat * len(dem))
    for solver in available_solvers():
        alloc = DutyCycleAllocator(unit, T, 0.012, solver=solver,
                                   tracking="weighted")
        rows.append((f"QP {solver}: DutyCycleAllocator.solve", median_us(
            lambda d: alloc.solve(d[0], d[1], d[2]), dem, args.repeat)))
        th = [alloc.theta(d[0], d[1], d[2]) for d in dem]
        rows.append((f"QP {solver}: solve_theta (no input checks)",
                     median_us(alloc.solve_theta, th, args.repeat)))
    w = max(len(r[0]) for r in rows)
    print(f"{'allocation (per cycle)':<{w}}  {'median µs':>10}  "
          f"{'min µs':>8}  {'x closed form':>13}")
    for name, (med, low) in rows:
        print(f"{name:<{w}}  {med:>10.1f}  {low:>8.1f}  "
              f"{med / ref[0]:>13.2f}")
    print(f"duty_fast fell back to solve() on {fast.fast_fallbacks} of "
          f"{n_fast_calls} calls (weighted), {hard.fast_fallbacks} of "
          f"{n_fast_calls // 2} (hard)")
    return rows


if __name__ == "__main__":
    main()
