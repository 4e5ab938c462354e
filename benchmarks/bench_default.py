"""Wall time of ``adcs bench`` with its defaults (target: under 2 min).

Run from the repository root: ``python -m benchmarks.bench_default``.
Prints the run's wall time, the rows, and which backends the time budget
cut short.
"""

from __future__ import annotations

import time

from adcs.bench import run_bench


def main() -> None:
    """Print the figures."""
    t0 = time.perf_counter()
    rows = run_bench(progress=False)
    wall = time.perf_counter() - t0
    slow = [f"{r.problem}/{r.backend}" for r in rows if r.too_slow]
    print(f"\nadcs bench (defaults): {wall:.1f} s wall for {len(rows)} rows "
          f"({'met' if wall < 120 else 'NOT met'}: under 120 s)")
    print("cut short by the time budget: " + (", ".join(slow) or "none"))


if __name__ == "__main__":
    main()
