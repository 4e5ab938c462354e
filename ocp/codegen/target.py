"""Cortex-M targets of the C export: cross-compile, run on qemu, count.

`export_c(..., target="cortex-m7")` (or ``"cortex-m4f"``) writes beside
the generated source a bare-metal driver ``main_cortex_m.c`` (the host
driver's calls and closed loops on a SysTick clock), its startup code
``startup_cortex_m.c`` (vector table, FPU enabled before any
floating-point instruction, ``.data`` copied, ``.bss`` cleared) and linker
script ``cortex_m.ld`` (code memory at 0x00000000, RAM at 0x20000000);
`build_target` compiles them with ``arm-none-eabi-gcc`` (C99, ``-Wall
-Wextra -Werror``, ``--specs=rdimon.specs`` semihosting) and writes the
memory report (`ocp.codegen.memory`); `run_target` runs the ELF on
``qemu-system-arm`` (MPS2 board of the core, ``-icount shift=0``) and
returns the driver's figures in instructions.

Counting: with ``-icount shift=0`` qemu advances its clock one nanosecond
per instruction and the board's SysTick counts one tick per 40 of them;
the driver checks that rate on a known loop at start ("CAL" line,
`run_target` raises when it differs). The figures are instruction counts,
deterministic, not cycle counts (qemu models no pipeline, cache or wait
states). The resolution of one call's count is one tick (40
instructions); ``mean`` (total over the calls) is finer.

Functions that call DAQP need its C sources: the casadi wheel's
``libdaqpstat.a`` is built for x86. `daqp_c_sources` lists those the
export folder carries (none until the export vendors DAQP); without them
a target export solves every QP with qrqp (generated inline).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from adcs_common.codegen import CompileError, CompilerNotFound
from adcs_common.exceptions import AdcsError, InvalidValueError
from .checks import (DriverCheckError, driver_verdict, loop_failures,
                     loop_line, parse_loop_line, parse_series_line)
from ocp.mpc.primal_qp import PQP_DIR
from ocp.mpc.riccati_qp import RQP_DIR
from .driver import _template
from .result import OPT_FLAGS, SOURCE, ExportResult

#: Targets of ``export_c(target=...)`` and ``adcs export --target``
#: (aarch64: `ocp.codegen.linux_target`).
TARGETS = ("host", "cortex-m7", "cortex-m4f", "aarch64")

#: Cross compiler and emulator of the Cortex-M targets.
CROSS_CC = "arm-none-eabi-gcc"
QEMU = "qemu-system-arm"

#: SysTick ticks to instructions under ``qemu -icount shift=0`` (MPS2).
INSTRUCTIONS_PER_TICK = 40

#: Flags of every target compile (flight builds: warnings are errors).
TARGET_WARNINGS = ("-std=c99", "-Wall", "-Wextra", "-Werror")

#: Files written into the export folder for a Cortex-M target.
STARTUP, LINKER_SCRIPT, TARGET_DRIVER = (
    "startup_cortex_m.c", "cortex_m.ld", "main_cortex_m.c")


@dataclass(frozen=True)
class CortexM:
    """A Cortex-M core: compiler flags and the qemu board that has it."""

    name: str
    cpu_flags: tuple[str, ...]
    machine: str
    fpu: str


CORES = {
    "cortex-m7": CortexM("cortex-m7", ("-mcpu=cortex-m7", "-mthumb",
                                       "-mfpu=fpv5-d16",
                                       "-mfloat-abi=hard"),
                         "mps2-an500", "double-precision FPU"),
    "cortex-m4f": CortexM("cortex-m4f", ("-mcpu=cortex-m4", "-mthumb",
                                         "-mfpu=fpv4-sp-d16",
                                         "-mfloat-abi=hard"),
                          "mps2-an386", "single-precision FPU: double "
                          "arithmetic in software"),
}


def qemu_command(core: CortexM, elf: str | os.PathLike[str]) -> list[str]:
    """qemu-system-arm's command line running ``elf`` on ``core``'s board:
    semihosting for its output, ``-icount shift=0`` so that SysTick
    counts instructions (`INSTRUCTIONS_PER_TICK`)."""
    return [QEMU, "-M", core.machine, "-nographic", "-semihosting-config",
            "enable=on,target=native", "-icount", "shift=0", "-kernel",
            str(elf)]


def check_target(target: str) -> str:
    """Return ``target`` if it is one of `TARGETS`, else raise."""
    if target not in TARGETS:
        raise InvalidValueError(
            f"target must be one of {TARGETS}, got {target!r}")
    return target


def toolchain_missing(run: bool = True) -> str | None:
    """Why the Cortex-M targets cannot be built (or run) here, or None."""
    missing = [t for t in (CROSS_CC, QEMU if run else None)
               if t and shutil.which(t) is None]
    if missing:
        return (f"needs {' and '.join(missing)} (Debian: apt-get install "
                "gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm)")
    return None


def daqp_c_sources(out_dir: Path) -> tuple[list[Path], list[Path]]:
    """DAQP's C sources and include folders in an export folder.

    A Cortex-M build compiles them with the generated source: the
    export copies them to ``daqp/`` beside it whenever a function calls
    DAQP (empty lists otherwise). The generated source includes
    ``"daqp/api.h"`` and DAQP's files include each other from their own
    folder, so no include folder is needed.
    """
    root = Path(out_dir) / "daqp"
    return sorted(root.glob("*.c")), []


def write_target_files(res: ExportResult, target: str, driver_text: str
                       ) -> ExportResult:
    """Write the startup code, linker script and driver of ``target``."""
    out = res.out_dir
    (out / STARTUP).write_text(_template(STARTUP))
    (out / LINKER_SCRIPT).write_text(_template(LINKER_SCRIPT))
    (out / TARGET_DRIVER).write_text(driver_text)
    srcs, inc = daqp_c_sources(out)
    # the toolbox's primal active set and its wrappers (ocp.mpc.primal_qp)
    srcs += sorted((out / PQP_DIR).glob("*.c"))
    # the Riccati active set's wrappers, each including rqp.c
    srcs += sorted((out / RQP_DIR).glob("adcs_rqp_*.c"))
    extras = {**res.extras, "target": target,
              "c_sources": [str(p) for p in srcs],
              "c_include": [str(p) for p in inc]}
    return ExportResult(**{**res.__dict__, "extras": extras})


def target_head() -> str:
    """The bare-metal driver's head (SysTick clock, stack painting)."""
    return _template("target_head.c")


def _cc(args: list[str], log: list[str], cwd: Path) -> None:
    if shutil.which(CROSS_CC) is None:
        raise CompilerNotFound(f"{CROSS_CC} not found: "
                               f"{toolchain_missing(run=False)}")
    proc = subprocess.run([CROSS_CC, *args], capture_output=True, text=True,
                          cwd=cwd)
    log.append(proc.stderr)
    if proc.returncode != 0:
        raise CompileError(f"{CROSS_CC} failed:\n{proc.stderr[-4000:]}")


def compile_flags(res: ExportResult, core: CortexM) -> list[str]:
    """Flags of every object of a target build (optimisation, core, C99,
    warnings as errors, one section per function and object; the
    export's defines: ``-DDAQP_SINGLE_PRECISION`` in single precision)."""
    inc = [f"-I{p}" for p in res.extras.get("c_include", [])]
    return [*OPT_FLAGS, *core.cpu_flags, *TARGET_WARNINGS,
            "-ffunction-sections", "-fdata-sections", *inc,
            *res.extras.get("cflags", [])]


def link_flags(res: ExportResult, core: CortexM) -> list[str]:
    """Link flags: the core, the linker script, semihosting, no crt0."""
    return [*core.cpu_flags, "-nostartfiles", "--specs=rdimon.specs",
            f"-T{res.out_dir / LINKER_SCRIPT}", "-Wl,--gc-sections"]


def build_target(res: ExportResult, progress: bool = False
                 ) -> ExportResult:
    """Cross-compile the export and its bare-metal driver; memory report.

    Every source (the generated one, DAQP's) is compiled with
    ``-fstack-usage -fcallgraph-info=su`` (stack and call graph for the
    report). Sets
    ``executable`` (the ELF), ``extras["memory"]`` and writes
    ``memory_<target>.json`` (`ocp.codegen.memory.memory_report`).
    """
    from .memory import memory_report

    target = res.extras.get("target", "host")
    if target not in CORES:
        raise InvalidValueError(f"res is not a Cortex-M export ({target!r})")
    core = CORES[target]
    # the compiler runs in the export folder: a relative folder (adcs
    # export --out build) would be looked for inside itself
    res = ExportResult(**{**res.__dict__, "out_dir": res.out_dir.resolve(),
                          "extras": {**res.extras, "c_sources": [
                              str(Path(p).resolve())
                              for p in res.extras["c_sources"]]}})
    out = res.out_dir
    flags = compile_flags(res, core)
    log: list[str] = []
    objs = []
    sources = [out / f"{SOURCE}.c", *map(Path, res.extras["c_sources"])]
    for src in sources:
        obj = out / f"{src.stem}_{target}.o"
        # every unit's frames and calls: DAQP's too (named relative to
        # the folder, so that the .su and .ci files name no machine path)
        _cc([*flags, "-fstack-usage", "-fcallgraph-info=su", "-c",
             os.path.relpath(src, out), "-o", obj.name], log, out)
        objs.append(obj)
    startup = out / f"startup_{target}.o"
    _cc([*flags, "-c", str(out / STARTUP), "-o", str(startup)], log, out)
    elf = out / f"adcs_driver_{target}.elf"
    _cc([*flags, str(out / TARGET_DRIVER), str(startup), *map(str, objs),
         *link_flags(res, core), "-lm", "-o", str(elf)], log, out)
    mem = memory_report(res, core, objs, startup, lambda a: _cc(a, log, out))
    text = "".join(log)
    extras = {**res.extras, "memory": mem, "warnings":
              text.count("warning:"), "warning_text": text}
    return ExportResult(**{**res.__dict__, "executable": elf,
                           "extras": extras})


_TIME = re.compile(r"^TIME (\S+)(?: first_ticks=(\S+))? median_ticks=(\S+) "
                   r"max_ticks=(\S+) calls=(\d+)(?: flag=(\d+))?"
                   r"(?: total_ticks=(\S+))?(?: final_error_deg=(\S+))?"
                   r"(?: max_warm_ticks=(\S+))?")


def run_target(res: ExportResult, timeout: float = 600.0,
               check: bool = True) -> dict[str, dict]:
    """Run the target driver on qemu; return its figures per function.

    Returns
    -------
    dict
        C name -> ``{"first": ..., "median": ..., "max": ..., "mean": ...,
        "calls": ..., "flag": ..., "outputs": [[...], ...], "work":
        (sz_arg, sz_res, sz_iw, sz_w), "stack_measured": bytes}``, counts
        in instructions; ``closed_loop:<name>``: the per-step counts of
        the closed loop (``steps``, in step order), ``max_warm``,
        ``final_error_deg``, ``state`` (the final state) and the check's ``loop_*`` figures (as
        `ocp.codegen.run_driver`). ``_stdout``: the driver's output.

    Raises
    ------
    DriverCheckError
        ``check`` and a closed loop failed its check
        (`ocp.codegen.checks`; its ``times``: the figures).
    """
    target = res.extras.get("target", "host")
    if target not in CORES or res.executable is None:
        raise InvalidValueError("res has no Cortex-M executable: export "
                                "with target=... and build=True")
    if shutil.which(QEMU) is None:
        raise AdcsError(f"{QEMU} not found: {toolchain_missing()}")
    cmd = qemu_command(CORES[target], res.executable)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        raise AdcsError(f"{QEMU} did not finish within {timeout} s") from exc
    out = parse_target_output(proc.stdout)
    failures = loop_failures(out, res.extras.get("closed_loop"))
    if proc.returncode != 0 and not failures:
        raise AdcsError(f"target driver failed ({proc.returncode}): "
                        f"{(proc.stdout + proc.stderr)[-2000:]}")
    if failures and check:
        raise DriverCheckError("driver check failed: closed loop "
                               + "; ".join(failures), out, failures)
    return out


def parse_target_output(text: str) -> dict[str, dict]:
    """Figures of the target driver's output, counted in instructions."""
    out: dict[str, dict] = {}
    k = INSTRUCTIONS_PER_TICK
    for line in text.splitlines():
        if line.startswith("CAL "):
            f = dict(kv.split("=") for kv in line.split()[1:])
            if int(f["ticks"]) * k != int(f["instructions"]):
                raise AdcsError(
                    f"SysTick counted {f['ticks']} ticks for "
                    f"{f['instructions']} instructions, not one per {k}: "
                    "the instruction counts would be wrong")
            out["_calibration"] = {"ticks": int(f["ticks"]),
                                   "instructions": int(f["instructions"])}
        elif parse_loop_line(line, out):
            continue
        elif (m := _TIME.match(line)):
            rec: dict = {"median": k * float(m[3]), "max": k * float(m[4]),
                         "calls": int(m[5])}
            for key, g in (("first", 2), ("mean", 7), ("max_warm", 9)):
                if m[g] is not None:
                    rec[key] = k * float(m[g])
            if "mean" in rec:
                rec["mean"] /= rec["calls"]
            if m[6] is not None:
                rec["flag"] = int(m[6])
            if m[8] is not None:
                rec["final_error_deg"] = float(m[8])
            out.setdefault(m[1], {}).update(rec)
        elif parse_series_line(line, out, "steps", k):
            continue
        elif line.startswith(("OUT ", "WORK ", "STACK ")):
            _parse_detail(line, out)
    out["_stdout"] = {"text": text}
    return out


def _parse_detail(line: str, out: dict[str, dict]) -> None:
    kind, rest = line.split(" ", 1)
    if kind == "OUT":
        name, rest = rest.split(" ", 1)
        j, vals = rest.split(":", 1)
        outs = out.setdefault(name, {}).setdefault("outputs", [])
        outs.append([float(v) for v in vals.split()])
    elif kind == "WORK":
        name, *v = rest.split()
        out.setdefault(name, {})["work"] = tuple(int(x) for x in v[:4])
        out[name]["work_sizeof"] = (int(v[4]), int(v[5]))
    else:
        name, v = rest.split()
        out.setdefault(name, {})["stack_measured"] = int(v)


def format_counts(times: dict[str, dict], target: str,
                  plan: dict | None = None) -> str:
    """The driver's figures as a table, in instructions (not cycles), and
    the verdict of its checks (``plan``: the export's
    ``extras["closed_loop"]``, for the failure's hint)."""
    rows = [f"instructions per call on {target} (qemu -icount: "
            "instruction counts, not cycles; ±40)",
            f"{'function':30s} {'first call':>12s} {'median':>12s} "
            f"{'worst':>12s} {'mean':>12s}"]
    for name, t in times.items():
        if name.startswith("_") or "median" not in t:
            continue
        rows.append(f"{name:30s} {t.get('first', float('nan')):12.0f} "
                    f"{t['median']:12.0f} {t['max']:12.0f} "
                    f"{t.get('mean', float('nan')):12.0f}")
        if "final_error_deg" in t:
            rows.append(f"{'':30s} {loop_line(t)}; worst step after the "
                        f"cold first: {t.get('max_warm', float('nan')):.0f}")
    rows.append(driver_verdict(times, plan)[1])
    return "\n".join(rows)
