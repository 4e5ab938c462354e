"""Memory report of a Cortex-M export: flash, static RAM, work, stack.

Per exported function (`memory_report`, written as
``memory_<target>.json`` in the export folder by
`ocp.codegen.target.build_target`):

* ``flash`` (``text`` + ``rodata`` + ``data``: the initial values of
  ``.data`` are stored in flash too) and ``static_ram`` (``data`` +
  ``bss``): the function linked alone. A probe program that references
  the function, its ``_checkout`` and ``_release`` is linked with the
  startup code and ``--gc-sections`` (the source is compiled with
  ``-ffunction-sections -fdata-sections``) and the same program without
  the function is subtracted: what the function adds, the C library
  routines it calls (libm, libgcc's soft-float) included. Helpers shared
  by several functions count in each; ``"all"`` is every function linked
  together, and ``"wheel_qp+duty_qp+<step>"`` the flight set of each
  exported MPC step (`flight_groups`), with ``ram`` = its static RAM +
  the largest caller work + the deepest stack of the three (they run
  one at a time: one work buffer, one stack).
* ``work_bytes``: the caller's work arrays (``sz_arg``, ``sz_res``
  pointers of 4 bytes, ``sz_iw`` casadi_int of 4 bytes (a Cortex-M
  export's is int) and ``sz_w`` casadi_real of 8 bytes (4 in a single-precision export); the sizes
  the generated ``*_work`` functions return, which can be smaller than
  the casadi Function's ``sz_w``).
* ``stack``: the worst stack depth of the generated code from gcc's
  ``-fstack-usage`` frames along its call graph (``-fcallgraph-info=su``),
  from the function down; calls into the C library are not in that graph
  (``library_calls`` lists them) and add their own frames;
  ``stack_bounded`` is False when a frame is dynamic or the graph has a
  cycle. The target driver also measures the deepest stack the sample
  calls used, library included (painted stack, `run_target`; it
  includes the driver's clock read, 12 bytes on the M7).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any, Callable

from .result import SOURCE, ExportResult

#: Sizes on a 32-bit Cortex-M: pointer, casadi_int (long long; a
#: Cortex-M export's is int: ``extras["casadi_int_bytes"]``), double.
POINTER_BYTES, INT_BYTES, REAL_BYTES = 4, 8, 8

#: Fields of one function's entry in the memory report.
FIELDS = ("flash", "text", "rodata", "data", "bss", "static_ram",
          "sz_arg", "sz_res", "sz_iw", "sz_w", "work_bytes", "stack",
          "stack_bounded", "library_calls", "heap")

_NODE = re.compile(r'node: \{ title: "([^"]+)" label: "([^"]*)"')
_EDGE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')
_FRAME = re.compile(r"\\n(\d+) bytes \(([^)]*)\)")


def call_graph(ci_text: str) -> tuple[dict[str, tuple[int, bool]],
                                      dict[str, set[str]]]:
    """Frames and edges of gcc's ``-fcallgraph-info=su`` output (VCG).

    Returns ``frames``: node -> (bytes, static) for the functions compiled
    (external ones have none) and ``edges``: node -> callees.
    """
    frames: dict[str, tuple[int, bool]] = {}
    edges: dict[str, set[str]] = {}
    for line in ci_text.splitlines():
        if (m := _NODE.match(line)):
            f = _FRAME.search(m[2])
            if f:
                frames[m[1]] = (int(f[1]), f[2] == "static")
        elif (m := _EDGE.match(line)):
            edges.setdefault(m[1], set()).add(m[2])
    return frames, edges


def worst_stack(root: str, frames: dict[str, tuple[int, bool]],
                edges: dict[str, set[str]]) -> tuple[int, bool, list[str]]:
    """Deepest frame sum from ``root``; bounded; external callees."""
    memo: dict[str, int] = {}
    library: set[str] = set()
    bounded = True

    def depth(node: str, path: frozenset) -> int:
        nonlocal bounded
        if node in path:
            bounded = False
            return 0
        if node not in frames:
            library.add(node)
            return 0
        if node in memo:
            return memo[node]
        size, static = frames[node]
        bounded = bounded and static
        sub = [depth(c, path | {node}) for c in edges.get(node, ())]
        memo[node] = size + max(sub, default=0)
        return memo[node]

    return depth(root, frozenset()), bounded, sorted(library)


def _probe(names: list[str]) -> str:
    lines = [f'#include "{SOURCE}.h"', "int main(void);", "int main(void) {",
             "  static volatile unsigned keep;"]
    for n in names:
        lines += [
            f"  {{ int (*volatile f)(const casadi_real**, casadi_real**, "
            f"casadi_int*, casadi_real*, int) = {n};",
            f"    int (*volatile c)(void) = {n}_checkout;",
            f"    void (*volatile r)(int) = {n}_release;",
            "    keep += (f != 0) + (c != 0) + (r != 0); }"]
    return "\n".join(lines + ["  return (int)keep;", "}", ""])


def section_sizes(elf: Path, size_tool: str) -> dict[str, int]:
    """text, rodata, data, bss of an ELF (``size -A``)."""
    proc = subprocess.run([size_tool, "-A", str(elf)], capture_output=True,
                          text=True, check=True)
    out = {"text": 0, "rodata": 0, "data": 0, "bss": 0}
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) < 3 or not parts[0].startswith(".") or \
                not parts[1].isdigit():
            continue
        name, size = parts[0], int(parts[1])
        if name in (".data", ".bss", ".rodata"):
            out[name[1:]] += size
        elif name in (".text", ".isr_vector", ".ARM.exidx", ".ARM.extab",
                      ".init_array", ".fini_array", ".preinit_array"):
            out["text"] += size
    return out


def c_work_sizes(source_text: str, name: str) -> tuple[int, ...]:
    """(sz_arg, sz_res, sz_iw, sz_w) that the generated ``name_work``
    returns (read from its source)."""
    m = re.search(rf"int {re.escape(name)}_work\(.*?\n}}", source_text,
                  re.S)
    if m is None:
        raise ValueError(f"no {name}_work in the generated source")
    sizes = []
    for k in ("sz_arg", "sz_res", "sz_iw", "sz_w"):
        mk = re.search(rf"\*{k} = (\d+);", m[0])
        if mk is None:
            raise ValueError(f"no {k} in the generated {name}_work")
        sizes.append(int(mk[1]))
    return tuple(sizes)


def _size_tool(cc_path: str) -> str:
    tool = shutil.which("arm-none-eabi-size")
    if tool is None:
        tool = str(Path(shutil.which(cc_path) or cc_path).with_name(
            "arm-none-eabi-size"))
    return tool


def flight_groups(names: list[str]) -> dict[str, list[str]]:
    """The flight computer's sets, linked together: ``wheel_qp`` +
    ``duty_qp`` + each exported MPC step, keyed ``"wheel_qp+duty_qp+<step>"``
    (none without both QPs)."""
    if not {"wheel_qp", "duty_qp"} <= set(names):
        return {}
    return {f"wheel_qp+duty_qp+{n}": ["wheel_qp", "duty_qp", n]
            for n in names if n.startswith("mpc_")}


def memory_report(res: ExportResult, core, objs: list[Path],
                  startup: Path, cc: Callable[[list[str]], None]) -> dict:
    """The memory report of a built target export (see the module doc);
    writes ``memory_<target>.json`` and returns its content."""
    from .target import CROSS_CC, compile_flags, link_flags

    out = res.out_dir
    target = core.name
    # the call graphs of every unit (the generated source's and DAQP's):
    # a call into another unit meets its node by name
    ci = "\n".join(p.with_suffix(".ci").read_text() for p in objs
                   if p.with_suffix(".ci").is_file())
    frames, edges = call_graph(ci)
    text = res.source.read_text()
    size_tool = _size_tool(CROSS_CC)
    names = list(res.functions)
    groups = flight_groups(names)
    sizes: dict[str, dict[str, int]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for key, refs in [("_base", []), *[(n, [n]) for n in names],
                          ("all", names), *groups.items()]:
            src = Path(tmp) / f"probe_{key}.c"
            src.write_text(_probe(refs))
            elf = Path(tmp) / f"probe_{key}.elf"
            cc([*compile_flags(res, core), f"-I{out}", str(src),
                str(startup), *map(str, objs), *link_flags(res, core),
                "-lm", "-o", str(elf)])
            sizes[key] = section_sizes(elf, size_tool)
    base = sizes.pop("_base")
    report: dict = {"target": target, "core": list(core.cpu_flags),
                    "units": "bytes", "method": __doc__.split("\n\n")[1]
                    .strip(), "functions": {}}
    real = 4 if res.extras.get("precision") == "single" else REAL_BYTES
    for key, s in sizes.items():
        d = {k: s[k] - base[k] for k in s}
        rec: dict[str, Any] = {
            **d, "flash": d["text"] + d["rodata"] + d["data"],
            "static_ram": d["data"] + d["bss"]}
        if key in res.functions:
            sz = c_work_sizes(text, key)
            stack, bounded, lib = worst_stack(
                key if key in frames else f"{out / SOURCE}.c:{key}",
                frames, edges)
            rec.update(sz_arg=sz[0], sz_res=sz[1], sz_iw=sz[2], sz_w=sz[3],
                       work_bytes=POINTER_BYTES * (sz[0] + sz[1])
                       + res.extras.get("casadi_int_bytes", INT_BYTES)
                       * sz[2] + real * sz[3],
                       stack=stack, stack_bounded=bounded,
                       library_calls=lib,
                       heap=bool({"malloc", "calloc", "realloc", "free"}
                                 & set(lib)))
        report["functions"][key] = rec
    for key, refs in groups.items():
        rec = report["functions"][key]
        members = [report["functions"][n] for n in refs]
        rec.update(work_bytes=max(m["work_bytes"] for m in members),
                   stack=max(m["stack"] for m in members),
                   stack_bounded=all(m["stack_bounded"] for m in members))
        rec["ram"] = rec["static_ram"] + rec["work_bytes"] + rec["stack"]
    (out / f"memory_{target}.json").write_text(
        json.dumps(report, indent=2) + "\n")
    return report


def format_memory(report: dict, measured: dict | None = None) -> str:
    """The memory report as a table (bytes); ``measured``: `run_target`'s
    figures, for the painted-stack column."""
    width = max([22, *map(len, report["functions"])])
    rows = [f"memory on {report['target']} [bytes] (flash = text + rodata "
            "+ data; each function linked alone; stack: call graph, "
            "library calls excluded)",
            f"{'function':{width}s} {'flash':>8s} {'static RAM':>10s} "
            f"{'work':>8s} {'stack':>7s} {'measured':>9s}  library calls"]
    for name, r in report["functions"].items():
        meas = (measured or {}).get(name, {}).get("stack_measured")
        note = (f"RAM = static + work + stack: {r['ram']}" if "ram" in r
                else ", ".join(r.get("library_calls", [])))
        rows.append(
            f"{name:{width}s} {r['flash']:8d} {r['static_ram']:10d} "
            f"{r.get('work_bytes', ''):>8} "
            f"{str(r.get('stack', '')) + ('' if r.get('stack_bounded', True) else '+'):>7s} "
            f"{'' if meas is None else meas:>9}  {note}")
    return "\n".join(rows)
