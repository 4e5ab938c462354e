"""Sweep machinery on this machine: overhead, speed-up, the agility map.

Run from the repository root::

    python -m benchmarks.sweeps [--slews 1000] [--quick]

Rows (wall times, one run each, same process):

* overhead: the agility study on the Meteor-M craft called in a plain loop
  against `run_sweep` on a 1-worker local cluster (default task size);
* speed-up: the same on 2 worker processes, and the accuracy Monte Carlo
  (10⁶ samples in blocks of 10⁵) on 1 and 2 workers;
* the agility map of ``--slews`` time-optimal slews (N = 50) on Meteor-M
  with 2 workers.
Worker start-up and each worker's first solver build are inside the
cluster times (what a user waits for).
"""

from __future__ import annotations

import argparse
import time

from adcs.sweep import connect, run_sweep
from adcs.sweep.builtin import _accuracy, accuracy_case, agility_case


def agility_params(n: int) -> list[dict]:
    """``n`` Meteor-M slews: 12 axes × angles from 10° to 180°, N = 50."""
    per_axis = -(-n // 12)
    angles = [10.0 + 170.0 * k / max(per_axis - 1, 1)
              for k in range(per_axis)]
    rows = [{"spacecraft": "meteor-m", "axis": a, "angle_deg": ang,
             "N": 50} for ang in angles for a in range(12)]
    return rows[:n]


def timed(fn) -> float:
    """Wall time of ``fn()`` [s]."""
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def on_cluster(workers: int, study, params) -> float:
    """Wall time of `run_sweep` on a fresh local cluster (start included)."""
    t0 = time.perf_counter()
    client, cluster = connect(workers=workers)
    try:
        run_sweep(study, params, client=client, progress=False)
    finally:
        client.close()
        cluster.close()
    return time.perf_counter() - t0


def main(argv=None) -> list[tuple[str, float, str]]:
    """Print the table of the module docstring; return its rows."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slews", type=int, default=1000)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    small = agility_params(24 if args.quick else 120)
    mc = _accuracy(False, samples=200_000 if args.quick else 1_000_000)
    # warm this process's solver cache like a worker's first case does
    agility_case(**small[0])
    loop = timed(lambda: [agility_case(**p) for p in small])
    one = on_cluster(1, agility_case, small)
    two = on_cluster(2, agility_case, small)
    mc1 = on_cluster(1, accuracy_case, mc)
    mc2 = on_cluster(2, accuracy_case, mc)
    big = on_cluster(2, agility_case,
                     agility_params(100 if args.quick else args.slews))
    rows = [
        (f"agility, {len(small)} slews: plain loop", loop, "1.00"),
        ("  run_sweep, 1 worker (start-up included)", one,
         f"overhead {one / loop - 1:+.1%}"),
        ("  run_sweep, 2 workers", two, f"speed-up {loop / two:.2f}x"),
        (f"accuracy Monte Carlo {sum(p['n_samples'] for p in mc):,}: "
         "1 worker", mc1, "1.00"),
        ("  2 workers", mc2, f"speed-up {mc1 / mc2:.2f}x"),
        (f"agility map, {100 if args.quick else args.slews} slews N=50, "
         "2 workers", big, ""),
    ]
    print("| run | wall time [s] | ratio |\n|---|---:|---|")
    for name, sec, ratio in rows:
        print(f"| {name} | {sec:.1f} | {ratio} |")
    return rows


if __name__ == "__main__":
    main()
