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


def on_cluster(workers: int, study, params) -> tuple[float, float]:
    """Wall times of `run_sweep` on a fresh local cluster [s].

    ``(cold, warm)``: cold includes starting the workers and their first
    solver builds; warm is the same sweep again on the warmed workers.
    """
    t0 = time.perf_counter()
    client, cluster = connect(workers=workers)
    try:
        run_sweep(study, params, client=client, progress=False)
        cold = time.perf_counter() - t0
        warm = timed(lambda: run_sweep(study, params, client=client,
                                       progress=False))
    finally:
        client.close()
        cluster.close()
    return cold, warm


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
    mc_loop = timed(lambda: [accuracy_case(**p) for p in mc])
    one, one_w = on_cluster(1, agility_case, small)
    two, two_w = on_cluster(2, agility_case, small)
    mc1, mc1_w = on_cluster(1, accuracy_case, mc)
    mc2, mc2_w = on_cluster(2, accuracy_case, mc)
    n_big = 100 if args.quick else args.slews
    big, big_w = on_cluster(2, agility_case, agility_params(n_big))
    rows = [
        (f"agility, {len(small)} slews: plain loop", loop, "1.00"),
        ("  run_sweep, 1 worker: warm / cold (start-up)",
         one_w, f"overhead {one_w / loop - 1:+.1%} / {one / loop - 1:+.1%}"),
        ("  run_sweep, 2 workers: warm / cold", two_w,
         f"speed-up {loop / two_w:.2f}x / {loop / two:.2f}x"),
        (f"accuracy Monte Carlo {sum(p['n_samples'] for p in mc):,}: "
         "plain loop", mc_loop, "1.00"),
        ("  1 worker: warm / cold", mc1_w,
         f"overhead {mc1_w / mc_loop - 1:+.1%} / {mc1 / mc_loop - 1:+.1%}"),
        ("  2 workers: warm / cold", mc2_w,
         f"speed-up {mc_loop / mc2_w:.2f}x / {mc_loop / mc2:.2f}x"),
        (f"agility map, {n_big} slews N=50, 2 workers: warm", big_w,
         f"cold {big:.1f} s"),
    ]
    print("| run | wall time [s] | ratio |\n|---|---:|---|")
    for name, sec, ratio in rows:
        print(f"| {name} | {sec:.1f} | {ratio} |")
    return rows


if __name__ == "__main__":
    main()
