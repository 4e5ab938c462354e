"""A C QP solver and its driver on an emulated Cortex-M core: what
`benchmarks.primal_qp_c` and `benchmarks.riccati_qp_c` share.

`run_driver` builds a driver (its ``main.c`` reads the QPs from a file
by semihosting and prints a line ``QP <i> key=value ...`` per solve)
with the solver's source for the core and runs it under qemu
(``-icount shift=0``: SysTick ticks of 40 instructions, as `adcs export
--target`); `qp_rows` reads those lines; `solver_memory` compiles the
solver alone for its flash and deepest stack.
"""

from __future__ import annotations

import subprocess
import tempfile
from importlib import resources
from pathlib import Path

from ocp.codegen.memory import call_graph, section_sizes, worst_stack
from ocp.codegen.result import OPT_FLAGS
from ocp.codegen.target import (CORES, CROSS_CC, INSTRUCTIONS_PER_TICK,
                                TARGET_WARNINGS, qemu_command, target_head,
                                toolchain_missing)


def _template(name: str) -> str:
    return (resources.files("ocp.codegen") / "templates" / name).read_text(
        encoding="utf-8")


def run_driver(main: str, source: Path, data: bytes, target: str,
               precision: str, define: str, timeout: float = 3600.0,
               extra: tuple[str, ...] = (), generated: str = "") -> str:
    """Build ``main`` (the driver's C after the target head) with the
    solver ``source`` (``define`` set in a float build, ``extra`` flags
    in every build; ``generated``: C compiled beside it) for ``target``,
    run it on qemu with ``data`` as its file ``qps.bin``, and return what
    it printed (RuntimeError where it failed or printed ``ERROR``)."""
    why = toolchain_missing()
    if why:
        raise RuntimeError(why)
    core = CORES[target]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        (out / "qps.bin").write_bytes(data)
        real = "float" if precision == "single" else "double"
        # the driver head's types: no generated code here
        (out / "adcs_codegen.h").write_text(
            f"typedef {real} casadi_real;\ntypedef long long casadi_int;\n")
        (out / "main.c").write_text(target_head() + main)
        for name in ("startup_cortex_m.c", "cortex_m.ld"):
            (out / name).write_text(_template(name))
        if generated:
            (out / "generated.c").write_text(generated)
        flags = [*OPT_FLAGS, *core.cpu_flags, *TARGET_WARNINGS,
                 *([define] if precision == "single" else []), *extra,
                 f"-I{source.parent}"]
        subprocess.run([CROSS_CC, *flags, "main.c", str(source),
                        *(["generated.c"] if generated else []),
                        "startup_cortex_m.c", "-nostartfiles",
                        "--specs=rdimon.specs", "-Tcortex_m.ld",
                        "-Wl,--gc-sections", "-lm", "-o", "solver.elf"],
                       cwd=out, check=True, capture_output=True, text=True)
        proc = subprocess.run(qemu_command(core, "solver.elf"), cwd=out,
                              capture_output=True, text=True,
                              timeout=timeout)
    if proc.returncode != 0 or "ERROR" in proc.stdout:
        raise RuntimeError(f"target driver failed: {proc.stdout[-2000:]}"
                           f"{proc.stderr[-2000:]}")
    return proc.stdout


def qp_rows(stdout: str, status: dict[int, str] | tuple[str, ...],
            ints: tuple[str, ...] = ("iterations",)) -> list[dict]:
    """The driver's lines ``QP <i> cap=… ticks=… status=… err=…`` (and
    the integer fields ``ints``): per solve its ``qp``, ``cap``,
    ``instructions``, ``status`` (named by ``status``), ``err`` and the
    ``ints``."""
    rows = []
    for line in stdout.splitlines():
        if not line.startswith("QP "):
            continue
        part = dict(kv.split("=") for kv in line.split()[2:])
        rows.append({"qp": int(line.split()[1]), "cap": int(part["cap"]),
                     "instructions": int(part["ticks"])
                     * INSTRUCTIONS_PER_TICK,
                     "status": status[int(part["status"])],
                     "err": float(part["err"])}
                    | {k: int(part[k]) for k in ints})
    return rows


def compile_object(source: Path, target: str, precision: str, define: str,
                   out: Path, extra: tuple[str, ...] = ()
                   ) -> subprocess.CompletedProcess:
    """``source`` compiled alone for ``target`` into ``out`` (the flight
    flags and warnings; ``define`` in a float build)."""
    return subprocess.run([CROSS_CC, *OPT_FLAGS, *CORES[target].cpu_flags,
                           *TARGET_WARNINGS,
                           *([define] if precision == "single" else []),
                           *extra, "-c", str(source), "-o", out.name],
                          cwd=out.parent, capture_output=True, text=True)


def undefined_symbols(obj: Path) -> set[str]:
    """The symbols the object ``obj`` calls but does not define (nm)."""
    return set(subprocess.run(["arm-none-eabi-nm", "-u", str(obj)],
                              capture_output=True, text=True,
                              check=True).stdout.split())


def solver_memory(source: Path, entry: str, target: str, precision: str,
                  define: str, extra: tuple[str, ...] = ()) -> dict:
    """``source`` compiled for ``target`` alone: its ``flash`` (text +
    rodata, bytes), the deepest ``stack`` from ``entry`` (gcc's frames
    and call graph, `ocp.codegen.memory.worst_stack`), whether that is
    ``bounded`` and the ``library`` functions it calls (their frames not
    counted)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        obj = out / "solver.o"
        compile_object(source, target, precision, define, obj,
                       ("-fstack-usage", "-fcallgraph-info=su", *extra)
                       ).check_returncode()
        frames, edges = call_graph((out / "solver.ci").read_text())
        sizes = section_sizes(obj, "arm-none-eabi-size")
    stack, bounded, library = worst_stack(entry, frames, edges)
    return {"flash": sizes.get("text", 0) + sizes.get("rodata", 0),
            "stack": stack, "bounded": bounded, "library": library}
