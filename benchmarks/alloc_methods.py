"""The control-allocation literature's methods beside the exact QP.

Run from the repository root: ``python -m benchmarks.alloc_methods``
(``--samples 2000 --directions 100 --seed 0`` by default). For each
array (the pyramid of the papers with m_max = 0.2 N·m, the same with
wheel 2 failed, 3 + 1, six wheels as orthogonal pairs and six on a
54.7° cone) it prints, per method, the share of the attainable torque
set reached by volume (uniform Monte Carlo demands, fixed seed) and over
directions (mean and least radial reach over the set's), the relative
torque error on the attainable demands it misses (median, 95th
percentile), the share of reached demands where its torques equal the
exact QP's, the mean time per call in Python (this machine, one
process) and, where the method is exported (`allocation.methods.symbolic`,
gcc -O2), the median time per call in C and its ratio to the exact QP's
exported ``wheel_qp`` measured in the same run on the same demands
(`benchmarks.alloc_methods_c`; ``--no-c`` skips it). See
`allocation.compare_methods`.

Then the momentum-bound handling (`allocation.momentum_handling`,
``--cases 400``, dt = 0.5 s): on momentum states with wheels near their
bound, the share of steps after which a method told only the torque
limits leaves a wheel beyond h_max (and the worst excess), and, with the
momentum folded into its box, the share of the demands the exact QP
meets exactly that the method meets too.
"""

from __future__ import annotations

import argparse

from allocation import (
    WheelArray,
    compare_methods,
    comparison_arrays,
    format_comparison,
    format_momentum,
    momentum_handling,
)
from allocation.method_comparison import sample_attainable

from benchmarks.alloc_methods_c import c_times


def arrays() -> dict[str, WheelArray]:
    """Return the arrays of the comparison (`comparison_arrays`)."""
    return comparison_arrays()


def with_c_columns(table: str, rows, times: dict[str, float] | None
                   ) -> str:
    """``table`` (`format_comparison` of ``rows``) with the C columns.

    ``C µs``: median per call in C; ``÷ QP``: over the exported exact
    QP's (``wheel_qp``) in the same run; "-" where not exported.
    """
    if times is None:
        return table
    base = times["exact QP (scale)"]
    lines = table.splitlines()
    out = [lines[0] + f"{'C µs':>9}{'÷ QP':>8}", lines[1] + "-" * 17]
    for line, r in zip(lines[2:], rows):
        t = times.get(r.method)
        out.append(line + (f"{t:>9.3f}{t / base:>8.2f}" if t is not None
                           else f"{'-':>9}{'-':>8}"))
    return "\n".join(out)


def main(argv: list[str] | None = None) -> None:
    """Print the comparison table of every array."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=2000)
    p.add_argument("--directions", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--blocks", type=int, default=51,
                   help="C timing: blocks of 256 demands (median)")
    p.add_argument("--no-c", action="store_true", help="skip the C column")
    p.add_argument("--cases", type=int, default=400,
                   help="momentum states of the momentum-bound table")
    a = p.parse_args(argv)
    for name, array in arrays().items():
        rows = compare_methods(array, n_samples=a.samples,
                               n_directions=a.directions, seed=a.seed)
        times = None if a.no_c else c_times(
            array, sample_attainable(array, 256, a.seed), a.blocks, a.seed)
        print(f"\n{name} ({array.n_wheels - len(array.failed)} working "
              f"wheels, {a.samples} demands, {a.directions} directions)")
        print(with_c_columns(format_comparison(rows), rows, times))
    print("\nC: gcc -O2, median over blocks of 256 attainable demands; "
          "÷ QP: over the exported exact QP (wheel_qp, momentum bound at "
          "dt = 0.5 s) in the same run; fixed point: 200 steps (numpy "
          "stops when converged)")
    for name, array in arrays().items():
        rows = momentum_handling(array, dt=0.5, n_cases=a.cases,
                                 seed=a.seed)
        print(f"\nmomentum bound, {name} ({a.cases} cases, dt = 0.5 s, "
              f"{rows[0].n_exact} inside the momentum-limited set)")
        print(format_momentum(rows))


if __name__ == "__main__":
    main()
