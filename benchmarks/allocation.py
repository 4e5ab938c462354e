"""Per-call cost of every wheel-allocation method (prints a table).

Run from the repository root as ``python -m benchmarks.allocation
[--quick]`` (as a module, so that this file does not shadow the
`allocation` package). Each figure is the median over repeated blocks of
calls, in µs per demand, with its ratio to
the numpy closed form measured in the same run. The QP demands are all
attainable with some wheel on its torque bound (the minimum-norm law
cannot meet them), plus a saturated share.
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np

from adcs_common.buffers import BoundCall
from allocation import (
    QPAllocator,
    WheelArray,
    available_solvers,
    conic_allocator_function,
    min_norm_function,
    min_norm_gains,
    min_norm_law,
)


def per_call(fn, n_calls: int, repeats: int) -> float:
    """Median time of one call [µs] over ``repeats`` blocks."""
    fn()
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n_calls):
            fn()
        samples.append((time.perf_counter() - t0) / n_calls)
    return statistics.median(samples) * 1e6


def demands(array: WheelArray, k: int, rng) -> np.ndarray:
    """Demands with a bound active for the QP (some saturated)."""
    G = min_norm_gains(array)
    out = []
    while len(out) < k:
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        reach_mn = 1.0 / np.max(np.abs(G @ u) / array.m_max)
        out.append(u * reach_mn * rng.uniform(1.05, 1.6))
    return np.array(out).T


def demands_batch(array: WheelArray, k: int, rng) -> np.ndarray:
    """Return (K, 3) demands with a bound active on every row.

    Up to 1.6 times the minimum-norm reach: beyond the set's extent
    along some directions, so a share is saturated.
    """
    u = rng.normal(size=(k, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    G = min_norm_gains(array)
    reach_mn = 1.0 / np.max(np.abs(u @ G.T) / array.m_max, axis=1)
    return u * (reach_mn * rng.uniform(1.05, 1.6, size=k))[:, None]


def run(quick: bool = False) -> list[tuple[str, float]]:
    """Measure every method; returns (label, µs per demand) rows."""
    rng = np.random.default_rng(0)
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    n_calls, repeats = (50, 3) if quick else (2000, 7)
    Ms = demands(arr, 64, rng)
    cycle = iter(np.tile(np.arange(64), 10**6))
    rows: list[tuple[str, float]] = []

    G = min_norm_gains(arr)
    M0 = Ms[:, 0].copy()
    rows.append(("closed form, numpy G @ M (per call)",
                 per_call(lambda: G @ M0, n_calls * 5, repeats)))
    law = min_norm_law(arr)
    rows.append(("closed form, LinearLaw.allocate (checked)",
                 per_call(lambda: law.allocate(M0), n_calls, repeats)))
    big = rng.normal(size=(3, 10_000 if quick else 1_000_000))
    t = per_call(lambda: G @ big, 1, repeats)
    rows.append((f"closed form, numpy batch of {big.shape[1]:,}",
                 t / big.shape[1]))
    f = min_norm_function(arr)
    rows.append(("closed form, CasADi Function (numpy in)",
                 per_call(lambda: f(M0), n_calls, repeats)))
    law_call = BoundCall(f, (M0.copy(),), (np.zeros(4),))
    rows.append(("closed form, CasADi Function.buffer",
                 per_call(law_call.trigger, n_calls * 5, repeats)))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in [s for s in available_solvers()
                     if not s.startswith("qpsolvers:")] + ["qpsolvers:osqp"]:
            qa = QPAllocator(arr, solver=name)
            label = {"osqp": "QP osqp (persistent, warm-started)",
                     "qpsolvers:osqp": "QP osqp via qpsolvers (set up per "
                     "call)", "daqp": "QPAllocator.allocate, default "
                     "(exact closed form, checked)"}.get(name, f"QP {name}")
            rows.append((label, per_call(
                lambda: qa.allocate(Ms[:, next(cycle)]),
                max(n_calls // 10, 5), repeats)))

    fa = QPAllocator(arr, solver="daqp")
    rows.append(("QPAllocator.allocate_fast (checked, closed-form QP)",
                 per_call(lambda: fa.allocate_fast(Ms[:, next(cycle)]),
                          n_calls, repeats)))

    for size in (1_000, 100_000):
        batch = demands_batch(arr, size, rng)
        rows.append((f"QPAllocator.allocate_batch, batch of {size:,}",
                     per_call(lambda: fa.allocate_batch(batch), 1,
                              repeats) / size))
    loop = batch[:200]
    rows.append(("QPAllocator.allocate, the batch's demands one by one",
                 per_call(lambda: [fa.allocate(M) for M in loop], 1,
                          repeats) / len(loop)))

    def buffered(f):
        """Return a call of ``f`` through its buffer on the next demand."""
        bound = BoundCall(f, (Ms[:, 0].copy(),),
                          (np.zeros(4), np.zeros(1), np.zeros(1)))

        def run_one():
            bound.inputs[0][:] = Ms[:, next(cycle)]
            bound.trigger()
        return run_one

    rows.append(("QP conic_allocator_function closed form, buffer",
                 per_call(buffered(conic_allocator_function(arr)), n_calls,
                          repeats)))
    qf = conic_allocator_function(arr, plugin="daqp", fast_path=False)
    rows.append(("QP conic_allocator_function daqp (numpy in)",
                 per_call(lambda: qf(Ms[:, next(cycle)]), n_calls,
                          repeats)))
    rows.append(("QP conic_allocator_function daqp, Function.buffer",
                 per_call(buffered(qf), n_calls, repeats)))
    compiled = compile_external(qf)
    if compiled is not None:
        rows.append(("QP same Function compiled to C (gcc -O2), buffer",
                     per_call(buffered(compiled), n_calls, repeats)))
    return rows


def compile_external(f):
    """Generate C for ``f``, build it with gcc, load it (None: no gcc)."""
    import shutil
    import subprocess
    import tempfile
    from pathlib import Path

    import casadi as ca

    from allocation.qp.conic_function import conic_c_flags

    if shutil.which("gcc") is None:
        return None
    tmp = Path(tempfile.mkdtemp(prefix="adcs_bench_"))
    cg = ca.CodeGenerator(f"{f.name()}.c")
    cg.add(f)
    cg.generate(f"{tmp}/")
    lib = tmp / f"{f.name()}.so"
    subprocess.run(["gcc", "-O2", "-fPIC", "-shared",
                    str(tmp / f"{f.name()}.c"), "-o", str(lib),
                    *conic_c_flags("daqp")], check=True)
    return ca.external(f.name(), str(lib))


def main() -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="few repetitions (smoke test)")
    args = parser.parse_args()
    rows = run(args.quick)
    base = rows[0][1]
    print(f"{'method':58s} {'µs/demand':>10s} {'ratio':>9s}")
    for label, us in rows:
        print(f"{label:58s} {us:10.3f} {us / base:9.1f}")
    batch = next(us for label, us in rows if "numpy batch" in label)
    print(f"\nclosed-form batch throughput: {1e6 / batch / 1e6:.1f} million "
          "demands/s on one core")
    qp = next(us for label, us in rows if "batch of 100,000" in label)
    one = next(us for label, us in rows if "one by one" in label)
    print(f"bounded-QP batch throughput: {1e6 / qp / 1e6:.2f} million "
          f"allocations/s on one core ({one / qp:.0f}x allocate)")


if __name__ == "__main__":
    main()
