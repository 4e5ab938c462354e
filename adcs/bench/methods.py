"""The bench's ``methods`` problem: the literature's allocation methods.

Same array and demands as the ``wheels`` problem; each method of
`allocation.methods` is timed in Python and compared with the exact QP.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .core import TOL, BenchRow, Progress, quiet, timed_row

#: bench name -> `allocation.methods.METHODS` key
METHOD_NAMES = {
    "method:pinv": "pseudo-inverse",
    "method:rpi": "redistributed pseudo-inverse",
    "method:cgi": "cascaded generalised inverse",
    "method:daisy": "daisy chain",
    "method:fixed-point": "fixed point",
    "method:wls": "WLS active set",
    "method:direct": "direct allocation",
}


def bench_methods(backends: Sequence[str] | None = None, reps: int = 200,
                  seed: int = 0, progress: Progress | None = None,
                  spacecraft: Any | None = None,
                  budget: float = 8.0) -> list[BenchRow]:
    """Time the literature's allocation methods on the wheel demands.

    One row per method (``method:pinv``, ``method:rpi``, ``method:cgi``,
    ``method:daisy``, ``method:fixed-point``, ``method:wls``,
    ``method:direct``; all when ``backends`` names none of them). Its
    reference is the exact QP's answer (``saturation="scale"`` for direct
    allocation, ``"least_squares"`` otherwise); "max error" is the largest
    distance from it [N·m] and "max KKT" the largest relative torque
    error ``|A m - M| / |M|`` [1]. "wrong" counts answers off the QP's by
    more than 1e-6: for a method that is not minimum-norm (direct
    allocation inside the set, daisy chaining) or biased (the fixed point,
    ε = 1e-4) this is by design, and the note says how many answers
    missed the demand itself.
    """
    from allocation import QPAllocator
    from allocation.methods import METHODS

    from .problems import wheel_problem

    bar = progress or quiet()
    names = [b for b in (backends or ()) if b in METHOD_NAMES] or (
        list(METHOD_NAMES) if not backends else [])
    if not names:
        return []
    arr, demands = wheel_problem(spacecraft, reps, seed)
    A = arr.working_axes
    qp = {s: QPAllocator(arr, saturation=s)
          for s in ("scale", "least_squares")}

    def torque_error(M: np.ndarray, m: np.ndarray) -> float:
        return float(np.linalg.norm(A @ m - M)
                     / max(float(np.linalg.norm(M)), 1e-300))

    bar.add(len(names) * len(demands))
    rows = []
    for name in names:
        key = METHOD_NAMES[name]
        f = METHODS[key]
        ref_qp = qp["scale" if key == "direct allocation"
                    else "least_squares"]
        refs = [ref_qp.allocate(M).torques for M in demands]
        row = timed_row("methods", name, demands, refs,
                        lambda M, f=f: f(arr, M), torque_error, bar,
                        budget)
        missed = sum(torque_error(M, f(arr, M)) > TOL
                     for M in demands[:row.n])
        note = (f"{key}: {missed}/{row.n} demands missed; answers "
                f"{'equal' if row.wrong == 0 else 'differ from'} the "
                "exact QP's" + (f" ({row.wrong}/{row.n})" if row.wrong
                                else ""))
        rows.append(BenchRow(**{**row.__dict__, "note": note}))
    return rows
