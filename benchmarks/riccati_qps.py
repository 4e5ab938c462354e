"""What the Riccati active set (`benchmarks.riccati_active_set`) does with
the condensed step's QPs, kept stage by stage: iterations, recursions,
working sets, against DAQP.

Run from the repository root::

    python -m benchmarks.riccati_qps [--spacecraft demo] [--horizon 20]
                                     [--draws 20] [--steps 120]
                                     [--seed 0] [--caps 8,0]

Flies the condensed RTI step from `benchmarks.horizon_qps`'s random
starts (the same loops) and keeps each step's QP stage by stage. Each QP
whose start (the shifted plan, as the step starts) keeps every box is
solved by the twin from that start and from the last QP's working set
moved one stage ahead, capped at each of ``--caps`` iterations (0: none;
each cap's loop warm-starts from its own last working sets, as the
capped step does), and by DAQP on the dense QP (`dense_qp`, cold). Prints
per cap the iterations, the recursions (stages factored over N: one
recursion factors every stage, a change at stage k refactors k + 1),
the working sets' sizes, and the uncapped answers' distance from DAQP's
and from the step's torques (over m_max); then the reals a C version
would keep (`memory_reals`).
"""

from __future__ import annotations

import argparse

import daqp
import numpy as np
from tqdm.auto import tqdm

from benchmarks.horizon_qps import add_loop_arguments, collect
from benchmarks.riccati_active_set import StageQP, dense_qp, solve

#: DAQP's primal tolerance for the reference answers.
DAQP_TOL = 1e-12
#: Iterations of an uncapped solve.
NO_CAP = 100_000


def shifted(working: dict[tuple[int, int], int]) -> dict[tuple[int, int], int]:
    """A working set moved one stage ahead (the plan's shift)."""
    return {(k - 1, b): s for (k, b), s in working.items() if k >= 1}


def feasible_start(qp: StageQP, tol: float = 1e-9) -> bool:
    """Whether the QP's start keeps every box (within ``tol``)."""
    v = qp.values(qp.u0, qp.x0)
    return bool(np.all(v <= qp.hi + tol) and np.all(v >= qp.lo - tol))


def run_daqp(qp: StageQP) -> np.ndarray:
    """DAQP's δu (N, n_u) on the dense QP, cold, its primal tolerance
    `DAQP_TOL` (its default, 1e-6, leaves up to 1.4e-5 m_max here)."""
    H, f, C, lo, hi = dense_qp(qp)
    sense = np.where(lo == hi, 5, 0).astype(np.int32)
    x, _, flag, _ = daqp.solve(H, f, C, hi.copy(), lo.copy(), sense,
                               primal_tol=DAQP_TOL)
    if flag < 1:
        raise RuntimeError(f"DAQP failed ({flag}) on a stage-wise QP")
    return x.reshape(qp.dims[0], -1)


def carried(c: dict, cap: int, progress: bool = False):
    """The twin over the QPs of ``c`` in loop order, capped at ``cap``
    iterations (0: none), each warm-started from the working set its own
    last QP ended with, moved one stage ahead (none at a loop's first
    step, or after a QP left out). Yields ``(q, warm, result)`` per QP,
    ``result`` None where the start breaks a box (left out)."""
    last: dict | None = None
    for q in tqdm(c["qps"], desc=f"cap {cap or 'none'}", leave=False,
                  disable=None if progress else True):
        qp = q["stage"]
        if q["step"] == 0:
            last = None
        if not feasible_start(qp):
            last = None
            yield q, {}, None
            continue
        warm = shifted(last) if last else {}
        r = solve(qp, warm, max_iter=cap or NO_CAP)
        last = r["working"]
        yield q, warm, r


def run_cap(c: dict, cap: int) -> dict:
    """The twin on every QP with a feasible start, capped at ``cap``
    iterations (0: none), warm-started from its own last working set
    (`carried`)."""
    out: dict = {"iterations": [], "recursions": [], "working": [],
                 "dependent": 0, "error": 0.0, "step_error": 0.0,
                 "left_out": 0, "passed_back": 0}
    for q, _, r in carried(c, cap, progress=True):
        qp = q["stage"]
        if r is None:
            out["left_out"] += 1
            continue
        N = qp.dims[0]
        out["iterations"].append(r["iterations"])
        out["recursions"].append(r["factored"] / N)
        out["working"].append(len(r["working"]))
        out["dependent"] += r["dependent"]
        out["passed_back"] = max(out["passed_back"], r["passed_back"])
        if r["optimal"]:
            m_max = c["m_max"].reshape(N, -1)
            out["error"] = max(out["error"], float(np.max(
                np.abs(r["U"] - run_daqp(qp)) / m_max)))
            out["step_error"] = max(out["step_error"], float(np.max(
                np.abs(r["U"].ravel() - q["du"]) / c["m_max"])))
    return out


def memory_reals(qp: StageQP, passed_back: int) -> dict[str, int]:
    """Reals a C version of the twin would keep for ``qp`` (double: ×8
    bytes): the stage data as nonzeros (A, B, the lower triangle of Q;
    q, d, g, the boxes' bounds), the law δu_k = Kδx_k + k and the
    cost-to-go (P's lower triangle, p) per stage, the rows passed back to
    each stage (``passed_back`` of them, each n_x + 1 reals), and the
    iterate, its step and its box values."""
    N, nx, nu, nb = qp.dims

    def nnz(M: np.ndarray) -> int:
        return int(np.count_nonzero(np.any(M != 0, axis=0)))
    data = nnz(qp.A) + nnz(qp.B) + nnz(np.tril(qp.Q)) + 2 * nx + nu + 2 * nb
    law = nu * nx + nu + nx * (nx + 1) // 2 + nx
    rows = passed_back * (nx + 1)
    iterate = 2 * (nu + nx) + nb
    return {"stage data": N * data, "law and cost-to-go": N * law,
            "rows passed back": N * rows, "iterate and step": N * iterate,
            "total": N * (data + law + rows + iterate)}


def _stats(v) -> str:
    a = np.asarray(v, dtype=float)
    if a.size == 0:
        return "–"
    return (f"{np.median(a):.3g} / {np.percentile(a, 99):.3g} / "
            f"{a.max():.3g}")


def report(c: dict, runs: dict[int, dict]) -> str:
    """The table of `main`."""
    qp0 = c["qps"][0]["stage"]
    N, nx, nu, nb = qp0.dims
    lines = [f"{len(c['qps'])} QPs, N = {N}, {nx} states, {nu} inputs, "
             f"{nb} boxes a stage; median / p99 / worst over the QPs "
             f"solved:", "",
             "| cap | QPs solved (left out: start breaks a box) | "
             "iterations | recursions | working set at the end | "
             "|δu − DAQP| / m_max | |δu − step| / m_max |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for cap, r in runs.items():
        lines.append(
            f"| {cap or 'none'} | {len(r['iterations'])} "
            f"({r['left_out']}) | {_stats(r['iterations'])} | "
            f"{_stats(r['recursions'])} | {_stats(r['working'])} | "
            f"{r['error']:.1e} | {r['step_error']:.1e} |")
    back = max(r["passed_back"] for r in runs.values())
    mem = memory_reals(qp0, back)
    lines += ["", f"Rows passed back to one stage: at most {back}; boxes "
              f"held out as dependent: "
              + ", ".join(str(r["dependent"]) for r in runs.values()) + ".",
              "A C version's memory at this horizon (reals; ×8 bytes in "
              "double): " + ", ".join(f"{k} {v:,}" for k, v in mem.items())
              + "."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_loop_arguments(ap)
    ap.add_argument("--caps", default="8,0",
                    help="iteration caps, 0 for none (default 8,0)")
    args = ap.parse_args(argv)
    caps = [int(v) for v in args.caps.split(",")]
    c = collect(args.horizon, args.draws, args.steps, args.seed,
                args.spacecraft, stagewise=True)
    print(report(c, {cap: run_cap(c, cap) for cap in caps}))


if __name__ == "__main__":
    main()
