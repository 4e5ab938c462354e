"""C timing of the allocation methods beside the exported exact QP.

Used by ``python -m benchmarks.alloc_methods``: the CasADi methods
(`allocation.methods.symbolic`) and the exact QP's exported ``wheel_qp``
(`allocation.conic_allocator_function` with the export's settings: the
momentum bound at ``dt``, DAQP where CasADi has it, the closed-form fast
path) go into one generated C file, built with gcc -O2 together with a
small driver. The driver times every function on the same demands:
``blocks`` blocks of one call per demand, the median of the per-call
means, in µs.
"""

from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from adcs_common.codegen import compile_c, find_compiler, generate_c
from allocation import WheelArray, conic_allocator_function
from allocation.methods.symbolic import method_functions
from allocation.qp.conic_function import conic_c_flags
from allocation.qp.problem import torque_bounds

#: Sample time of the exported wheel QP's momentum bound [s] (export_c's).
DT = 0.5

_HEAD = """#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "@NAME@.h"
static double now_us(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return 1e6 * (double)t.tv_sec + 1e-3 * (double)t.tv_nsec;
}
static int cmp(const void* a, const void* b) {
  double x = *(const double*)a, y = *(const double*)b;
  return (x > y) - (x < y);
}
static double t_block[@BLOCKS@];
static double checksum = 0.0;
"""

_TIME = """static void time_@F@(void) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  const casadi_real** arg; casadi_real** res; casadi_int* iw;
  casadi_real* w; casadi_real out[@NOUT@];
  int b, k, mem;
  @F@_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  arg = malloc(sizeof(*arg) * (sz_arg > 8 ? sz_arg : 8));
  res = malloc(sizeof(*res) * (sz_res > 8 ? sz_res : 8));
  iw = malloc(sizeof(*iw) * (sz_iw > 1 ? sz_iw : 1));
  w = malloc(sizeof(*w) * (sz_w > 1 ? sz_w : 1));
  for (k = 0; k < (sz_res > 8 ? sz_res : 8); ++k) res[k] = 0;
  res[0] = out;
  mem = @F@_checkout();
  for (b = 0; b < @BLOCKS@; ++b) {
    double t0 = now_us();
    for (k = 0; k < @K@; ++k) {
@ARGS@
      @F@(arg, res, iw, w, mem);
      checksum += out[0];
    }
    t_block[b] = (now_us() - t0) / @K@;
  }
  @F@_release(mem);
  qsort(t_block, @BLOCKS@, sizeof(double), cmp);
  printf("TIME @F@ %.6f\\n", t_block[@BLOCKS@ / 2]);
  free(arg); free(res); free(iw); free(w);
}
"""


def _c_array(name: str, values: np.ndarray) -> str:
    body = ", ".join(f"{x:.17g}" for x in np.asarray(values).ravel())
    return f"static const casadi_real {name}[] = {{{body}}};"


def _driver(name: str, functions: dict[str, ca.Function],
            inputs: dict[str, list[np.ndarray]], blocks: int) -> str:
    """C text: inputs as static arrays, one timing routine a function."""
    parts = [_HEAD.replace("@NAME@", name).replace("@BLOCKS@",
                                                   str(blocks))]
    for c_name, f in functions.items():
        k = inputs[c_name][0].shape[0]
        args = []
        for i, a in enumerate(inputs[c_name]):
            parts.append(_c_array(f"{c_name}_in{i}", a))
            args.append(f"      arg[{i}] = {c_name}_in{i} + "
                        f"(size_t)k * {a.shape[1]};")
        parts.append(_TIME.replace("@F@", c_name).replace(
            "@BLOCKS@", str(blocks)).replace("@K@", str(k)).replace(
            "@NOUT@", str(max(f.nnz_out(0), 1))).replace(
            "@ARGS@", "\n".join(args)))
    calls = "\n".join(f"  time_{n}();" for n in functions)
    parts.append(f"int main(void) {{\n{calls}\n  printf(\"CHECK %g\\n\", "
                 "checksum);\n  return 0;\n}\n")
    return "\n".join(parts)


def exact_qp_function(array: WheelArray) -> ca.Function:
    """Build the exact QP as `export_c` exports it: ``wheel_qp(M, h)``."""
    plugin = "daqp" if ca.has_conic("daqp") else "qrqp"
    return conic_allocator_function(array, dt=DT, plugin=plugin,
                                    name="wheel_qp")


def c_times(array: WheelArray, demands: np.ndarray, blocks: int = 51,
            seed: int = 0) -> dict[str, float] | None:
    """Median time per call in C [µs] of each method and ``wheel_qp``.

    Parameters
    ----------
    array : WheelArray
    demands : numpy.ndarray, shape (K, 3)
        Demands [N·m], one call each per block.
    blocks : int
        Timed blocks (the median is taken over them).
    seed : int
        Seed of the wheel momenta h, uniform in ±h_max/2 (the QP's
        momentum input; the methods get the torque bounds they imply).

    Returns
    -------
    dict or None
        Method name (`allocation.methods.METHODS` keys, and
        ``"exact QP (scale)"`` for ``wheel_qp``) -> µs per call; None
        when there is no C compiler.
    """
    try:
        find_compiler()
    except Exception:           # CompilerNotFound: no C column
        return None
    rng = np.random.default_rng(seed)
    n = array.n_wheels
    h = 0.5 * np.asarray(array.h_max) * rng.uniform(-1, 1, (len(demands), n))
    lo, hi = zip(*[torque_bounds(array, hk, DT)[:2] for hk in h])
    lo, hi = np.array(lo), np.array(hi)
    fns, names = {}, {}
    for label, f in method_functions(array).items():
        fns[f.name()] = f
        names[f.name()] = label
    inputs = {k: [demands, lo, hi] for k in fns}
    fns["wheel_qp"] = exact_qp_function(array)
    names["wheel_qp"] = "exact QP (scale)"
    inputs["wheel_qp"] = [demands, h]
    with tempfile.TemporaryDirectory(prefix="adcs_alloc_c_") as tmp:
        src = generate_c(list(fns.values()), tmp, "methods_c",
                         {"with_header": True})
        drv = Path(tmp) / "driver.c"
        drv.write_text(_driver("methods_c", fns, inputs, blocks))
        flags = conic_c_flags("daqp")
        exe = compile_c([src, drv], Path(tmp) / "driver", opt="-O2",
                        shared=False, flags=[f"-I{tmp}", flags[0]],
                        libs=flags[1:])
        out = subprocess.run([str(exe)], capture_output=True, text=True,
                             check=True, timeout=600).stdout
    times = {m[1]: float(m[2]) for m in re.finditer(
        r"^TIME (\S+) (\S+)$", out, re.M)}
    return {names[k]: v for k, v in times.items()}
