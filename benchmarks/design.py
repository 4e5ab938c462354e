"""The array design optimiser against random search.

Run from the repository root: ``python -m benchmarks.design``
(``--starts 100 --random 20000`` by default). For each problem it prints
the time per start (IPOPT continuation plus certification by the
envelope code), the fraction of random starts that reach the best known
value to 1e-6 or beat it, the best value found, and for four wheels the
best of a random search over unit axes (uniform on the sphere), each
layout's radius from the facet formula and the best one certified by the
envelope code. Unit capacity per wheel; radii in that unit. One untimed
design first loads IPOPT's shared libraries (about 1 s, once per
process).
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from allocation import certify_layout, design_array

#: (wheels, failures, family, best known value of the objective)
PROBLEMS = [
    (4, 0, "free", 4 / np.sqrt(6)),
    (4, 1, "free", 2 / np.sqrt(6)),
    (5, 0, "free", 2.182643356),
    (5, 1, "free", np.sqrt(5) - 1),
    (6, 0, "free", 2.752763841),
    (6, 1, "free", 1.902113033),
    (5, 0, "cone", 2.182643356),
    (6, 0, "pairs", 2.752763841),
]


def random_search(n: int, samples: int, seed: int = 0
                  ) -> tuple[float, float, np.ndarray]:
    """Best nominal radius of ``samples`` random layouts of n unit axes.

    Returns (best radius from the facet formula, the same layout
    certified by the envelope code, its axes (3, n)).
    """
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(samples, 3, n))
    A /= np.linalg.norm(A, axis=1, keepdims=True)
    radius = np.full(samples, np.inf)
    for i, j in itertools.combinations(range(n), 2):
        nrm = np.cross(A[:, :, i], A[:, :, j])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        h = np.abs(np.einsum("sd,sdk->sk", nrm, A)).sum(axis=1)
        radius = np.minimum(radius, h)
    best = int(np.argmax(radius))
    return float(radius[best]), certify_layout(A[best])[0], A[best]


def main(argv=None) -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=100)
    ap.add_argument("--random", type=int, default=20000)
    args = ap.parse_args(argv)
    design_array(4, starts=1)        # load IPOPT's libraries once, untimed
    print(f"{'wheels':>6s} {'fail':>4s} {'family':>6s} {'best known':>11s} "
          f"{'found':>11s} {'reached':>8s} {'median s':>9s} {'max s':>7s}")
    for n, k, family, known in PROBLEMS:
        d = design_array(n, failures=k, family=family, starts=args.starts,
                         seed=0)
        reached = np.mean(d.start_objectives >= known - 1e-6)
        print(f"{n:6d} {k:4d} {family:>6s} {known:11.6f} {d.objective:11.6f}"
              f" {reached:8.0%} {np.median(d.start_times):9.3f} "
              f"{d.start_times.max():7.3f}")
    t = time.perf_counter()
    r, r_cert, _ = random_search(4, args.random)
    dt = time.perf_counter() - t
    print(f"\nrandom search, {args.random} four-wheel layouts: best "
          f"{r:.6f} (envelope code {r_cert:.6f}) in {dt:.2f} s; "
          f"optimum {4 / np.sqrt(6):.6f}")


if __name__ == "__main__":
    main()
