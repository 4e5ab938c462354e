"""The Riccati active set in C (``ocp/mpc/rqp/rqp.c``), counted on the
emulated Cortex-M cores against its numpy twin.

Run from the repository root::

    python -m benchmarks.riccati_qp_c [--target cortex-m7]
                                      [--precision double] [--caps 8,0]
                                      [--spacecraft demo] [--horizon 20]
                                      [--draws 20] [--steps 120] [--seed 0]

Flies `benchmarks.riccati_qps`'s loops (the condensed RTI step's QPs kept
stage by stage, `benchmarks.horizon_qps.collect`), keeps the QPs whose
start keeps every box, each with the warm working set the twin's own
capped loop carried to it (`benchmarks.riccati_active_set.solve` capped
at the first of ``--caps``), and solves each again in C: on the host
through ctypes (the answer against the twin's) and built for the core
and run under qemu (``-icount shift=0``, SysTick's ticks of 40
instructions, as `adcs export --target`), one solve per cap. Prints per
cap the instructions per QP (median, p99, worst), iterations, the
recursions (stages factored over N), the largest distance from the
twin's answer, and rqp.c's flash, work and deepest stack.
"""

from __future__ import annotations

import argparse
import ctypes
import functools
import shutil
import struct
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from benchmarks import emulated_solver
from benchmarks.emulated_solver import qp_rows, run_driver
from benchmarks.horizon_qps import add_loop_arguments, collect
from benchmarks.riccati_active_set import StageQP, solve
from benchmarks.riccati_qps import NO_CAP, carried
from ocp.codegen.target import CORES, TARGET_WARNINGS
from ocp.mpc.primal_qp import PQP_SOURCES
from ocp.mpc.riccati_qp import products_source as riccati_products

#: The C solver's folder (rqp.c, rqp.h), shipped with ocp.mpc.
RQP_DIR = PQP_SOURCES.parent / "rqp"
#: The solver's step and sign tolerance (in box widths).
TOL = {"double": 1e-10, "single": 1e-4}
#: rqp.c's hook for the generated stage products (`products_source`).
PRODUCTS_FLAG = "-DRQP_PRODUCTS=rqp_products"
#: rqp's float build.
RQP_SINGLE = "-DRQP_SINGLE_PRECISION"
#: Statuses of rqp_solve (rqp.h).
STATUS = {0: "optimal", 1: "iteration limit", 2: "infeasible start",
          3: "invalid input", 4: "rows full"}


def boxes(qp: StageQP) -> tuple[np.ndarray, np.ndarray]:
    """``(box, scale)``: each box's component of (u, x) and its scale,
    from the one entry of its row of E_u or E_x."""
    nu = qp.Eu.shape[1]
    box, scale = [], []
    for eu, ex in zip(qp.Eu, qp.Ex):
        i = int(np.flatnonzero(eu)[0]) if np.any(eu) else \
            nu + int(np.flatnonzero(ex)[0])
        box.append(i)
        scale.append(eu[i] if i < nu else ex[i - nu])
    return np.array(box, dtype=np.int32), np.array(scale)


class _Problem(ctypes.Structure):
    _fields_ = [(n, ctypes.c_int) for n in ("N", "nx", "nu", "nb")] + [
        (n, ctypes.c_void_p) for n in ("a_col", "a_row", "b_col", "b_row",
                                       "q_col", "q_row",
                                       "A", "B", "d", "Q", "q", "R", "g",
                                       "box", "scale", "lo", "hi",
                                       "fixed")]


Masks = tuple[np.ndarray, np.ndarray]


def common_masks(qps: list[StageQP]) -> Masks:
    """The patterns of A and B (boolean n_x × n_x and n_x × n_u) that
    hold every stage's nonzeros of every QP in ``qps``."""
    return (np.any([np.any(q.A != 0, axis=0) for q in qps], axis=0),
            np.any([np.any(q.B != 0, axis=0) for q in qps], axis=0))


def pattern(M: np.ndarray, mask: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(col, row, values)``: the stages' matrices M (N, r, c) as the
    nonzeros (N, nnz) of one compressed-column pattern: ``mask``'s, or
    the union of their nonzeros."""
    nz = np.any(M != 0, axis=0) if mask is None else mask
    rows, cols = [], [0]
    for j in range(M.shape[2]):
        rows += list(np.flatnonzero(nz[:, j]))
        cols.append(len(rows))
    col_of = np.repeat(np.arange(M.shape[2]), np.diff(cols))
    return (np.array(cols, dtype=np.int32), np.array(rows, dtype=np.int32),
            M[:, rows, col_of])


def sizes_flags(nx: int, nu: int) -> tuple[str, ...]:
    """The flags that compile rqp.c for n_x states and n_u inputs (its
    stage loops then of fixed length, unrolled)."""
    return (f"-DRQP_NX={nx}", f"-DRQP_NU={nu}")


def products_source(masks: Masks, precision: str = "double",
                    name: str = "rqp_products") -> str:
    """C of the stage's products that rqp.c takes from ``-DRQP_PRODUCTS``
    for the patterns ``masks`` of A and B (`common_masks`):
    `ocp.mpc.riccati_qp.products_source` on those patterns."""
    import casadi as ca

    nx, nu = masks[1].shape
    a_col, a_row, _ = pattern(np.zeros((1, nx, nx)), masks[0])
    b_col, b_row, _ = pattern(np.zeros((1, nx, nu)), masks[1])
    return riccati_products(
        ca.Sparsity(nx, nx, a_col.tolist(), a_row.tolist()),
        ca.Sparsity(nx, nu, b_col.tolist(), b_row.tolist()), precision, name)


def host_library(out_dir: Path, precision: str = "double",
                 sizes: tuple[int, int] | None = None,
                 products: Masks | None = None,
                 defines: tuple[str, ...] = ()) -> ctypes.CDLL:
    """rqp.c built by the host's cc as a shared library in ``out_dir``
    (``sizes``: for that (n_x, n_u) only, `sizes_flags`; ``products``:
    with the stage products generated for those patterns of A and B,
    `products_source`: solve with the same ``masks``; ``defines``: more
    -D flags, and the library's name says they are there)."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise RuntimeError("no C compiler (cc) on this machine")
    tag = f"_{sizes[0]}x{sizes[1]}" if sizes else ""
    tag += "_gen" if products is not None else ""
    tag += f"_d{abs(hash(defines)) % 10 ** 8}" if defines else ""
    lib = Path(out_dir) / f"librqp_{precision}{tag}.so"
    define = [RQP_SINGLE] if precision == "single" else []
    define += list(sizes_flags(*sizes)) if sizes else []
    define += list(defines)
    extra: list[str] = []
    if products is not None:
        gen = Path(out_dir) / "rqp_products.c"
        gen.write_text(products_source(products, precision))
        define.append(PRODUCTS_FLAG)
        extra.append(str(gen))
    subprocess.run([cc, "-O2", "-shared", "-fPIC", *TARGET_WARNINGS, *define,
                    str(RQP_DIR / "rqp.c"), *extra, "-lm", "-o", str(lib)],
                   check=True, capture_output=True, text=True)
    dll = ctypes.CDLL(str(lib))
    real = ctypes.c_float if precision == "single" else ctypes.c_double
    ptr = ctypes.c_void_p
    dll.rqp_solve.argtypes = [ctypes.POINTER(_Problem), ptr, ptr, ptr, ptr,
                              ctypes.c_int, real, ptr, ptr,
                              ctypes.POINTER(ctypes.c_int),
                              ctypes.POINTER(ctypes.c_long)]
    return dll


def _arrays(qp: StageQP, real, masks: Masks | None = None
            ) -> dict[str, np.ndarray]:
    box, scale = boxes(qp)
    a_col, a_row, A = pattern(qp.A, None if masks is None else masks[0])
    b_col, b_row, B = pattern(qp.B, None if masks is None else masks[1])
    q_col, q_row, Q = pattern(qp.Q)
    ints = {"a_col": a_col, "a_row": a_row, "b_col": b_col, "b_row": b_row,
            "q_col": q_col, "q_row": q_row, "box": box,
            "fixed": qp.fixed.astype(np.int32)}
    reals = {"A": A, "B": B, "d": qp.d, "Q": Q, "q": qp.q, "R": qp.R,
             "g": qp.g, "scale": scale, "lo": qp.lo, "hi": qp.hi}
    return {k: np.ascontiguousarray(v, dtype=np.int32) for k, v in
            ints.items()} | {k: np.ascontiguousarray(v, dtype=real)
                             for k, v in reals.items()}


#: The problem's arrays in rqp_problem's order.
_FIELDS = ("a_col", "a_row", "b_col", "b_row", "q_col", "q_row", "A", "B",
           "d", "Q", "q", "R", "g", "box", "scale", "lo", "hi", "fixed")


def solve_c(lib: ctypes.CDLL, qp: StageQP,
            working: dict[tuple[int, int], int] | None = None,
            max_iter: int = NO_CAP, precision: str = "double",
            box: np.ndarray | None = None, masks: Masks | None = None
            ) -> dict:
    """rqp_solve on one QP through ``lib`` (`host_library`), from the
    QP's start and the warm boxes ``working`` (``box``: the boxes'
    components given instead of `boxes`'; ``masks``: A's and B's
    patterns, a build's with generated products): ``U``, ``X``, ``side``
    (N, n_b), ``lam``, ``status``, ``iterations`` and ``stages``."""
    real = np.float32 if precision == "single" else np.float64
    N, nx, nu, nb = qp.dims
    arr = _arrays(qp, real, masks)
    if box is not None:
        arr["box"] = np.ascontiguousarray(box, dtype=np.int32)
    prob = _Problem(N, nx, nu, nb, *(arr[k].ctypes.data for k in _FIELDS))
    U = np.ascontiguousarray(qp.u0, dtype=real)
    X = np.ascontiguousarray(qp.x0, dtype=real)
    side = np.zeros((N, nb), dtype=np.int8)
    for (k, b), s in (working or {}).items():
        side[k, b] = s
    lam = np.zeros((N, nb), dtype=real)
    w = np.zeros(lib.rqp_work_size(N, nx, nu, nb), dtype=real)
    iw = np.zeros(lib.rqp_iwork_size(N, nx, nu, nb), dtype=np.int32)
    its, stages = ctypes.c_int(0), ctypes.c_long(0)
    status = lib.rqp_solve(ctypes.byref(prob), U.ctypes.data, X.ctypes.data,
                           side.ctypes.data, lam.ctypes.data, int(max_iter),
                           TOL[precision], w.ctypes.data,
                           iw.ctypes.data, ctypes.byref(its),
                           ctypes.byref(stages))
    return {"U": U.astype(float), "X": X.astype(float),
            "side": side.astype(int), "lam": lam.astype(float),
            "status": STATUS[status], "iterations": its.value,
            "stages": stages.value}


def problems(c: dict, cap: int, progress: bool = False) -> list[dict]:
    """The QPs of ``c`` (`collect` with ``stagewise=True``) whose start
    keeps every box, each with the warm working set the twin's loop
    capped at ``cap`` (0: none) carried to it (`riccati_qps.carried`),
    and the twin's answer uncapped from there (``U_ref``); ``progress``:
    a progress bar over the QPs."""
    return [{"qp": q["stage"], "warm": warm,
             "U_ref": solve(q["stage"], warm, max_iter=NO_CAP)["U"]}
            for q, warm, r in carried(c, cap, progress) if r is not None]


def write_problems(path: Path, probs: list[dict], caps: list[int],
                   precision: str = "double", masks: Masks | None = None
                   ) -> None:
    """The QPs as the target driver reads them: a header (count, N, n_x,
    n_u, n_b, caps), then per QP its arrays (reals little-endian, the
    boxes' indices and the fixed inputs as int32, the warm sides int8)."""
    real = "<f4" if precision == "single" else "<f8"
    N, nx, nu, nb = probs[0]["qp"].dims
    with open(path, "wb") as fh:
        fh.write(struct.pack("<6i", len(probs), N, nx, nu, nb, len(caps)))
        fh.write(struct.pack(f"<{len(caps)}i", *caps))
        for p in probs:
            qp = p["qp"]
            arr = _arrays(qp, real, masks)
            fh.write(struct.pack("<3i", arr["a_row"].size, arr["b_row"].size,
                                 arr["q_row"].size))
            for key in _FIELDS:
                fh.write(arr[key].astype("<i4" if arr[key].dtype == np.int32
                                         else real).tobytes())
            for v in (qp.u0, qp.x0):
                fh.write(np.ascontiguousarray(v, dtype=real).tobytes())
            side = np.zeros((N, nb), dtype=np.int8)
            for (k, b), s in p["warm"].items():
                side[k, b] = s
            fh.write(side.tobytes())
            fh.write(np.ascontiguousarray(p["U_ref"], dtype=real).tobytes())


_MAIN = r"""
#include "rqp.h"

#define N_ @N@
#define NX @NX@
#define NU @NU@
#define NB @NB@
#define CMAX 8
static rqp_real A[N_ * NX * NX], B[N_ * NX * NU], d[N_ * NX], Q[N_ * NX * NX],
    q[N_ * NX], R[NU], g[N_ * NU], scale[NB], lo[N_ * NB], hi[N_ * NB],
    U0[N_ * NU], X0[N_ * NX], Uref[N_ * NU], U[N_ * NU], X[N_ * NX],
    lam[N_ * NB], w[@WORK@];
static int a_col[NX + 1], a_row[NX * NX], b_col[NU + 1], b_row[NX * NU],
    q_col[NX + 1], q_row[NX * NX], box[NB], fixed[NU], iw[@IWORK@];
static signed char side0[N_ * NB], side[N_ * NB];

#define READ(p, n) (fread(p, sizeof *(p), (size_t)(n), fh) == (size_t)(n))

int main(void) {
  int head[6], caps[CMAX], nnz[3], qn, c, i, its, status;
  long stages;
  FILE* fh;
  rqp_problem qp = {N_, NX, NU, NB, a_col, a_row, b_col, b_row, q_col, q_row,
                    A, B, d, Q, q, R, g, box, scale, lo, hi, fixed};
  driver_init();
  stack_paint();
  fh = fopen("qps.bin", "rb");
  if (!fh || !READ(head, 6) || head[1] != N_ || head[2] != NX ||
      head[3] != NU || head[4] != NB || head[5] > CMAX ||
      !READ(caps, head[5])) {
    printf("ERROR reading qps.bin\n");
    return 1;
  }
  for (qn = 0; qn < head[0]; ++qn) {
    if (!READ(nnz, 3) || nnz[0] > NX * NX || nnz[1] > NX * NU ||
        nnz[2] > NX * NX || !READ(a_col, NX + 1) || !READ(a_row, nnz[0]) ||
        !READ(b_col, NU + 1) || !READ(b_row, nnz[1]) ||
        !READ(q_col, NX + 1) || !READ(q_row, nnz[2]) ||
        !READ(A, N_ * nnz[0]) || !READ(B, N_ * nnz[1]) || !READ(d, N_ * NX) ||
        !READ(Q, N_ * nnz[2]) || !READ(q, N_ * NX) || !READ(R, NU) ||
        !READ(g, N_ * NU) || !READ(box, NB) || !READ(scale, NB) ||
        !READ(lo, N_ * NB) || !READ(hi, N_ * NB) || !READ(fixed, NU) ||
        !READ(U0, N_ * NU) || !READ(X0, N_ * NX) || !READ(side0, N_ * NB) ||
        !READ(Uref, N_ * NU)) {
      printf("ERROR reading QP %d\n", qn);
      return 1;
    }
    for (c = -1; c < head[5]; ++c) {
      double t0, t1, err = 0;
      for (i = 0; i < N_ * NU; ++i) U[i] = U0[i];
      for (i = 0; i < N_ * NX; ++i) X[i] = X0[i];
      for (i = 0; i < N_ * NB; ++i) side[i] = side0[i];
      t0 = clock_now();
      status = rqp_solve(&qp, U, X, side, lam, c < 0 ? 0 : caps[c],
                         (rqp_real)@TOL@, w, iw, &its, &stages);
      t1 = clock_now();
      for (i = 0; i < N_ * NU; ++i) {
        double e = fabs((double)U[i] - (double)Uref[i]);
        if (e > err) err = e;
      }
      printf("QP %d cap=%d ticks=%lu iterations=%d status=%d stages=%ld "
             "err=%.3e\n", qn, c < 0 ? -1 : caps[c], (unsigned long)(t1 - t0),
             its, status, stages, err);
    }
  }
  fclose(fh);
  printf("STACK %ld\n", stack_used());
  return 0;
}
"""


def run_target(probs: list[dict], caps: list[int], target: str,
               precision: str, timeout: float = 3600.0,
               generated: bool = False) -> list[dict]:
    """Build rqp.c and its driver for ``target`` and run it on qemu; per
    QP and cap (``-1``: the warm working set's recursion alone) its
    ``instructions``, ``iterations``, ``status``, ``stages`` and ``err``
    (max |δu − the twin's uncapped δu|). ``generated``: with the stage
    products generated for the QPs' patterns (`products_source`)."""
    N, nx, nu, nb = probs[0]["qp"].dims
    caps = [NO_CAP if cap == 0 else cap for cap in caps]
    work, iwork = _sizes(N, nx, nu, nb)
    masks = common_masks([p["qp"] for p in probs])
    with tempfile.TemporaryDirectory() as tmp:
        write_problems(Path(tmp) / "qps.bin", probs, caps, precision, masks)
        data = (Path(tmp) / "qps.bin").read_bytes()
    main = _MAIN
    for key, v in (("@N@", N), ("@NX@", nx), ("@NU@", nu), ("@NB@", nb),
                   ("@WORK@", work), ("@IWORK@", iwork),
                   ("@TOL@", repr(TOL[precision]))):
        main = main.replace(key, str(v))
    gen = products_source(masks, precision) if generated else ""
    out = run_driver(main, RQP_DIR / "rqp.c", data, target, precision,
                     RQP_SINGLE, timeout, sizes_flags(nx, nu)
                     + ((PRODUCTS_FLAG,) if generated else ()), gen)
    return qp_rows(out, STATUS, ("iterations", "stages"))


@functools.lru_cache(maxsize=None)
def _sizes(N: int, nx: int, nu: int, nb: int) -> tuple[int, int]:
    """rqp's work sizes (reals, ints), from a host build of rqp.c."""
    with tempfile.TemporaryDirectory() as tmp:
        lib = host_library(Path(tmp))
        return (lib.rqp_work_size(N, nx, nu, nb),
                lib.rqp_iwork_size(N, nx, nu, nb))


def solver_memory(target: str, precision: str = "double",
                  sizes: tuple[int, int] = (11, 4)) -> dict:
    """rqp.c compiled for ``target`` alone, for ``sizes`` (n_x, n_u; the
    demo craft's by default): its ``flash`` (text + rodata, bytes) and
    the deepest ``stack`` from `rqp_solve` (gcc's frames and call graph),
    whether ``bounded``, and the ``library`` calls."""
    return emulated_solver.solver_memory(RQP_DIR / "rqp.c", "rqp_solve",
                                         target, precision, RQP_SINGLE,
                                         sizes_flags(*sizes))


def _stats(v) -> str:
    a = np.asarray(v, dtype=float)
    if not a.size:
        return "–"
    return (f"{np.median(a):,.0f} / {np.percentile(a, 99):,.0f} / "
            f"{a.max():,.0f}")


def products_memory(masks: Masks, target: str, precision: str) -> dict:
    """The generated stage products (`products_source`) for ``target``:
    their ``flash`` (text + rodata, bytes) and deepest ``stack``."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "rqp_products.c"
        src.write_text(products_source(masks, precision))
        return emulated_solver.solver_memory(src, "rqp_products", target,
                                             precision, RQP_SINGLE)


def report(probs: list[dict], rows: list[dict], caps: list[int],
           target: str, precision: str, generated: bool = False) -> str:
    """The tables of `main`."""
    N, nx, nu, nb = probs[0]["qp"].dims
    lines = [f"{len(probs)} QPs at N = {N} ({nx} states, {nu} inputs, {nb} "
             f"boxes a stage), {target}, {precision}; median / p99 / "
             f"worst:", "",
             "| cap | instructions per QP | iterations | recursions "
             "(stages / N) | max \\|δu − twin's\\| |", "|---|---:|---:|---:|---:|"]
    for cap in [-1] + [NO_CAP if c == 0 else c for c in caps]:
        r = [x for x in rows if x["cap"] == cap]
        name = ("the warm set's recursion alone" if cap < 0 else
                "none" if cap == NO_CAP else str(cap))
        err = max((x["err"] for x in r if x["status"] == "optimal"),
                  default=float("nan"))
        lines.append(
            f"| {name} | {_stats([x['instructions'] for x in r])} | "
            f"{_stats([x['iterations'] for x in r])} | "
            f"{_stats([x['stages'] / N for x in r])} | {err:.1e} |")
    mem = solver_memory(target, precision, (nx, nu))
    work, iwork = _sizes(N, nx, nu, nb)
    size = 4 if precision == "single" else 8
    if generated:
        gen = products_memory(common_masks([p["qp"] for p in probs]),
                              target, precision)
        lines += ["", f"The generated stage products: {gen['flash']:,} "
                  f"bytes of flash, stack {gen['stack']:,} bytes (beside "
                  f"rqp.c's, whose own loops for them are then unused)."]
    lines += ["", f"rqp.c on the {target}: {mem['flash']:,} bytes of flash, "
              f"work {work * size + iwork * 4:,} bytes ({work:,} reals, "
              f"{iwork:,} ints), stack {mem['stack']:,} bytes"
              f"{'' if mem['bounded'] else ' (not bounded)'}"
              f"{' + ' + ', '.join(mem['library']) if mem['library'] else ''}."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_loop_arguments(ap)
    ap.add_argument("--target", default="cortex-m7", choices=sorted(CORES))
    ap.add_argument("--precision", default="double",
                    choices=("double", "single"))
    ap.add_argument("--generated", action="store_true",
                    help="the stage products as CasADi straight-line code "
                    "for the craft's patterns")
    ap.add_argument("--caps", default="8,0",
                    help="iteration caps, 0 for none (default 8,0); the "
                    "first is the warm sets' loop's")
    args = ap.parse_args(argv)
    caps = [int(c) for c in args.caps.split(",")]
    c = collect(args.horizon, args.draws, args.steps, args.seed,
                args.spacecraft, stagewise=True)
    probs = problems(c, caps[0], progress=True)
    rows = run_target(probs, caps, args.target, args.precision,
                      generated=args.generated)
    print(report(probs, rows, caps, args.target, args.precision,
                 args.generated))


if __name__ == "__main__":
    main()
