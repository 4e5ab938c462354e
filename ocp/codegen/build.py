"""Build and run an export: shared library, driver, timings."""

from __future__ import annotations

import re
import shutil
import subprocess
from collections.abc import Sequence

from adcs_common.codegen import compile_c
from adcs_common.exceptions import AdcsError, InvalidValueError
from .linux_target import LINUX_INSTALL
from .checks import (DriverCheckError, loop_failures, parse_loop_line,
                     parse_series_line)
from .result import OPT_FLAGS, SOURCE, ExportResult


#: Warnings the builds enable (the Makefile adds -Werror).
WARNING_FLAGS = ("-Wall", "-Wextra")

#: The C standard of the builds.
STD_FLAGS = ("-std=c99",)


def build_exported(res: ExportResult, cc: str = "gcc",
                   progress: bool = False, shared: bool = True,
                   link_flags: Sequence[str] = ()) -> ExportResult:
    """Compile the sources once; link the driver and a shared library.

    ``shared`` False links the driver alone (a cross build, whose library
    this Python could not load); ``link_flags`` go to the driver's link
    (``-static`` for an emulated target).

    The generated source and the solver sources beside it
    (``extras["solver_sources"]``: DAQP) are compiled to objects in the
    export folder, C99, with ``-Wall -Wextra``: the compiler's warnings
    are counted in ``extras["warnings"]`` (0 for the toolbox's exports;
    their text in ``extras["warning_text"]``; the compiler and the
    driver's link flags in ``extras["built_with"]``). ``progress`` shows a bar
    over the three steps (the object takes most of an MPC export's
    build: 27 s for the default export's 4.3 MB source here).

    Raises
    ------
    CompilerNotFound
        ``cc`` is not on PATH.
    CompileError
        The compiler failed (its output is in the message).
    """
    from tqdm.auto import tqdm

    ldflags = list(res.extras.get("ldflags", ["-lm"]))
    solver = list(res.extras.get("solver_sources", []))
    opt = " ".join(OPT_FLAGS)
    # defines the sources need (single precision: DAQP's float build)
    flags = [*STD_FLAGS, *WARNING_FLAGS, *res.extras.get("cflags", [])]
    log: list[str] = []
    # on a terminal only (None: tqdm's own test), not in logs or pipes
    steps = tqdm(total=3 if shared else 2,
                 desc=f"compiling {SOURCE}.c", unit="step",
                 disable=None if progress else True,
                 bar_format="{l_bar}{bar}| "
                 "{n}/{total} [{elapsed}]")
    with steps:
        objs = [compile_c([src], src.with_suffix(".o"), cc=cc, opt=opt,
                          shared=False, flags=["-fPIC", "-c", *flags],
                          libs=(), log=log)
                for src in [res.source, *solver]]
        lib = None
        if shared:
            steps.set_description("linking the shared library")
            steps.update(1)
            lib = compile_c(objs, res.out_dir / f"{SOURCE}.so", cc=cc,
                            opt=opt, libs=ldflags, log=log)
        steps.set_description("building the driver")
        steps.update(1)
        exe = compile_c([res.driver, *objs], res.out_dir / "adcs_driver",
                        cc=cc, opt=opt, shared=False,
                        flags=[*flags, *link_flags], libs=ldflags, log=log)
        steps.update(1)
    text = "".join(log)
    extras = {**res.extras, "warnings": text.count("warning:"),
              "built_with": " ".join([cc, *link_flags]),
              "warning_text": text, "objects": objs}
    return ExportResult(**{**res.__dict__, "executable": exe,
                           "shared_library": lib, "extras": extras})


def run_driver(res: ExportResult, timeout: float = 300.0,
               check: bool = True) -> dict[str, dict[str, float]]:
    """Run the built driver; return its timings per function.

    Parameters
    ----------
    res : ExportResult
        A built export (``export_c(..., build=True)``).
    timeout : float
        Seconds the driver may run.
    check : bool
        Raise `DriverCheckError` when a closed loop fails its check
        (`ocp.codegen.checks`); False returns the figures all the same.

    Returns
    -------
    dict
        C name -> ``{"first_us": ..., "median_us": ..., "max_us": ...,
        "calls": ..., "flag": ...}`` (the first, cold call; the median and
        worst of all calls; ``flag`` 0 when every call returned 0). For
        ``closed_loop:<name>``: the per-step times ``steps_us`` (in step
        order) of the closed loop the driver runs with the generated RK4 as plant, ``max_warm_us`` (the
        worst step after the cold first one) and the final error angle
        ``final_error_deg``, and the check's ``loop_*`` figures:
        ``loop_steps``, ``loop_dt`` and ``loop_seconds`` [s] (its length),
        ``loop_final_error_deg``, ``loop_tolerance_deg``,
        ``loop_worst_violation``, ``loop_violation_tolerance``,
        ``loop_finite``, ``loop_flag`` and ``loop_ok`` (1: passed), and
        ``state``, the loop's final state.

    Raises
    ------
    DriverCheckError
        ``check`` and a closed loop failed its check (its ``times``:
        what this function would have returned).
    AdcsError
        The driver failed otherwise.
    """
    if res.executable is None:
        raise InvalidValueError(
            "res has no executable: call export_c(..., build=True)")
    # an emulated target's driver runs under its emulator (`linux_target`)
    runner = list(res.extras.get("runner", ()))
    if runner and shutil.which(runner[0]) is None:
        raise AdcsError(f"{runner[0]} not found "
                        f"({LINUX_INSTALL[res.extras['target']]})")
    proc = subprocess.run([*runner, str(res.executable)],
                          capture_output=True, text=True, timeout=timeout)
    out = _parse_driver(proc.stdout)
    failures = loop_failures(out, res.extras.get("closed_loop"))
    if proc.returncode != 0 and not failures:
        raise AdcsError(f"driver failed ({proc.returncode}): "
                        f"{proc.stderr[-2000:]}")
    if failures and check:
        raise DriverCheckError("driver check failed: closed loop "
                               + "; ".join(failures), out, failures)
    return out


def _parse_driver(text: str) -> dict[str, dict[str, float]]:
    """The host driver's figures (`run_driver`) from its output."""
    out: dict[str, dict[str, float]] = {}
    pat = re.compile(r"^TIME (\S+)(?: first_us=(\S+))? median_us=(\S+) "
                     r"max_us=(\S+) calls=(\d+)(?: flag=(\d+))?"
                     r"(?: final_error_deg=(\S+))?(?: max_warm_us=(\S+))?")
    for line in text.splitlines():
        if parse_loop_line(line, out) or parse_series_line(
                line, out, "steps_us"):
            continue
        m = pat.match(line)
        if m:
            rec = {"median_us": float(m[3]), "max_us": float(m[4]),
                   "calls": int(m[5])}
            if m[2] is not None:
                rec["first_us"] = float(m[2])
            if m[6] is not None:
                rec["flag"] = int(m[6])
            if m[7] is not None:
                rec["final_error_deg"] = float(m[7])
            if m[8] is not None:
                rec["max_warm_us"] = float(m[8])
            out.setdefault(m[1], {}).update(rec)
    out["_stdout"] = {"text": text}  # type: ignore[dict-item]
    return out
