"""The primal active set in C, counted on the emulated Cortex-M cores.

Run from the repository root::

    python -m benchmarks.primal_qp_c [--target cortex-m7]
                                     [--precision double]
                                     [--caps 5,10,20,40,0]
                                     [--spacecraft demo] [--horizon 20]
                                     [--draws 20] [--steps 120] [--seed 0]

`benchmarks.horizon_qps` counted the iterations a primal active set
needs on the condensed RTI step's QPs, in dense numpy. This counts its
instructions: ``ocp/mpc/pqp/pqp.c`` (C99, no heap, double or float)
solves each QP in y as the step poses it (Hessian I, rows
``[W⁻¹; momenta]``) from where the step starts: y = 0 (δu = 0, the last
plan moved one stage ahead) and the signs of the last QP's multipliers
moved one stage ahead (those at their bound there; the C solver drops
dependent ones, as `primal_active_set.independent`). QPs where y = 0
breaks a bound (a loop's first, or a defect) are left out and counted.

It is built for the core and run under qemu (``-icount shift=0``,
SysTick's ticks of 40 instructions, as `adcs export --target`): per QP,
the warm working set's factorisation alone (cap 0 is read as no cap;
the factorisation is timed by a call stopped before its first
iteration), then one solve per cap. Prints instructions per QP (median,
p99, worst over the QPs with a constraint active, and over all), and the
largest distance of the C answer from the numpy twin's
(`primal_active_set.solve` on the same QP in y, run to its optimum).
The QPs travel to the board through a file read by semihosting.
"""

from __future__ import annotations

import argparse
import ctypes
import shutil
import struct
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from benchmarks import emulated_solver, primal_active_set
from benchmarks.emulated_solver import qp_rows, run_driver
from benchmarks.horizon_qps import (add_loop_arguments, collect, run_daqp,
                                    shift_stages, stage_parts)
from ocp.mpc.primal_qp import PQP_SOURCES
from ocp.codegen.target import CORES, TARGET_WARNINGS

#: The C solver's folder (pqp.c, pqp.h), shipped with ocp.mpc.
PQP_DIR = PQP_SOURCES
#: The solver's step and sign tolerance (y is of the order of W·m_max).
TOL = {"double": 1e-10, "single": 1e-4}
#: Iterations of an uncapped solve.
NO_CAP = 1000
#: pqp's float build.
PQP_SINGLE = "-DPQP_SINGLE_PRECISION"
#: Statuses of pqp_solve (pqp.h).
STATUS = ("optimal", "iteration limit", "infeasible", "invalid input",
          "no feasible point")


def host_library(out_dir: Path, precision: str = "double") -> ctypes.CDLL:
    """pqp.c built by the host's cc as a shared library in ``out_dir``."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise RuntimeError("no C compiler (cc) on this machine")
    lib = Path(out_dir) / f"libpqp_{precision}.so"
    define = ["-DPQP_SINGLE_PRECISION"] if precision == "single" else []
    subprocess.run([cc, "-O2", "-shared", "-fPIC", *TARGET_WARNINGS, *define,
                    str(PQP_DIR / "pqp.c"), "-lm", "-o", str(lib)],
                   check=True, capture_output=True, text=True)
    return ctypes.CDLL(str(lib))


def solve_c(lib: ctypes.CDLL, C: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            f: np.ndarray, y0: np.ndarray, side: np.ndarray,
            max_iter: int = NO_CAP, tol: float = TOL["double"],
            precision: str = "double", row_len: np.ndarray | None = None,
            packed: bool = False, phase_one: int | None = None,
            fill: float = 0.0) -> dict:
    """pqp_solve on one QP through ``lib`` (`host_library`): ``y``,
    ``side``, ``lam``, ``status`` (`STATUS`) and ``iterations``. With
    ``row_len`` (m,): pqp_solve_rows, each row read up to its length;
    ``packed``: the rows so cut, one after the other (row_start);
    ``phase_one``: pqp_solve_rows with that phase-one iteration limit
    (else pqp_solve's, m + max_iter); ``fill``: the work arrays' values
    before the call (NaN: any read of work not written first shows)."""
    real = np.float32 if precision == "single" else np.float64
    ctype = ctypes.c_float if precision == "single" else ctypes.c_double
    m, n = C.shape
    starts = None
    if packed:
        starts = np.r_[0, np.cumsum(row_len)[:-1]].astype(np.int32)
        C = np.concatenate([c[:k] for c, k in zip(C, row_len)])
    arr = [np.ascontiguousarray(a, dtype=real) for a in (C, lo, hi, f)]
    y = np.array(y0, dtype=real)
    sd = np.array(side, dtype=np.int8)
    lam = np.zeros(m, dtype=real)
    w = np.full(lib.pqp_work_size(n, m), fill, dtype=real)
    iw = np.full(lib.pqp_iwork_size(n, m), 0 if fill == 0 else -99999,
                 dtype=np.int32)
    its = ctypes.c_int(0)

    def ptr(a):
        return a.ctypes.data_as(ctypes.c_void_p)

    head = (ptr(y), ptr(sd), ptr(lam), int(max_iter))
    tail = (ctype(tol), ptr(w), ptr(iw), ctypes.byref(its))
    if row_len is None and phase_one is None:
        status = lib.pqp_solve(n, m, *map(ptr, arr), *head, *tail)
    else:
        lens = None if row_len is None else ptr(
            np.ascontiguousarray(row_len, dtype=np.int32))
        limit = m + max_iter if phase_one is None else phase_one
        status = lib.pqp_solve_rows(n, m, ptr(arr[0]), None if starts is
                                    None else ptr(starts), lens,
                                    *map(ptr, arr[1:]), *head, int(limit),
                                    *tail)
    return {"y": y.astype(float), "side": sd.astype(int),
            "lam": lam.astype(float), "status": STATUS[status],
            "iterations": its.value}


def y_problems(c: dict, signs: list) -> tuple[list[dict], int]:
    """The QPs of `collect` in y (rows ``[W⁻¹; rows]``), started where
    the step starts: y = 0 and ``signs`` (DAQP's multipliers' signs at
    each optimum, `run_daqp`) of the last QP moved one stage ahead; each
    with the numpy twin's answer ``y_ref`` and ``iterations``. Returns
    them and the number left out because y = 0 breaks a bound."""
    N, nw = c["N"], c["nw"]
    parts = stage_parts(N, c["nu"], nw, c["qps"][0]["rows"].shape[0] > N * nw)
    out, infeasible = [], 0
    for i, q in enumerate(tqdm(c["qps"], desc="numpy twin", disable=None,
                               leave=False)):
        if q["step"] == 0:
            continue
        tol = 1e-9 * c["scale"]
        if np.any(q["lo"] > tol) or np.any(q["hi"] < -tol):
            infeasible += 1
            continue
        C = np.vstack([q["Winv"], q["rows"]])
        side = shift_stages(signs[i - 1], parts).astype(int)
        at = [int(j) for j in np.flatnonzero(side)
              if abs((q["hi"] if side[j] > 0 else q["lo"])[j]) <= tol[j]]
        warm = {j: int(side[j])
                for j in primal_active_set.independent(C, at)}
        side = np.zeros(C.shape[0], dtype=int)
        side[list(warm)] = list(warm.values())
        n = C.shape[1]
        r = primal_active_set.solve(np.eye(n), q["gy"], C, q["lo"], q["hi"],
                                    np.zeros(n), warm, max_iter=NO_CAP)
        out.append({"C": C, "lo": q["lo"], "hi": q["hi"], "f": q["gy"],
                    "side": side, "y_ref": r["x"],
                    "iterations": r["iterations"],
                    "constrained": bool(r["working"])})
    return out, infeasible


def write_problems(path: Path, problems: list[dict], caps: list[int],
                   precision: str = "double") -> None:
    """The QPs as the target driver reads them: a header (count, n, m,
    caps), then per QP C, lo, hi, f, y_ref (reals, little-endian) and
    the warm sides (int8)."""
    real = "<f4" if precision == "single" else "<f8"
    m, n = problems[0]["C"].shape
    with open(path, "wb") as fh:
        fh.write(struct.pack("<4i", len(problems), n, m, len(caps)))
        fh.write(struct.pack(f"<{len(caps)}i", *caps))
        for p in problems:
            for key in ("C", "lo", "hi", "f", "y_ref"):
                fh.write(np.ascontiguousarray(p[key], dtype=real).tobytes())
            fh.write(np.asarray(p["side"], dtype=np.int8).tobytes())


_MAIN = r"""
#include "pqp.h"

#define NMAX @NMAX@
#define MMAX @MMAX@
#define CMAX 8
static pqp_real C[MMAX * NMAX], lo[MMAX], hi[MMAX], f[NMAX], yref[NMAX];
static pqp_real y[NMAX], lam[MMAX], w[PQP_WORK_SIZE(NMAX, MMAX)];
static signed char side0[MMAX], side[MMAX];
static int iw[PQP_IWORK_SIZE(NMAX, MMAX)];

static int read_all(FILE* fh, void* p, size_t size, size_t count) {
  return fread(p, size, count, fh) == count;
}

int main(void) {
  int head[4], caps[CMAX], q, c, i, its, status;
  FILE* fh;
  driver_init();
  stack_paint();
  fh = fopen("qps.bin", "rb");
  if (!fh || !read_all(fh, head, sizeof(int), 4) || head[1] > NMAX ||
      head[2] > MMAX || head[3] > CMAX ||
      !read_all(fh, caps, sizeof(int), (size_t)head[3])) {
    printf("ERROR reading qps.bin\n");
    return 1;
  }
  for (q = 0; q < head[0]; ++q) {
    const int n = head[1], m = head[2];
    if (!read_all(fh, C, sizeof(pqp_real), (size_t)(m * n)) ||
        !read_all(fh, lo, sizeof(pqp_real), (size_t)m) ||
        !read_all(fh, hi, sizeof(pqp_real), (size_t)m) ||
        !read_all(fh, f, sizeof(pqp_real), (size_t)n) ||
        !read_all(fh, yref, sizeof(pqp_real), (size_t)n) ||
        !read_all(fh, side0, 1, (size_t)m)) {
      printf("ERROR reading QP %d\n", q);
      return 1;
    }
    for (c = -1; c < head[3]; ++c) {
      double t0, t1;
      double err = 0;
      for (i = 0; i < n; ++i) y[i] = 0;
      for (i = 0; i < m; ++i) side[i] = side0[i];
      t0 = clock_now();
      status = pqp_solve(n, m, C, lo, hi, f, y, side, lam,
                         c < 0 ? 0 : caps[c], (pqp_real)@TOL@, w, iw, &its);
      t1 = clock_now();
      for (i = 0; i < n; ++i) {
        double d = fabs((double)y[i] - (double)yref[i]);
        if (d > err) err = d;
      }
      printf("QP %d cap=%d ticks=%lu iterations=%d status=%d err=%.3e\n", q,
             c < 0 ? -1 : caps[c], (unsigned long)(t1 - t0), its, status,
             err);
    }
  }
  fclose(fh);
  printf("STACK %ld\n", stack_used());
  return 0;
}
"""


def run_target(problems: list[dict], caps: list[int], target: str,
               precision: str, timeout: float = 3600.0) -> list[dict]:
    """Build pqp.c and its driver for ``target`` and run it on qemu; per
    QP and cap (``-1``: the warm factorisation alone) its
    ``instructions``, ``iterations``, ``status`` and ``err`` (max |y −
    y_ref|)."""
    m, n = problems[0]["C"].shape
    caps = [NO_CAP if cap == 0 else cap for cap in caps]
    with tempfile.TemporaryDirectory() as tmp:
        write_problems(Path(tmp) / "qps.bin", problems, caps, precision)
        data = (Path(tmp) / "qps.bin").read_bytes()
    main = _MAIN.replace("@NMAX@", str(n)).replace("@MMAX@", str(m)).replace(
        "@TOL@", repr(TOL[precision]))
    out = run_driver(main, PQP_DIR / "pqp.c", data, target, precision,
                     PQP_SINGLE, timeout)
    return qp_rows(out, STATUS)


def solver_memory(target: str, precision: str = "double") -> dict:
    """pqp.c compiled for ``target`` alone: its ``flash`` (text + rodata,
    bytes), the deepest ``stack`` from `pqp_solve` (gcc's frames and call
    graph, `ocp.codegen.memory.worst_stack`), whether that is
    ``bounded`` and the ``library`` functions it calls (their frames not
    counted)."""
    return emulated_solver.solver_memory(PQP_DIR / "pqp.c", "pqp_solve",
                                         target, precision, PQP_SINGLE)


def _stats(v) -> str:
    v = np.asarray(v)
    if not v.size:
        return "–"
    return (f"{np.median(v):,.0f} / {np.percentile(v, 99):,.0f} / "
            f"{v.max():,.0f}")


def report(problems: list[dict], rows: list[dict], caps: list[int]) -> str:
    """The instructions per QP table (median / p99 / worst)."""
    constrained = {i for i, p in enumerate(problems) if p["constrained"]}
    lines = ["| cap | iterations, constrained QPs | instructions, "
             "constrained QPs | instructions, all QPs | stopped at the "
             "cap | not optimal, uncapped | max \\|y − numpy's\\| |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for cap in [-1, *[NO_CAP if c == 0 else c for c in caps]]:
        sel = [r for r in rows if r["cap"] == cap]
        con = [r for r in sel if r["qp"] in constrained]
        name = ("warm factorisation" if cap == -1 else
                "none" if cap == NO_CAP else str(cap))
        err, failed = "", ""
        if cap == NO_CAP:
            err = f"{max(r['err'] for r in sel):.1e}"
            failed = str(sum(r["status"] != "optimal" for r in sel))
        stopped = sum(r["status"] == "iteration limit" for r in sel)
        lines.append(
            f"| {name} | {_stats([r['iterations'] for r in con])} | "
            f"{_stats([r['instructions'] for r in con])} | "
            f"{_stats([r['instructions'] for r in sel])} | "
            f"{stopped if cap >= 0 else ''} | {failed} | {err} |")
    return "\n".join(lines)


def host_accuracy(problems: list[dict], c: dict,
                  precision: str = "single") -> dict:
    """The host build's answers (the target's code, compiled by cc) on
    every QP, uncapped, against the numpy twin's: the largest torque
    difference over m_max (``du``, δu = W⁻¹y) and the largest bound
    violation over each row's scale (``violation``; `row_scales`)."""
    n = problems[0]["C"].shape[1]
    with tempfile.TemporaryDirectory() as tmp:
        lib = host_library(Path(tmp), precision)
        du = violation = 0.0
        for p in problems:
            r = solve_c(lib, p["C"], p["lo"], p["hi"], p["f"], np.zeros(n),
                        p["side"], tol=TOL[precision], precision=precision)
            v = p["C"] @ r["y"]
            du = max(du, float(np.max(np.abs(v[:n] - p["C"][:n]
                                             @ p["y_ref"]) / c["m_max"])))
            violation = max(violation, float(np.max(
                np.maximum(v - p["hi"], p["lo"] - v) / c["scale"])))
    return {"du": du, "violation": violation}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_loop_arguments(ap)
    ap.add_argument("--target", default="cortex-m7",
                    choices=sorted(CORES))
    ap.add_argument("--precision", default="double",
                    choices=("double", "single"))
    ap.add_argument("--caps", default="5,10,20,40,0",
                    help="iteration caps, 0 for none (default 5,10,20,40,0)")
    args = ap.parse_args(argv)
    caps = [int(c) for c in args.caps.split(",")]
    c = collect(args.horizon, args.draws, args.steps, args.seed,
                args.spacecraft)
    signs = run_daqp(c)["signs"]
    problems, infeasible = y_problems(c, signs)
    rows = run_target(problems, caps, args.target, args.precision)
    m, n = problems[0]["C"].shape
    print(f"{len(problems)} QPs ({sum(p['constrained'] for p in problems)}"
          f" constrained; {infeasible} left out: y = 0 breaks a bound), "
          f"{n} variables, {m} rows, {args.target}, {args.precision}:\n")
    print(report(problems, rows, caps))
    mem = solver_memory(args.target, args.precision)
    work = (n * (n + 1) // 2 + 4 * n + 3 * m) * (
        4 if args.precision == "single" else 8) + 4 * (n + m)
    print(f"\npqp.c on the {args.target}: {mem['flash']:,} bytes of flash, "
          f"work {work:,} bytes, stack {mem['stack']:,} bytes"
          f"{'' if mem['bounded'] else ' (not bounded)'}"
          f"{' + ' + ', '.join(mem['library']) if mem['library'] else ''}.")
    if args.precision == "single":
        acc = host_accuracy(problems, c)
        print(f"\nThe float build on the host, uncapped: torques within "
              f"{acc['du']:.1e} m_max of the numpy twin's, bounds kept "
              f"within {acc['violation']:.1e} of their scale.")


if __name__ == "__main__":
    main()
