"""The stage-wise step exported with ``stagewise_qp_plugin="rqp"``.

The Riccati active set travels in the export folder (``rqp/``: its
sources and licence, and the wrapper that compiles rqp.c for the step's
QP sizes), the folder builds alone under -Wall -Wextra -Werror, no
function reaches the heap, the driver's closed loop ends where the
condensed DAQP export's does, and the emulated M7 flies it to the host's
state.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from ocp.codegen.build import run_driver
from ocp.codegen.export import export_c
from ocp.codegen.target import run_target, toolchain_missing

from export_build import HEAP, check_heap_free, make_copy, undefined_symbols

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(shutil.which("cc") is None
                       or shutil.which("make") is None,
                       reason="needs cc and make"),
]

STEP = "mpc_sw_rti_step"
LOOP = f"closed_loop:{STEP}"
WRAPPER = "adcs_rqp_6x11x4x8"


def _export(out: Path, **kw):
    return export_c(out, spacecraft="demo", horizon=6, repeats=5, **kw)


def _rate_export(out: Path, horizon: int = 20, **kw):
    """The step with rqp capped at 8 on the demo craft with a 1°/s rate
    bound (the phase one's wrapper), built."""
    return export_c(out, spacecraft="demo", horizon=horizon, repeats=3,
                    rate_max=np.deg2rad(1.0), mpc_variants=(STEP,),
                    stagewise_qp_plugin="rqp", stagewise_qp_max_iter=8,
                    build=True, **kw)


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    root = tmp_path_factory.mktemp("rqp-export")
    return {"rqp": _export(root / "rqp", mpc_variants=(STEP,),
                           stagewise_qp_plugin="rqp", build=True),
            "daqp": _export(root / "daqp",
                            mpc_variants=("mpc_cond_rti_step",),
                            build=True)}


def test_rqp_sources_travel_in_the_folder(exports):
    res = exports["rqp"]
    folder = res.out_dir / "rqp"
    assert [p.name for p in folder.glob("adcs_rqp_*.c")] == [
        f"{WRAPPER}.c"]
    for name in ("rqp.c", "rqp.h", "rqp_kernels.h", "rqp_rows.h",
                 "LICENSE"):
        assert (folder / name).is_file(), name
    wrapper = (folder / f"{WRAPPER}.c").read_text()
    assert '#include "../adcs_codegen.h"' in wrapper
    assert '#include "rqp.c"' in wrapper and "#define RQP_NX 11" in wrapper
    assert f"{WRAPPER}(arg" in res.source.read_text()
    assert str(res.out_dir) not in wrapper
    for name in ("Makefile", "CMakeLists.txt"):
        body = (res.out_dir / name).read_text()
        assert f"rqp/{WRAPPER}.c" in body and "rqp/rqp.c" not in body
    assert f"`rqp/{WRAPPER}.c`" in res.readme.read_text()
    assert not (exports["daqp"].out_dir / "rqp").exists()


def test_rqp_export_flies_the_condensed_loop(exports):
    """The host drivers' closed loops: every call returns 0, the loop
    passes its check and ends in the condensed DAQP export's state."""
    a = run_driver(exports["rqp"])[LOOP]
    b = run_driver(exports["daqp"])["closed_loop:mpc_cond_rti_step"]
    assert a["flag"] == 0 and a["loop_ok"]
    assert np.max(np.abs(np.array(a["state"]) - b["state"])) <= 1e-9
    assert exports["rqp"].extras["warnings"] == 0


def test_copied_folder_builds_alone_without_heap(exports, tmp_path):
    """make with the system's tools in a copy, -Werror; no allocator in
    the generated object or the wrapper's (rqp.c inside it), and the
    driver runs on a heap that traps."""
    dst = tmp_path / "copy"
    make_copy(exports["rqp"].out_dir, dst)
    objects = [dst / "adcs_codegen.o", dst / "rqp" / f"{WRAPPER}.o"]
    assert all(p.is_file() for p in objects)
    check_heap_free(dst, objects, LOOP)


@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
@pytest.mark.parametrize("cap", [None, 5])
def test_rqp_step_on_the_emulated_m7_equals_the_host(exports, tmp_path,
                                                     cap):
    """Cross-compiled clean (-Werror), no heap in the memory report, and
    the emulated closed loop (double) ends in the host driver's state to
    1e-9; also with the QP capped at 5 iterations."""
    kw = {"mpc_variants": (STEP,), "stagewise_qp_plugin": "rqp",
          "stagewise_qp_max_iter": cap, "build": True}
    res = _export(tmp_path / "m7", target="cortex-m7", **kw)
    rec = res.extras["memory"]["functions"][STEP]
    assert rec["heap"] is False and not set(rec["library_calls"]) & set(HEAP)
    loop = run_target(res)[LOOP]
    host = run_driver(exports["rqp"] if cap is None else
                      _export(tmp_path / "host", **kw))[LOOP]
    assert loop["flag"] == 0 and loop["loop_ok"]
    np.testing.assert_allclose(loop["state"], host["state"], rtol=0,
                               atol=1e-9)
    assert loop["loop_worst_violation"] <= 1e-9


def test_rate_bounded_export_runs_the_phase_one(tmp_path):
    """With a rate bound the exported rqp wrapper carries the phase one
    (``_p1``; its README says so), builds under -Wall -Wextra -Werror,
    and the driver's capped loop of the rate-bounded demo craft at
    horizon 20 reaches the target within every bound (the capped plans'
    shifted starts break rate boxes there)."""
    res = _rate_export(tmp_path / "rate")
    assert res.extras["warnings"] == 0, res.extras["warning_text"]
    wrapper = res.out_dir / "rqp" / "adcs_rqp_20x11x4x11_cap8_p1"
    assert wrapper.with_suffix(".c").is_file()
    assert not undefined_symbols([wrapper.with_suffix(".o")]) & set(HEAP)
    assert "runs a phase one" in res.readme.read_text()
    loop = run_driver(res)[LOOP]
    assert loop["flag"] == 0 and loop["loop_ok"]
    assert loop["final_error_deg"] <= 1e-6
    assert loop["loop_worst_violation"] <= 1e-9


@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
@pytest.mark.parametrize("target, precision, worst", [
    ("cortex-m7", "double", 4.5e6), ("cortex-m4f", "single", 5.5e6)])
def test_rate_bounded_phase_one_costs_a_capped_step_on_target(
        tmp_path, target, precision, worst):
    """The rate-bounded demo slew at horizon 20, capped at 8, on the
    emulated M7 (double) and M4F (float): the phase one repairs the
    plan's tail over the stages from the first broken box, so the worst
    step stays a capped QP's (measured after the cold step: 4,173,920
    instructions on the M7, 4,926,880 on the M4F; the phase one over the
    whole horizon took 16.4 M on the M7), and the loop reaches the target
    within every bound (float: within float's tolerances)."""
    from test_targets import (M4F_SINGLE_FINAL_ERROR_RAD,
                              M4F_SINGLE_STEP_VIOLATION)

    res = _rate_export(tmp_path / target, target=target,
                       precision=precision)
    loop = run_target(res, timeout=600)[LOOP]
    steps = np.asarray(loop["steps"])
    single = precision == "single"
    assert loop["loop_ok"]
    assert np.deg2rad(loop["final_error_deg"]) <= (
        M4F_SINGLE_FINAL_ERROR_RAD if single else np.deg2rad(1e-6))
    assert loop["loop_worst_violation"] <= (
        M4F_SINGLE_STEP_VIOLATION if single else 1e-9)
    assert steps[1:].max() <= worst, steps[1:].max()


def test_a_toml_crafts_rate_bound_reaches_the_phase_one(tmp_path):
    """A user's craft whose TOML file sets ``rate_max_deg``: its rqp
    export carries the phase one (the ``_p1`` wrapper, 11 boxes a stage:
    the 3 rates with the 4 torques and 4 momenta)."""
    from test_primal_qp import CRAFT_TOML

    path = tmp_path / "craft.toml"
    path.write_text(CRAFT_TOML.replace('name = "toml-craft"',
                                       'name = "toml-craft"\n'
                                       'rate_max_deg = 1.5'))
    res = export_c(tmp_path / "out", spacecraft=path, horizon=5,
                   mpc_variants=(STEP,), stagewise_qp_plugin="rqp")
    assert (res.out_dir / "rqp" / "adcs_rqp_5x11x4x11_p1.c").is_file()
    assert "runs a phase one" in res.readme.read_text()


def test_rate_bounded_float_export_reaches_the_target(tmp_path):
    """The phase one in float (rqp.c's float build, the wrapper's penalty
    in float): the rate-bounded demo craft at horizon 12, capped at 8,
    built clean, its host loop reaching the target within float's
    tolerances (measured: 4.8e-6°, worst scaled violation 3.7e-7)."""
    from test_targets import (M4F_SINGLE_FINAL_ERROR_RAD,
                              M4F_SINGLE_STEP_VIOLATION)

    res = _rate_export(tmp_path / "rate", horizon=12, precision="single")
    assert res.extras["warnings"] == 0, res.extras["warning_text"]
    assert "runs a phase one" in res.readme.read_text()
    loop = run_driver(res)[LOOP]
    assert loop["flag"] == 0 and loop["loop_ok"]
    assert np.deg2rad(loop["final_error_deg"]) <= M4F_SINGLE_FINAL_ERROR_RAD
    assert loop["loop_worst_violation"] <= M4F_SINGLE_STEP_VIOLATION


#: The float rqp step at horizon 20 on the emulated M4F (demo craft, the
#: driver's 90° slew; `benchmarks.embedded --target cortex-m4f
#: --precision single --qp rqp --qp-max-iter 8`): measured flight set
#: 61,628 bytes of RAM (58,628 of caller work, 2,256 of stack) and
#: 159,528 of flash; final error 1.9e-6°.
M4F_RQP_20_RAM = 61_628


@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
def test_single_rqp_step_at_horizon_20_fits_the_m4f(tmp_path):
    """In float on the emulated Cortex-M4F the stage-wise step with rqp
    (capped at 8) at horizon 20 flies the slew to the target within
    float's tolerances (final error ≤ 1e-3 rad, applied steps within
    1e-5 of every bound), with no software double and no heap, and its
    flight set (wheel_qp, duty_qp and the step) fits the goal table's
    memory: RAM ≤ 64 KiB, flash ≤ 256 KiB."""
    from test_targets import (GOAL_FLASH, GOAL_RAM,
                              M4F_SINGLE_FINAL_ERROR_RAD,
                              M4F_SINGLE_STEP_VIOLATION)

    res = export_c(tmp_path / "m4f", spacecraft="demo", horizon=20,
                   repeats=3, precision="single", target="cortex-m4f",
                   mpc_variants=(STEP,), stagewise_qp_plugin="rqp",
                   stagewise_qp_max_iter=8, build=True)
    assert "#define RQP_SINGLE_PRECISION" in (
        res.out_dir / "rqp" / "adcs_rqp_20x11x4x8_cap8.c").read_text()
    times = run_target(res, timeout=600)
    loop = times[LOOP]
    assert times[STEP]["flag"] == 0 and loop["flag"] == 0
    assert np.deg2rad(loop["final_error_deg"]) <= M4F_SINGLE_FINAL_ERROR_RAD
    assert loop["loop_worst_violation"] <= M4F_SINGLE_STEP_VIOLATION
    mem = res.extras["memory"]["functions"]
    rec = mem[STEP]
    assert rec["heap"] is False and not [
        c for c in rec["library_calls"]
        if c.startswith("__aeabi_d") or c == "sqrt"], rec
    flight = mem[f"wheel_qp+duty_qp+{STEP}"]
    assert flight["ram"] <= GOAL_RAM and flight["flash"] <= GOAL_FLASH
    assert abs(flight["ram"] - M4F_RQP_20_RAM) <= 0.05 * M4F_RQP_20_RAM


@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
@pytest.mark.parametrize("target, precision, horizon", [
    ("cortex-m7", "double", 9), ("cortex-m4f", "single", 9)])
def test_capped_rqp_step_meets_every_flight_goal(tmp_path, target,
                                                 precision, horizon):
    """With rqp capped at 8 the stage-wise step's flight set meets every
    figure of the goal table on the driver's slew at horizon 9, in double
    on the emulated M7 (measured: median 320,800, worst 1,586,160; 161,324
    bytes of flash, 65,456 of RAM: 80 under 64 KiB) and in float on the
    M4F (330,920 and 1,689,440; 164,656 and 33,848); over 200 Monte Carlo
    loops too (docs/benchmarks.md)."""
    from test_targets import _meets_the_step_goals

    res = export_c(tmp_path / "rqp", spacecraft="demo", horizon=horizon,
                   repeats=3, precision=precision, target=target,
                   mpc_variants=(STEP,), stagewise_qp_plugin="rqp",
                   stagewise_qp_max_iter=8, build=True)
    _meets_the_step_goals(res, STEP)


def test_cli_exports_with_rqp(tmp_path, capsys):
    """``adcs export --stagewise-qp rqp --qp-max-iter 5 --run``: the
    folder carries rqp/ and the driver's checks pass; rqp without a
    stage-wise step, or an unknown stage-wise QP, is a one-line error
    with exit status 2."""
    from adcs.cli import main

    out = tmp_path / "c"
    assert main(["export", "--out", str(out), "--mpc", STEP, "--horizon",
                 "5", "--stagewise-qp", "rqp", "--qp-max-iter", "5",
                 "--run"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out / 'rqp'}/" in printed
    assert "every closed loop reached its target" in printed
    assert (out / "rqp" / "adcs_rqp_5x11x4x8_cap5.c").is_file()
    assert "at most 5 iterations" in (out / "README.md").read_text()
    # without --mpc, --stagewise-qp exports the step it solves; in float
    single = tmp_path / "single"
    assert main(["export", "--out", str(single), "--horizon", "5",
                 "--stagewise-qp", "rqp", "--precision", "single"]) == 0
    capsys.readouterr()
    assert "mpc_sw_rti_step" in (single / "adcs_codegen.h").read_text()
    assert "#define RQP_SINGLE_PRECISION" in (
        single / "rqp" / "adcs_rqp_5x11x4x8.c").read_text()
    for bad in (["--mpc", "mpc_cond_rti_step", "--stagewise-qp", "rqp"],
                ["--mpc", STEP, "--stagewise-qp", "ipm"],
                ["--mpc", STEP, "--stagewise-qp", "rqp", "--qp-max-iter",
                 "0"]):
        try:                    # argparse exits; a toolbox error returns
            code = main(["export", "--out", str(out), *bad])
        except SystemExit as exc:
            code = exc.code
        assert code == 2, bad
        assert len(capsys.readouterr().err.strip().splitlines()) == 1


@pytest.mark.parametrize("kw", [
    {"stagewise_qp_plugin": "bogus"}, {"stagewise_qp_plugin": "RQP"},
    {"stagewise_qp_plugin": "rqp", "stagewise_qp_max_iter": 0},
    {"stagewise_qp_plugin": "rqp", "stagewise_qp_max_iter": 2.5},
    {"stagewise_qp_plugin": None, "stagewise_qp_max_iter": 8},
    {"stagewise_qp_plugin": "rqp", "mpc_variants": ("mpc_cond_rti_step",)}])
def test_export_refuses_a_bad_stagewise_qp(tmp_path, kw):
    """`export_c` answers an unknown stage-wise QP, a cap that is not a
    whole number ≥ 1, a cap for the interior point, or rqp with no
    stage-wise step exported with the toolbox's error, before writing
    anything."""
    from adcs_common.exceptions import InvalidValueError

    kw = {"mpc_variants": (STEP,), **kw}
    with pytest.raises(InvalidValueError):
        export_c(tmp_path / "out", spacecraft="demo", horizon=4, **kw)
    assert not (tmp_path / "out" / "adcs_codegen.c").exists()
