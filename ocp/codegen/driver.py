"""The C test driver, Makefile and README written beside an export."""

from __future__ import annotations

import math
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import casadi as ca
import numpy as np
from ocp.models.rigid import SpacecraftModel
from ocp.mpc.primal_qp import PQP_DIR, max_iter_of
from ocp.mpc.riccati_qp import RQP_DIR, max_iter_of as rqp_max_iter_of
from .checks import loop_plan, plan_length
from .daqp_static import DAQP_DIR
from .loop_starts import loop_start_source
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


def _driver_sizes(fns: dict[str, ca.Function], repeats: int,
                  loop_steps: int) -> str:
    """``#define``s of the driver's static arrays (no heap in the driver).

    The largest ``*_work`` sizes of the exported functions (CasADi writes
    the Functions' ``sz_arg`` ... ``sz_w`` there; the driver checks them
    at run time), calls timed, and the closed loop's vectors.
    """
    def most(get, floor=1):
        return max([floor] + [int(get(f)) for f in fns.values()])
    loop = max([1] + [max(f.nnz_in(i) for i in (0, 3, 5))
                      for n, f in fns.items() if n.startswith("mpc")]
               + [f.nnz_out(0) for n, f in fns.items()
                  if n.startswith("mpc")])
    return "\n".join([
        f"#define ADCS_SZ_ARG {most(lambda f: max(f.sz_arg(), f.n_in()), 8)}",
        f"#define ADCS_SZ_RES {most(lambda f: max(f.sz_res(), f.n_out()), 8)}",
        f"#define ADCS_SZ_IW {most(lambda f: f.sz_iw())}",
        f"#define ADCS_SZ_W {most(lambda f: f.sz_w())}",
        f"#define ADCS_MAX_CALLS {max(repeats, loop_steps, 3)}",
        f"#define ADCS_LOOP_N {loop}"])


def _driver_source(fns: dict[str, ca.Function],
                   samples: dict[str, list[np.ndarray]], repeats: int,
                   model: SpacecraftModel | None, dt: float,
                   precision: str = "double",
                   head: str | None = None,
                   loop: dict | None = None,
                   starts: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> str:
    """Text of a driver: ``head`` (the host's by default, or a target's
    from `ocp.codegen.target`), the shared body with its static arrays,
    the calls, the loops (length and check: ``loop``, default
    `ocp.codegen.checks.loop_plan` of ``model``, which may be None when
    ``loop`` is given); sample inputs as float literals in single
    ``precision``. ``starts``: ``(x0s (K, n_x), qf (4,))``, one loop per
    start of every MPC step (`ocp.codegen.loop_starts`) instead of the
    sample's one."""
    if loop is None:
        loop = loop_plan(model, samples, dt, precision=precision)
    steps = loop["steps"]
    lines = [_DRIVER_HEAD if head is None else head,
             _DRIVER_BODY.replace("/* @SIZES@ */", _driver_sizes(
                 fns, repeats, steps))]
    calls = []
    for name, f in fns.items():
        for j in range(f.n_out()):
            lines.append(f"static casadi_real {name}_out{j}"
                         f"[{max(f.nnz_out(j), 1)}];")
        nnz = ", ".join(str(f.nnz_out(j)) for j in range(f.n_out()))
        lines.append(f"static const int {name}_nnz_out[] = {{{nnz}}};")
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
                f"    bad |= time_call(\"{case}\", {name}, {name}_work, "
                f"{name}_checkout, {name}_release, a, {len(ins)}, r, "
                f"{f.n_out()}, {name}_nnz_out, {reps}, {f.nnz_out(0)}); }}")
    body = "\n".join(lines)
    loops = []
    if starts is not None:
        decl, call = loop_start_source(fns, *starts, loop, precision)
        body += "\n" + decl
        loops.append(call)
    for name in fns if starts is None else ():
        if name.startswith("mpc"):
            f = fns[name]
            loops.append(
                f"  bad |= closed_loop(\"{name}\", {name}, {name}_work, "
                f"{name}_checkout, {name}_release, {name}_in0, {name}_in1,"
                f" {f.nnz_in(0)}, {f.nnz_in(3)}, {f.nnz_in(5)}, "
                f"{f.nnz_out(0)}, {plan_length(f, loop)}, {loop['dt']!r}, "
                f"{steps}, "
                f"{math.degrees(loop['final_error_tol'])!r}, "
                f"{float(loop['violation_tol'])!r});")
    main = ("int main(void) {\n  int bad = 0;\n  driver_init();\n"
            + "\n".join(calls) + "\n" + "\n".join(loops)
            + "\n  fflush(stdout);\n  return bad;\n}\n")
    return body + "\n" + (_CLOSED_LOOP if loops else "") + main


_DRIVER_HEAD = _template("driver_head.c")


_DRIVER_BODY = _template("driver_body.c")


_CLOSED_LOOP = _template("closed_loop.c")


_MAKEFILE = _template("Makefile.in")


_CMAKELISTS = _template("CMakeLists.txt.in")


def write_build_files(out, solver_sources, cflags=()) -> None:
    """The Makefile and CMakeLists.txt: relative paths, C99 and libm;
    ``cflags``: defines every build needs (DAQP's and pqp's float
    builds); ``solver_sources`` the C sources beside the generated one
    (``daqp/``, ``pqp/``, ``rqp/``), each folder named with its
    licence."""
    rel = [p.relative_to(out).as_posix() for p in solver_sources]
    notes = [f"{d}/: {what}, {d}/LICENSE" for d, what in (
        (DAQP_DIR, "DAQP, MIT licence"),
        (PQP_DIR, "the toolbox's primal active set, BSD-3-Clause"),
        (RQP_DIR, "the toolbox's Riccati active set, BSD-3-Clause"))
        if any(r.startswith(f"{d}/") for r in rel)]
    note = "; ".join(notes) or "the QPs are generated inline"
    (out / "Makefile").write_text(_MAKEFILE.format(
        src=SOURCE, opt=" ".join(OPT_FLAGS), solver_note=note,
        solver_sources="".join(f" \\\n  {r}" for r in rel),
        defines=" ".join(cflags)))
    (out / "CMakeLists.txt").write_text(_CMAKELISTS.format(
        src=SOURCE, opt=" ".join(OPT_FLAGS), solver_note=note,
        solver_sources_cmake="".join(f"\n  {r}" for r in rel),
        defines=" ".join(f[2:] for f in cflags)))


def _solver_text(fns, plugin, method, patched, duty_plugin) -> str:
    """The README's sentences on the QP solvers in the source."""
    daqp = ("DAQP (its C sources and MIT licence are in `daqp/`, "
            "compiled with the rest)")
    if method == "closed form":
        solver_text = ("`wheel_qp` solves its QP exactly in closed form "
                       "(3 or 4 working wheels: the equality leaves a "
                       "point or a segment).")
    elif plugin == "daqp":
        solver_text = f"`wheel_qp` calls {daqp} when its fast path cannot."
    else:
        solver_text = ("`wheel_qp` calls CasADi's qrqp, generated inline, "
                       "when its fast path cannot.")
    if duty_plugin is not None and "duty_qp" in fns:
        solver_text += (
            " `duty_qp` solves the duty QP reduced to its free directions "
            "with " + (daqp if duty_plugin == "daqp" else
                       "qrqp (generated inline)") + " after testing the "
            "demand against the set the thrusters can produce, and "
            "certifies the point by its KKT conditions; its `status` "
            "output is 0 optimal, 1 momentum bound relaxed, 2 infeasible, "
            "3 invalid input, 4 solver failed (duties 0 unless 0 or 1).")
    if patched:
        solver_text += (" qrqp is edited to reuse its KKT factorization "
                        "while the active set does not change within a "
                        "solve (`ocp.codegen.patch_qrqp`; same results).")
    return solver_text


def _memory_text(static_bytes: int) -> str:
    """The README's paragraph on memory (no heap)."""
    heap = ("No function allocates: all memory is the caller's `w`/`iw` "
            "arrays (sizes from `f_work`) or static. ")
    if static_bytes:
        heap += (
            "CasADi's DAQP runtime would set DAQP's workspace up on the "
            "heap on every solve; here it is edited "
            "(`ocp.codegen.patch_daqp_static`) to lay it out in static "
            f"arrays sized for each QP at generation time ({static_bytes}"
            " bytes in all, per memory slot: `CASADI_MAX_NUM_THREADS`, "
            "default 1), and DAQP's own allocating functions are not in "
            "`daqp/api.c`. A small QP (such as `duty_qp`'s, whose Hessian "
            "and rows are constants) keeps its setup in those arrays from "
            "one call to the next while its matrices stay the same: its "
            "first call costs more than the later ones, so a flight build "
            "makes one call at initialisation. ")
    heap += ("Check an object build with `nm`: no undefined `malloc`, "
             "`calloc`, `realloc` or `free`. `main.c` uses no heap either "
             "(static arrays, a static `stdout` buffer).")
    return heap


def _wrappers(solver_sources: list[str], solver: str,
              max_iter: Callable[[str], int]) -> tuple[str, int]:
    """``(names, cap)`` of the ``solver`` wrappers among the sources:
    their paths quoted for the README and their smallest iteration cap
    (``("", 0)`` if none)."""
    wrappers = [s for s in solver_sources
                if s.startswith(f"{solver}/adcs_{solver}_")]
    if not wrappers:
        return "", 0
    return (", ".join(f"`{w}`" for w in wrappers),
            min(max_iter(Path(w).stem) for w in wrappers))


def _pqp_text(solver_sources: list[str]) -> str:
    """The README's paragraph on the pqp wrappers among the sources ("" if
    none)."""
    wrappers, cap = _wrappers(solver_sources, "pqp", max_iter_of)
    if not wrappers:
        return ""
    return (
        " The condensed MPC steps solve their QP with `pqp/pqp.c`, the "
        "toolbox's primal active set (BSD-3-Clause, `pqp/LICENSE`), "
        f"called through {wrappers} "
        "(CasADi's calling convention): started from δu = 0 on the "
        f"shifted plan and the last step's active set, at most {cap} "
        "iterations, the caller's work only. Where that start breaks a "
        "bound (a defect, or a measured rate beyond its bound), a phase "
        "one first moves it to the nearest point that keeps every "
        f"bound (at most the QP's rows + {cap} iterations; where it "
        "finds none, the step's `qp_kkt` is infinite and the step is "
        "refused). A QP stopped at that cap returns a point that keeps "
        "every bound and lowers the QP's cost: the step applies it, its "
        "`qp_kkt` is then that point's certificate (bound violation and "
        "cost rise, not the KKT residual) and its output `qp_capped` is "
        "1.")


def _rqp_phase_one(wrappers: str) -> str:
    """The README's sentence on rqp's phase one (its wrappers ``_p1``)."""
    if "_p1." in wrappers:
        return ("Where the start breaks a box (a rate box, from the "
                "linearisation's defects) the wrapper runs a phase one "
                "first: the broken boxes' bounds widened to the start and "
                "a penalty pulling each to its bound, solved by rqp over "
                "the stages from the first broken one alone (the earlier "
                "stages keep the start; where a box stays beyond its "
                "bound, from stages ever earlier, the span doubled, up to "
                "stage 0), in at most n_b (N - j) + the cap iterations "
                "from stage j; from the point that keeps every box the "
                "QP itself is solved, capped as without it. Where a box "
                "stays beyond its bound the step's `qp_kkt` is infinite "
                "and the step is refused.")
    return ("Exported without a rate bound it has no phase one: where the "
            "start breaks a box (a measured wheel momentum beyond its "
            "bound), the step's `qp_kkt` is infinite and the step is "
            "refused.")


def _rqp_text(solver_sources: list[str]) -> str:
    """The README's paragraph on the rqp wrappers among the sources ("" if
    none)."""
    wrappers, cap = _wrappers(solver_sources, "rqp", rqp_max_iter_of)
    if not wrappers:
        return ""
    return (
        " The stage-wise MPC steps solve their QP with `rqp/rqp.c`, the "
        "toolbox's Riccati active set (BSD-3-Clause, `rqp/LICENSE`), "
        f"compiled inside {wrappers} for "
        "the QP's sizes (CasADi's calling convention; rqp.c itself is "
        "not compiled alone): started from the shifted plan and the last "
        f"step's working set, at most {cap} iterations of one Riccati "
        "recursion each, memory linear in the horizon, the caller's work "
        f"only. {_rqp_phase_one(wrappers)} A QP "
        "stopped at that cap "
        "returns a point that keeps every box and lowers the QP's cost: "
        "the step applies it, its `qp_kkt` is then that point's "
        "certificate (box violation and cost rise) and its output "
        "`qp_capped` is 1.")


def _readme(fns: dict[str, ca.Function],
            samples: dict[str, list[np.ndarray]], plugin: str = "qrqp",
            solver_sources=(), method: str = "conic",
            patched: bool = False, duty_plugin: str | None = None,
            static_bytes: int = 0, precision: str = "double") -> str:
    rows = []
    for name, f in fns.items():
        ins = ", ".join(f"{f.name_in(i)}[{f.nnz_in(i)}]"
                        for i in range(f.n_in()))
        outs = ", ".join(f"{f.name_out(i)}[{f.nnz_out(i)}]"
                         for i in range(f.n_out()))
        rows.append(f"| `{name}` | {ins} | {outs} |")
    opt = " ".join(OPT_FLAGS)
    build_cmd = " ".join(["cc", opt, "-std=c99 -o adcs_driver main.c",
                          f"{SOURCE}.c", *solver_sources, "-lm"])
    solver_text = _solver_text(fns, plugin, method, patched, duty_plugin)
    solver_text += _pqp_text(solver_sources) + _rqp_text(solver_sources)
    heap = _memory_text(static_bytes)
    version = ca.__version__  # type: ignore[attr-defined]  # not in stubs
    return f"""# Generated ADCS C code

Written by `ocp.codegen.export.export_c` (CasADi {version} code
generation). `{SOURCE}.c` / `{SOURCE}.h` are C99. {solver_text}

## Build

Everything the build reads is in this folder: a C99 compiler and libm
are all it needs (no include path, no prebuilt library).

* `make run`: build and run the driver (`make lib`: `lib{SOURCE}.a`;
  `make shared`: `{SOURCE}.so`). `CC`, `CFLAGS`, `WARNINGS` (default
  `-Wall -Wextra -Werror`), `LDLIBS` and `AR` may be overridden, e.g.
  `make lib CC=arm-none-eabi-gcc AR=arm-none-eabi-ar CFLAGS="-O2
  -mcpu=cortex-m7"`. A flight build of its own compiles the Makefile's
  `ADCS_SOURCES` with its flags.
* CMake: `add_subdirectory()` this folder and link the target
  `adcs_codegen` (options `ADCS_WARNINGS`, `ADCS_DRIVER`).
* `casadi_int` is `long long` in a host export (what `casadi.external`
  expects) and `int` in a Cortex-M export (`--target`: its sparsity
  patterns take half the flash). Do not load a Cortex-M export's `make
  shared` library with `casadi.external`: it assumes `long long` and
  crashes. For Python, export for the host.
* By hand: `{build_cmd} && ./adcs_driver`.

## Memory

{heap}

## Calling convention

CasADi's: for a function `f`, query work sizes with
`f_work(&sz_arg, &sz_res, &sz_iw, &sz_w)`, provide arrays of those sizes
(static in a flight build), take a memory slot with
`mem = f_checkout()`, call `f(arg, res, iw, w, mem)` (arg/res arrays of
pointers to dense column vectors) and `f_release(mem)`. `main.c` does
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
zero); their outputs `iterations` counts the SQP iterations and
`qp_kkt` is the last QP point's KKT residual (its optimality
certificate: a step above 1e-6 is not its QP's solution; check it).

Their worst case is bounded by construction: `mpc_cond_rti_step` makes
one SQP iteration, `mpc_cond_step` at most the `mpc_max_iter` given to
`export_c` (default 50; 8 is enough for the slew's after the cold
step); each iteration solves at most three QPs (the bounds alone, then
the rows, a cold restart if the warm start fails), each at most 1000
DAQP iterations (`ocp.mpc.condensed_qp.QP_ITER_LIMIT`). A QP stopped by
that limit shows in `qp_kkt`, never silently.
""" + (README_SINGLE if precision == "single" else "")
