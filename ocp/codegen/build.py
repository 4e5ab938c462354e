"""Build and run an export: shared library, driver, timings."""

from __future__ import annotations

import re
import subprocess
from adcs_common.codegen import compile_c
from adcs_common.exceptions import AdcsError, InvalidValueError
from .result import OPT_FLAGS, SOURCE, ExportResult


def build_exported(res: ExportResult, cc: str = "gcc") -> ExportResult:
    """Compile the driver and a shared library of an export.

    Raises
    ------
    CompilerNotFound
        ``cc`` is not on PATH.
    CompileError
        The compiler failed (its output is in the message).
    """
    cflags = list(res.extras.get("cflags", []))
    ldflags = list(res.extras.get("ldflags", ["-lm"]))
    opt = " ".join(OPT_FLAGS)
    obj = compile_c([res.source], res.out_dir / f"{SOURCE}.o", cc=cc,
                    opt=opt, shared=False, flags=["-fPIC", "-c", *cflags],
                    libs=())
    lib = compile_c([obj], res.out_dir / f"{SOURCE}.so", cc=cc, opt=opt,
                    libs=ldflags)
    exe = compile_c([res.driver, obj], res.out_dir / "adcs_driver", cc=cc,
                    opt=opt, shared=False, flags=cflags, libs=ldflags)
    return ExportResult(**{**res.__dict__, "executable": exe,
                           "shared_library": lib})


def run_driver(res: ExportResult, timeout: float = 300.0
               ) -> dict[str, dict[str, float]]:
    """Run the built driver; return its timings per function.

    Returns
    -------
    dict
        C name -> ``{"median_us": ..., "max_us": ..., "calls": ...}``
        (for ``closed_loop:<name>``, the per-step times of the closed loop
        the driver runs with the generated RK4 as plant, and its final
        error angle ``final_error_deg``).
    """
    if res.executable is None:
        raise InvalidValueError(
            "res has no executable: call export_c(..., build=True)")
    proc = subprocess.run([str(res.executable)], capture_output=True,
                          text=True, timeout=timeout)
    if proc.returncode != 0:
        raise AdcsError(f"driver failed ({proc.returncode}): "
                        f"{proc.stderr[-2000:]}")
    out: dict[str, dict[str, float]] = {}
    pat = re.compile(r"^TIME (\S+) median_us=(\S+) max_us=(\S+) "
                     r"calls=(\d+)(?: final_error_deg=(\S+))?")
    for line in proc.stdout.splitlines():
        m = pat.match(line)
        if m:
            rec = {"median_us": float(m[2]), "max_us": float(m[3]),
                   "calls": int(m[4])}
            if m[5] is not None:
                rec["final_error_deg"] = float(m[5])
            out[m[1]] = rec
    out["_stdout"] = {"text": proc.stdout}  # type: ignore[dict-item]
    return out
