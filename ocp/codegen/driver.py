"""The C test driver, Makefile and README written beside an export."""

from __future__ import annotations

from importlib import resources

import casadi as ca
import numpy as np
from ocp.models.rigid import SpacecraftModel
from .precision import README_SINGLE
from .result import OPT_FLAGS, SOURCE


def _template(name: str) -> str:
    """Text of a C or Makefile template shipped in ``templates/``."""
    return (resources.files("ocp.codegen") / "templates" / name).read_text(
        encoding="utf-8")


# ------------------------------------------------------------------ C text
def _c_array(name: str, values, suffix: str = "") -> str:
    v = np.asarray(values, dtype=float).ravel()
    if suffix:          # float: 9 digits round-trip, a point before "f"
        body = ", ".join(f"{float(x):#.9g}f" for x in v.astype(np.float32))
    else:
        body = ", ".join(f"{x:.17g}" for x in v)
    body = body or "0"
    return f"static casadi_real {name}[{max(v.size, 1)}] = {{{body}}};"


def _driver_source(fns: dict[str, ca.Function],
                   samples: dict[str, list[np.ndarray]], repeats: int,
                   model: SpacecraftModel, dt: float,
                   precision: str = "double") -> str:
    lines = [_DRIVER_HEAD]
    calls = []
    for name, f in fns.items():
        for j in range(f.n_out()):
            lines.append(f"static casadi_real {name}_out{j}"
                         f"[{max(f.nnz_out(j), 1)}];")
        res = ", ".join(f"{name}_out{j}" for j in range(f.n_out()))
        reps = repeats if not name.startswith("mpc") else max(
            repeats // 100, 3)
        # the function's sample, then extra cases "name:label"
        cases = [name] + [k for k in samples if k.startswith(f"{name}:")]
        for case in cases:
            ins = samples[case]
            tag = case.replace(":", "_")
            for i, a in enumerate(ins):
                lines.append(_c_array(f"{tag}_in{i}", a, "f" if
                                      precision == "single" else ""))
            arg = ", ".join(f"{tag}_in{i}" for i in range(len(ins)))
            calls.append(
                f"  {{ const casadi_real* a[] = {{{arg}}};\n"
                f"    casadi_real* r[] = {{{res}}};\n"
                f"    time_call(\"{case}\", {name}, {name}_work, "
                f"{name}_checkout, {name}_release, a, {len(ins)}, r, "
                f"{f.n_out()}, {reps}, {f.nnz_out(0)}); }}")
    body = "\n".join(lines)
    loops = []
    for name in fns:
        if name.startswith("mpc"):
            f = fns[name]
            loops.append(
                f"  closed_loop(\"{name}\", {name}, {name}_work, "
                f"{name}_checkout, {name}_release, {name}_in0, {name}_in1,"
                f" {f.nnz_in(0)}, {f.nnz_in(3)}, {f.nnz_in(5)}, "
                f"{model.nu}, {dt!r}, 80);")
    main = ("int main(void) {\n  realtime_heap();\n" + "\n".join(calls)
            + "\n"
            + "\n".join(loops) + "\n  return 0;\n}\n")
    return body + "\n" + (_CLOSED_LOOP if loops else "") + main


_DRIVER_HEAD = _template("driver_head.c")


_CLOSED_LOOP = _template("closed_loop.c")


_MAKEFILE = _template("Makefile.in")


def _readme(fns: dict[str, ca.Function],
            samples: dict[str, list[np.ndarray]], plugin: str = "qrqp",
            cflags=(), ldflags=("-lm",), method: str = "conic",
            patched: bool = False, duty_plugin: str | None = None,
            precision: str = "double") -> str:
    rows = []
    for name, f in fns.items():
        ins = ", ".join(f"{f.name_in(i)}[{f.nnz_in(i)}]"
                        for i in range(f.n_in()))
        outs = ", ".join(f"{f.name_out(i)}[{f.nnz_out(i)}]"
                         for i in range(f.n_out()))
        rows.append(f"| `{name}` | {ins} | {outs} |")
    opt = " ".join(OPT_FLAGS)
    build_cmd = " ".join(["gcc", opt, *cflags, "-o adcs_driver main.c",
                          f"{SOURCE}.c", *ldflags])
    if method == "closed form":
        solver_text = ("`wheel_qp` solves its QP exactly in closed form "
                       "(3 or 4 working wheels: the equality leaves a "
                       "point or a segment); the other QPs use CasADi's "
                       "qrqp, generated inline, so only `-lm` is needed.")
    elif plugin == "daqp":
        solver_text = ("`wheel_qp` is solved by DAQP: the source includes "
                       "`daqp/api.h` and links the static `libdaqpstat.a` "
                       "that the casadi wheel ships (paths in the "
                       "Makefile's `SOLVER_CFLAGS` / `SOLVER_LIBS`); the "
                       "other QPs use CasADi's qrqp, generated inline. "
                       "Export with `wheel_qp_plugin=\"qrqp\"` for a "
                       "self-contained source.")
    else:
        solver_text = ("The QPs are solved by CasADi's qrqp, generated "
                       "inline, so only `-lm` is needed.")
    if duty_plugin is not None and "duty_qp" in fns:
        solver_text += (
            " `duty_qp` solves the duty QP reduced to its free directions "
            f"with {duty_plugin} (" + ("DAQP: the source includes "
            "`daqp/api.h` and links `libdaqpstat.a`" if duty_plugin ==
            "daqp" else "generated inline") + ") after testing the demand "
            "against the set the thrusters can produce, and certifies the "
            "point by its KKT conditions; its `status` output is 0 "
            "optimal, 1 momentum bound relaxed, 2 infeasible, 3 invalid "
            "input, 4 solver failed (duties 0 unless 0 or 1).")
    if patched:
        solver_text += (" qrqp is edited to reuse its KKT factorization "
                        "while the active set does not change within a "
                        "solve (`ocp.codegen.patch_qrqp`; same results).")
    return f"""# Generated ADCS C code

Written by `ocp.codegen.export.export_c` (CasADi {ca.__version__} code
generation). `{SOURCE}.c` / `{SOURCE}.h` are C99. {solver_text}

Build and run the driver: `make run` (or
`{build_cmd} && ./adcs_driver`).

Calling convention (CasADi): for a function `f`, query work sizes with
`f_work(&sz_arg, &sz_res, &sz_iw, &sz_w)`, allocate, take a memory slot
with `mem = f_checkout()`, call `f(arg, res, iw, w, mem)` (arg/res arrays
of pointers to dense column vectors) and `f_release(mem)`. `main.c` does
this for every function and times the calls with `clock_gettime`.

Units: SI (N·m, N·m·s, kg·m², rad, s); quaternions scalar-first (w, x,
y, z); wheel torques act on the rotors (the body gets -A m). The QP
outputs `violation` (largest constraint violation of the returned point):
check it, qrqp can report success on a violated point.

| function | inputs | outputs |
|---|---|---|
{chr(10).join(rows)}

The MPC steps shift the previous plan (`z_prev`, multipliers) one
interval, solve by sqpmethod (Gauss–Newton Hessian, qrqp) and return the
command `u` to hold over one sample; feed `z`, `lam_x`, `lam_g` back in
at the next sample. `mpc_rti_step` makes one SQP step per sample.
`mpc_cond_step` / `mpc_cond_rti_step` (when exported) solve the same
problem by the condensed SQP (`ocp.mpc.condensed`: the QP on the controls
only, DAQP started from the active set of `lam_x_prev`; `lam_g` is
zero); their last output `iterations` counts the SQP iterations.
CasADi's DAQP runtime allocates its workspace on every solve: `main.c`
keeps freed memory in the heap (`mallopt`, glibc) so that the timed calls
do not fault pages in; a flight build without an operating-system heap
needs an allocator that does the same.
""" + (README_SINGLE if precision == "single" else "")
