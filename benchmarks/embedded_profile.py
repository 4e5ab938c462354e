"""Where an exported MPC step's instructions go, on the emulated core.

Run from the repository root: ``python -m benchmarks.embedded_profile
[--target cortex-m7] [--mpc mpc_sw_rti_step] [--qp rqp] [--qp-max-iter
8] [--horizon 20] [--precision double] [--spacecraft demo]``. Exports
the craft for the target (`ocp.codegen.export_c`, as
``benchmarks.embedded``), runs its bare-metal driver on
qemu-system-arm under ``-icount shift=0`` with the emulator's
translation-block trace (``-d in_asm,exec,nochain``, streamed through a
pipe, never written out) and counts every executed block's instructions
against the function that holds it (the ELF's symbols; CasADi's
generated functions by the name their source gives them, ``sw_lin``
rather than ``adcs_codegen_f18``). Each call of the step is one profile,
from the step's entry to the first block of the driver's own code. The
closed loop's calls are its last ones: each one's total is checked
against the driver's SysTick count of that step (one tick per 40
instructions, and its count holds the call and the clock's reads:
they agree within about 100 instructions).
Prints the profile of the loop's median step and of its worst step
after the cold one, by function and by part (the generated functions,
the QP solver's sources, the C library).
"""

from __future__ import annotations

import argparse
import bisect
import os
import re
import subprocess
import tempfile
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from adcs_common.exceptions import AdcsError
from benchmarks.embedded import target_export
from ocp.codegen.result import SOURCE, ExportResult
from ocp.codegen.target import (CORES, CROSS_CC, TARGET_DRIVER, CortexM,
                                compile_flags, parse_target_output,
                                qemu_command, toolchain_missing)

#: The parts a function's instructions are summed into, by the folder
#: of the source that defines it (the export's own: the generated
#: functions; the rest: the C library).
PARTS = {".": "generated (CasADi)", "rqp": "rqp", "pqp": "pqp",
         "daqp": "DAQP"}
_NM = CROSS_CC.replace("gcc", "nm")
_GENERATED = re.compile(r"^/\* (\w+):\(.*\*/\n(?:static )?int casadi_(f\d+)\(",
                        re.M)
#: a QP wrapper's prefix (`ocp.mpc.riccati_qp`, `ocp.mpc.primal_qp`)
_WRAPPER = re.compile(
    r"^adcs_[rp]qp_\d+(?:x\d+)+(?:_cap\d+)?(?:_p1)?_(?!(?:cap\d+)?(?:_?p1)?$)")
_PREFIX = re.compile(r"#define CASADI_PREFIX\(ID\) (\w+) ## ID")


@dataclass(frozen=True)
class Symbols:
    """An ELF's functions: sorted start addresses, ends and names."""

    starts: list[int]
    ends: list[int]
    names: list[str]

    def name_of(self, pc: int) -> str:
        """The function holding address ``pc`` (its hex if none)."""
        i = bisect.bisect_right(self.starts, pc) - 1
        if i >= 0 and pc < self.ends[i]:
            return self.names[i]
        return hex(pc)


def _nm(path: Path, *flags: str) -> list[list[str]]:
    text = subprocess.run([_NM, *flags, str(path)], capture_output=True,
                          text=True, check=True).stdout
    return [line.split() for line in text.splitlines()]


def elf_symbols(elf: Path) -> Symbols:
    """The functions of ``elf`` (Thumb addresses without their low bit)."""
    rows = sorted((int(a, 16) & ~1, int(s, 16), n)
                  for a, s, t, n in (r for r in _nm(elf, "-S")
                                     if len(r) == 4)
                  if t in "tTwW")
    return Symbols([r[0] for r in rows], [r[0] + r[1] for r in rows],
                   [r[2] for r in rows])


def generated_names(folder: Path) -> dict[str, str]:
    """Symbol stem -> the CasADi Function's name, from the sources'
    comments (``adcs_codegen_f18`` -> ``sw_lin``)."""
    names = {}
    for src in [folder / f"{SOURCE}.c", *folder.glob("*/adcs_*.c")]:
        text = src.read_text()
        prefix = _PREFIX.findall(text)
        for name, f in _GENERATED.findall(text):
            for p in prefix:
                names[p + f] = name
    return names


def parse_trace(lines: Iterable[str], symbols: Symbols, entry: str,
                driver: set[str]) -> list[Counter]:
    """The instructions of each call of ``entry``, by function.

    ``lines``: qemu's ``-d in_asm,exec,nochain`` log. A block's size is
    that of its translation (the ``IN:`` listing before its first
    ``Trace``); a block rewound at an I/O access (``cpu_io_recompile``)
    counts up to that access, one stopped before it ran (``Stopped
    execution``) nothing. A call runs from a block at ``entry``'s address
    that ran to the first block of a ``driver`` function (interrupt
    handlers, whose names end in ``_Handler``, count in the call).
    """
    start = symbols.starts[symbols.names.index(entry)]
    blocks: dict[str, list[int]] = {}
    where: dict[int, tuple[str, bool]] = {}
    calls: list[Counter] = []
    pending: list[int] | None = None
    call: Counter | None = None
    last: tuple[str, str, list[int]] | None = None
    for line in lines:
        if line.startswith("0x") and pending is not None:
            pending.append(int(line[:10], 16))
        elif line.startswith("Trace"):
            host, rest = line.split()[2:4]
            pc = int(rest.split("/")[1], 16)
            if pending is not None:
                blocks[host], pending = pending, None
            if pc not in where:
                name = symbols.name_of(pc)
                where[pc] = (name, name in driver
                             and not name.endswith("_Handler"))
            name, outside = where[pc]
            if pc == start:
                call = Counter()
                calls.append(call)
            elif outside:
                call = None
            if call is not None:
                addrs = blocks.get(host, [pc])
                call[name] += len(addrs)
                last = (host, name, addrs)
            else:
                last = None
        elif line.startswith("IN:"):
            pending = []
        elif line.startswith("cpu_io_recompile") and last and call:
            to = int(line.split()[-1], 16)
            call[last[1]] -= sum(a >= to for a in last[2])
        elif line.startswith("Stopped execution") and last and call:
            if line.split()[6] == last[0]:
                call[last[1]] -= len(last[2])
    # an entry block stopped before it ran starts no call
    return [c for c in calls if sum(c.values())]


def driver_functions(res: ExportResult, core: CortexM) -> set[str]:
    """The functions of the target driver's own source (and startup)."""
    with tempfile.TemporaryDirectory() as tmp:
        obj = Path(tmp) / "driver.o"
        subprocess.run([CROSS_CC, *compile_flags(res, core), "-c",
                        str(res.out_dir / TARGET_DRIVER), "-o", str(obj)],
                       check=True, capture_output=True)
        rows = _nm(obj) + _nm(res.out_dir / f"startup_{core.name}.o")
    return {r[2] for r in rows if len(r) == 3 and r[1] in "tTwW"}


def object_parts(res: ExportResult, target: str) -> dict[str, str]:
    """Function -> part (`PARTS`) of every function the export defines
    (its objects: ``<source stem>_<target>.o``)."""
    parts = {}
    root = res.out_dir.resolve()
    for src in [root / f"{SOURCE}.c", *map(Path, res.extras["c_sources"])]:
        folder = src.resolve().parent.relative_to(root).as_posix()
        for r in _nm(root / f"{src.stem}_{target}.o"):
            if len(r) == 3 and r[1] in "tTwW":
                parts[r[2]] = PARTS.get(folder, folder)
    return parts


def profile_export(res: ExportResult, entry: str, timeout: float = 3600.0
                   ) -> tuple[list[Counter], dict]:
    """Run ``res``'s target driver traced; ``(calls, figures)``: each
    call's instructions by function and `run_target`'s figures.

    Raises
    ------
    AdcsError
        The driver failed (its output's last lines in the message).
    """
    target = res.extras["target"]
    symbols = elf_symbols(res.executable)
    driver = driver_functions(res, CORES[target])
    with tempfile.TemporaryDirectory() as tmp:
        fifo, stdout = Path(tmp) / "trace", Path(tmp) / "stdout"
        os.mkfifo(fifo)
        with open(stdout, "w") as sink:
            proc = subprocess.Popen(
                [*qemu_command(CORES[target], res.executable),
                 "-d", "in_asm,exec,nochain", "-D", str(fifo)],
                stdout=sink)
            with open(fifo, errors="replace") as log:
                calls = parse_trace(log, symbols, entry, driver)
            proc.wait(timeout=timeout)
        text = stdout.read_text()
    if proc.returncode != 0:
        raise AdcsError(f"the traced driver exited {proc.returncode}:\n"
                        + "\n".join(text.splitlines()[-20:]))
    return calls, parse_target_output(text)


def loop_profiles(calls: list[Counter], figures: dict, entry: str
                  ) -> tuple[list[Counter], np.ndarray]:
    """The closed loop's calls (the driver's last ones) and the
    driver's SysTick count of each step, in instructions.

    Raises
    ------
    AdcsError
        The trace's totals are not the driver's counts (within 5 ticks:
        the driver's count holds its call and clock reads too).
    """
    counts = np.asarray(figures[f"closed_loop:{entry}"]["steps"])
    loop = calls[len(calls) - len(counts):]
    totals = np.array([sum(c.values()) for c in loop])
    if len(loop) != len(counts) or np.max(np.abs(totals - counts)) > 200:
        raise AdcsError(
            f"the trace's {len(loop)} calls of {entry} do not match the "
            "driver's closed loop: the profile would be wrong")
    return loop, counts


def format_profile(steps: dict[str, Counter], parts: dict[str, str],
                   names: dict[str, str], share: float = 0.01) -> str:
    """A table of a few steps' instructions by function (those above
    ``share`` of the first step) and by part."""
    heads = list(steps)
    first = steps[heads[0]]
    total0 = sum(first.values())

    def label(fn: str) -> str:
        stem = fn.split(".")[0]
        return _WRAPPER.sub("", names.get(stem, stem))

    rows: dict[str, list[int]] = {}
    by_part: dict[str, list[int]] = {}
    for j, h in enumerate(heads):
        for fn, n in steps[h].items():
            part = parts.get(fn, "C library")
            key = label(fn) if first[fn] >= share * total0 else \
                f"other ({part})"
            rows.setdefault(key, [0] * len(heads))[j] += n
            by_part.setdefault(part, [0] * len(heads))[j] += n
    lines = ["| function | " + " | ".join(heads) + " |",
             "|---|" + "---:|" * len(heads)]
    for key, v in sorted(rows.items(), key=lambda kv: -kv[1][0]):
        lines.append(f"| {key} | " + " | ".join(f"{n:,}" for n in v) + " |")
    lines.append("| **by part** |" + " |" * len(heads))
    tot = [sum(steps[h].values()) for h in heads]
    for part, v in sorted(by_part.items(), key=lambda kv: -kv[1][0]):
        lines.append(f"| {part} | " + " | ".join(
            f"{n:,} ({100 * n / t:.0f} %)" for n, t in zip(v, tot)) + " |")
    lines.append("| **step** | " + " | ".join(f"**{t:,}**" for t in tot)
                 + " |")
    return "\n".join(lines)


def main() -> None:
    """Print the profiles."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target", default="cortex-m7", choices=tuple(CORES))
    ap.add_argument("--mpc", default="mpc_sw_rti_step",
                    help="the MPC step to profile (one variant)")
    ap.add_argument("--precision", default="double",
                    choices=("double", "single"))
    ap.add_argument("--horizon", type=int, default=20)
    ap.add_argument("--qp", default="rqp", choices=("daqp", "pqp", "rqp"),
                    help="QP of the step (rqp: stage-wise steps only)")
    ap.add_argument("--qp-max-iter", type=int, default=8)
    ap.add_argument("--spacecraft", default="demo",
                    help="a built-in craft or a TOML file")
    args = ap.parse_args()
    reason = toolchain_missing()
    if reason:
        raise SystemExit(f"benchmarks.embedded_profile: {reason}")
    with tempfile.TemporaryDirectory() as out:
        res = target_export(out, args.spacecraft, (args.mpc,), args)
        calls, figures = profile_export(res, args.mpc)
        parts = object_parts(res, args.target)
        names = generated_names(res.out_dir)
    loop, counts = loop_profiles(calls, figures, args.mpc)
    order = np.argsort(counts, kind="stable")
    median = int(order[len(order) // 2])
    worst = 1 + int(np.argmax(counts[1:]))
    print(f"{args.spacecraft} craft, horizon {args.horizon}, {args.target}, "
          f"{args.precision}, {args.mpc} with {args.qp} capped at "
          f"{args.qp_max_iter}: {len(loop)} closed-loop steps traced, "
          f"each within {int(np.max(np.abs([sum(c.values()) for c in loop] - counts)))} "
          "instructions of the driver's SysTick count")
    print(format_profile({f"median step ({median})": loop[median],
                          f"worst step ({worst})": loop[worst]},
                         parts, names))


if __name__ == "__main__":
    main()
