"""The MPC step at long horizons: condensed against stage-wise, in C.

Run from the repository root::

    python -m benchmarks.long_horizon [--horizons 20,50,100]
                                      [--condensed-max 50] [--runs 3]

For each horizon N, exports the RTI steps of the demo craft (dt 0.5 s,
the 90° slew and hold of the driver's 80-step closed loop):
``mpc_sw_rti_step`` (stage-wise QP, Riccati interior point,
`ocp.mpc.stagewise`) at every N and ``mpc_cond_rti_step`` (condensed QP,
DAQP) up to ``--condensed-max`` (its compile grows as N^2.5: about 80 s
at N = 50 and 12 minutes at N = 100 on this machine kind). Each driver
runs ``--runs`` times in turn; the table gives the median of the runs'
medians, their worst step (the cold first included) and their worst step
after the first, the final error, and per variant the generated C of the
step alone (bytes, lines) and the CPU time of compiling it (gcc -O3 -c).
The last lines fit the growth exponents from the smallest to the largest
N of each variant: time ∝ N^a.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from allocation import WheelArray
from ocp.codegen.export import export_c, run_driver
from ocp.mpc import AttitudeMPC
from ocp import rigid_spacecraft

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)

VARIANTS = {"mpc_sw_rti_step": "stagewise", "mpc_cond_rti_step":
            "condensed"}


def code_size(variant: str, horizon: int, folder: Path) -> dict:
    """Generated C of one RTI step alone: bytes, lines, compile CPU [s]."""
    model = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS)
    mpc = AttitudeMPC(model, horizon=horizon, dt=0.5, rti=True,
                      solver=VARIANTS[variant])
    cg = ca.CodeGenerator(f"{variant}_{horizon}.c")
    cg.add(mpc.step_function)
    src = Path(cg.generate(str(folder) + "/"))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(
        ["gcc", "-O3", "-c", str(src), "-o", str(src.with_suffix(".o")),
         "-I", ca.GlobalOptions.getCasadiIncludePath()],
        capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    text = src.read_text()
    return {"bytes": len(text.encode()), "lines": text.count("\n"),
            "compile_s": (after.ru_utime + after.ru_stime
                          - before.ru_utime - before.ru_stime)
            if proc.returncode == 0 else float("nan")}


def run(horizons=(20, 50, 100), condensed_max: int = 50,
        runs: int = 3) -> list[dict]:
    """One row per (variant, N): timings of the closed loop and code size."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="adcs_long_") as tmp:
        for N in horizons:
            names = [v for v in VARIANTS
                     if v == "mpc_sw_rti_step" or N <= condensed_max]
            built = {}
            for name in names:
                out = Path(tmp) / f"{name}_{N}"
                t0 = time.perf_counter()
                built[name] = export_c(out, wheels=WHEELS, horizon=N,
                                       build=True, repeats=20,
                                       mpc_variants=(name,))
                build_s = time.perf_counter() - t0
                size = code_size(name, N, Path(tmp))
                rows.append({"variant": name, "N": N, "build_s": build_s,
                             **size, "recs": []})
            for _ in range(runs):
                for name, res in built.items():
                    rec = run_driver(res)[f"closed_loop:{name}"]
                    row = next(r for r in rows if r["variant"] == name
                               and r["N"] == N)
                    row["recs"].append(rec)
    for row in rows:
        recs = row.pop("recs")
        row["median_ms"] = 1e-3 * statistics.median(
            r["median_us"] for r in recs)
        row["worst_ms"] = 1e-3 * statistics.median(r["max_us"] for r in recs)
        row["worst_warm_ms"] = 1e-3 * statistics.median(
            r["max_warm_us"] for r in recs)
        row["final_deg"] = recs[0]["final_error_deg"]
    return rows


def exponents(rows: list[dict]) -> dict[str, dict[str, float]]:
    """Fitted growth ``x ∝ N^a`` from the smallest to the largest N."""
    out = {}
    for name in VARIANTS:
        mine = sorted((r for r in rows if r["variant"] == name),
                      key=lambda r: r["N"])
        if len(mine) < 2:
            continue
        a, b = mine[0], mine[-1]
        ratio = np.log(b["N"] / a["N"])
        out[name] = {k: float(np.log(b[k] / a[k]) / ratio) for k in
                     ("median_ms", "worst_ms", "bytes", "compile_s")}
    return out


def format_rows(rows: list[dict]) -> str:
    """The table, then the fitted exponents."""
    head = ("| variant | N | median [ms] | worst, cold first incl. [ms] | "
            "worst after the first [ms] | final error [deg] | C source "
            "[kB] | lines | compile CPU [s] |")
    lines = [head, "|" + "---|" * 9]
    for r in rows:
        lines.append(
            f"| {r['variant']} | {r['N']} | {r['median_ms']:.3f} | "
            f"{r['worst_ms']:.3f} | {r['worst_warm_ms']:.3f} | "
            f"{r['final_deg']:.2e} | {r['bytes'] / 1e3:.0f} | {r['lines']} "
            f"| {r['compile_s']:.1f} |")
    for name, ex in exponents(rows).items():
        lines.append(f"\n{name}: " + ", ".join(
            f"{k} ∝ N^{v:.2f}" for k, v in ex.items()))
    return "\n".join(lines)


def main(argv=None) -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizons", default="20,50,100")
    ap.add_argument("--condensed-max", type=int, default=50)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args(argv)
    horizons = tuple(int(h) for h in args.horizons.split(","))
    print(format_rows(run(horizons, args.condensed_max, args.runs)))


if __name__ == "__main__":
    main()
