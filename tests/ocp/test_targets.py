"""Cortex-M targets of the C export: counts, results, warnings, memory.

Skipped without arm-none-eabi-gcc and qemu-system-arm (Debian:
``apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi
qemu-system-arm``; `.ci/run` installs them).
"""

import json
import shutil
import subprocess

import numpy as np
import pytest

from ocp.codegen.export import export_c
from ocp.codegen.memory import FIELDS, call_graph, worst_stack
from ocp.codegen.target import (
    CORES,
    CROSS_CC,
    INSTRUCTIONS_PER_TICK,
    QEMU,
    STARTUP,
    compile_flags,
    link_flags,
    parse_target_output,
    run_target,
    toolchain_missing,
)

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(toolchain_missing() is not None,
                       reason=str(toolchain_missing())),
]


@pytest.fixture(scope="module")
def m7(tmp_path_factory):
    out = tmp_path_factory.mktemp("m7")
    res = export_c(out, "demo", mpc_variants=(), target="cortex-m7",
                   build=True, repeats=50)
    return res, run_target(res, timeout=120)


def test_systick_counts_one_tick_per_40_instructions(m7, tmp_path):
    """A known loop of 6 instructions: ticks = instructions / 40, the same
    on every run (qemu -icount shift=0)."""
    res, times = m7
    cal = times["_calibration"]
    assert cal["instructions"] == 24000
    assert cal["ticks"] * INSTRUCTIONS_PER_TICK == cal["instructions"]
    again = run_target(res, timeout=120)
    for name in ("min_norm", "wheel_qp", "rk4"):
        assert again[name]["median"] == times[name]["median"]
    # a wrong rate is an error, not a silently wrong table
    with pytest.raises(Exception, match="not one per 40"):
        parse_target_output("CAL ticks=601 instructions=24000\n")


@pytest.mark.parametrize("name", ["min_norm", "wheel_qp",
                                  "wheel_qp:saturated", "dynamics", "rk4",
                                  "duty_qp"])
def test_m7_double_results_equal_the_host(m7, name):
    res, times = m7
    fn = res.functions[name.split(":")[0]]
    ref = fn(*res.samples[name])
    ref = [ref] if fn.n_out() == 1 else ref
    got = times[name]["outputs"]
    assert len(got) == fn.n_out()
    for r, g in zip(ref, got):
        np.testing.assert_allclose(g, np.asarray(r).ravel(order="F"),
                                   rtol=0, atol=1e-9)
    assert times[name]["flag"] == 0


#: #28's goal for `wheel_qp` on the emulated M7 (double) and M4F
#: (single): instructions per call, deterministic (qemu -icount), so a
#: regression check rather than a timing. Measured: median 600, worst
#: 640 on both (1,040 and 960 before the closed form was rewritten;
#: docs/benchmarks.md).
WHEEL_QP_INSTRUCTIONS = 800


def test_wheel_qp_meets_its_instruction_goal_on_the_m7(m7):
    _, times = m7
    for name in ("wheel_qp", "wheel_qp:saturated"):
        assert times[name]["max"] <= WHEEL_QP_INSTRUCTIONS, times[name]
        assert times[name]["median"] >= 400, times[name]   # it did run


#: #28's goal for `duty_qp` (instructions per call). Measured: the M7
#: (double DAQP) 7,920-8,000 a call, 8,960 the first (DAQP's setup, which
#: later calls keep: `ocp.codegen.daqp_static.KEEP_MAX_NNZ`); the M4F in
#: float 9,360-9,440 a call with DAQP's float build and its proximal
#: iterations (73,880 with qrqp, which float needed before them), 10,440
#: the first: the M4F's first call is guarded by the bound below instead.
DUTY_QP_INSTRUCTIONS = 10_000
DUTY_QP_M4F_FIRST_INSTRUCTIONS = 11_000


def test_duty_qp_meets_its_instruction_goal_on_the_m7(m7):
    _, times = m7
    for name in ("duty_qp", "duty_qp:burn", "duty_qp:relaxed"):
        assert times[name]["max"] <= DUTY_QP_INSTRUCTIONS, times[name]
        assert times[name]["outputs"][3][0] in (0.0, 1.0), times[name]


def test_target_builds_clean_under_werror(m7):
    res, _ = m7
    assert res.extras["warnings"] == 0, res.extras["warning_text"][:2000]
    assert "-Werror" in compile_flags(res, CORES["cortex-m7"])
    for name in ("startup_cortex_m.c", "cortex_m.ld", "main_cortex_m.c"):
        assert (res.out_dir / name).is_file()


def test_m4f_startup_and_driver_build_clean(m7, tmp_path):
    """The M4F build of the same files (double in software) is clean."""
    res, _ = m7
    core = CORES["cortex-m4f"]
    out = res.out_dir
    proc = subprocess.run(
        [CROSS_CC, *compile_flags(res, core), str(out / "main_cortex_m.c"),
         str(out / STARTUP), str(out / "adcs_codegen.c"),
         *res.extras.get("c_sources", []),
         *link_flags(res, core), "-lm", "-o", str(tmp_path / "m4.elf")],
        capture_output=True, text=True)
    assert proc.returncode == 0 and "warning" not in proc.stderr, \
        proc.stderr[-2000:]
    assert shutil.which(QEMU)


def test_memory_report_has_its_fields(m7):
    res, times = m7
    path = res.out_dir / "memory_cortex-m7.json"
    rep = json.loads(path.read_text())
    assert rep == res.extras["memory"]
    for name in res.functions:
        rec = rep["functions"][name]
        assert set(FIELDS) <= set(rec), name
        assert rec["flash"] > 0 and rec["heap"] is False
        # the work sizes are those the generated *_work returns
        assert tuple(rec[k] for k in ("sz_arg", "sz_res", "sz_iw",
                                      "sz_w")) == times[name]["work"]
        # a target export's casadi_int is int (4 bytes on the core, as
        # the driver's sizeof says), and the work bytes count it so
        assert times[name]["work_sizeof"][0] == 4
        assert rec["work_bytes"] == (4 * (rec["sz_arg"] + rec["sz_res"])
                                     + 4 * rec["sz_iw"] + 8 * rec["sz_w"])
        # the call-graph bound covers the painted stack (+ the clock's
        # read, at most a few words)
        assert rec["stack"] + 16 >= times[name]["stack_measured"] > 0
    assert rep["functions"]["all"]["flash"] >= max(
        r["flash"] for k, r in rep["functions"].items() if k != "all")


def test_worst_stack_follows_the_call_graph():
    ci = "\n".join([
        'node: { title: "f" label: "f\\nx.c:1:1\\n16 bytes (static)" }',
        'node: { title: "x.c:g" label: "g\\nx.c:2:1\\n32 bytes (static)" }',
        'node: { title: "x.c:h" label: "h\\nx.c:3:1\\n8 bytes (static)" }',
        'node: { title: "sqrt" label: "sqrt\\n<built-in>" shape : ellipse }',
        'edge: { sourcename: "f" targetname: "x.c:g" }',
        'edge: { sourcename: "f" targetname: "x.c:h" }',
        'edge: { sourcename: "x.c:h" targetname: "sqrt" }'])
    frames, edges = call_graph(ci)
    assert worst_stack("f", frames, edges) == (48, True, ["sqrt"])


def test_unknown_target_is_an_error_and_daqp_travels(tmp_path):
    from adcs_common.exceptions import InvalidValueError

    with pytest.raises(InvalidValueError, match="target must be"):
        export_c(tmp_path, "demo", mpc_variants=(), target="avr")
    # DAQP travels in the folder (its C sources): a target takes it too
    res = export_c(tmp_path / "d", "demo", mpc_variants=(),
                   target="cortex-m7", wheel_qp_plugin="daqp")
    assert any(p.endswith("daqp.c") for p in res.extras["c_sources"])


def test_cli_export_target_run_prints_counts_and_memory(tmp_path, capsys,
                                                       monkeypatch):
    """From a folder named relative to the working directory (the
    compiler runs inside it), and no machine path in what the build
    leaves there (gcc's .su and .ci files name the sources) nor in what
    it prints (the folder as the user named it)."""
    from adcs.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["export", "--target", "cortex-m7", "--mpc", "",
                 "--out", "flight", "--run"]) == 0
    text = capsys.readouterr().out
    assert "instruction counts, not cycles" in text
    assert "memory on cortex-m7" in text and "min_norm" in text
    assert "wrote flight/daqp/" in text and "built flight/adcs_driver" in text
    assert str(tmp_path) not in text
    out = tmp_path / "flight"
    assert (out / "memory_cortex-m7.json").is_file()
    built = [p for p in out.rglob("*") if p.suffix in (".su", ".ci")]
    assert built and not any(str(tmp_path) in p.read_text() for p in built)


def test_m7_condensed_closed_loop_equals_the_host(tmp_path):
    """The exported condensed RTI step (DAQP in the folder, static
    workspace), flown 86 steps by the driver on the emulated M7 in double
    precision, ends in the state the host's driver ends in (1e-9), with
    no heap (the memory report) and every call returning 0."""
    kw = dict(mpc_variants=("mpc_cond_rti_step",), repeats=10)
    host = export_c(tmp_path / "host", "demo", build=True, **kw)
    run = subprocess.run([str(host.executable)], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:]
    line = next(s for s in run.stdout.splitlines()
                if s.startswith("STATE closed_loop:mpc_cond_rti_step:"))
    x_host = np.array([float(v) for v in line.split(":", 2)[2].split()])
    target = export_c(tmp_path / "m7", "demo", target="cortex-m7",
                      build=True, **kw)
    times = run_target(target, timeout=300)
    loop = times["closed_loop:mpc_cond_rti_step"]
    np.testing.assert_allclose(loop["state"], x_host, rtol=0, atol=1e-9)
    assert loop["final_error_deg"] < 1e-3
    assert times["mpc_cond_rti_step"]["flag"] == 0
    mem = target.extras["memory"]["functions"]
    rec = mem["mpc_cond_rti_step"]
    assert rec["heap"] is False
    # the flight set: the three linked together, one work buffer and one
    # stack for the three (they run one at a time)
    trio = mem["wheel_qp+duty_qp+mpc_cond_rti_step"]
    parts = [mem[n] for n in ("wheel_qp", "duty_qp", "mpc_cond_rti_step")]
    assert max(p["flash"] for p in parts) <= trio["flash"] \
        <= mem["all"]["flash"]
    assert trio["work_bytes"] == max(p["work_bytes"] for p in parts)
    assert trio["ram"] == (trio["static_ram"] + trio["work_bytes"]
                           + max(p["stack"] for p in parts))


#: The single-precision condensed RTI closed loop on the emulated M4F
#: (demo craft, 90° slew, 80 steps of 0.5 s, the driver's loop then; now
#: 86, `ocp.codegen.checks`; `benchmarks.embedded`):
#: measured final error 2.80e-2° (4.9e-4 rad; the double loop 2e-6°)
#: and worst applied-step violation 1.8e-6 of the bound (momentum h_max:
#: float rounding; the torques are projected onto their box, which a
#: float QP point left by up to 5.2e-5 of m_max; the double loop 1e-13).
#: Bounds: 1e-3 rad, and 1e-5.
M4F_SINGLE_FINAL_ERROR_RAD = 1e-3
M4F_SINGLE_STEP_VIOLATION = 1e-5


def test_m4f_single_condensed_closed_loop(tmp_path):
    """The float export (DAQP's float build, static workspace) flown 80
    steps on the emulated Cortex-M4F: reaches the target, leaves no bound
    beyond the documented tolerance, no heap, no software double in the
    MPC step, every call returning 0; wheel_qp and duty_qp equal the
    double Functions within the float tolerances."""
    res = export_c(tmp_path / "m4f", "demo", precision="single",
                   mpc_variants=("mpc_cond_rti_step",), target="cortex-m4f",
                   build=True, repeats=30)
    assert res.extras["cflags"] == ["-DDAQP_SINGLE_PRECISION"]
    times = run_target(res, timeout=600)
    loop = times["closed_loop:mpc_cond_rti_step"]
    assert np.deg2rad(loop["final_error_deg"]) <= M4F_SINGLE_FINAL_ERROR_RAD
    text = times["_stdout"]["text"]
    worst = float(text.split("closed_loop:mpc_cond_rti_step worst "
                             "applied-step violation ")[1].split()[0])
    assert worst <= M4F_SINGLE_STEP_VIOLATION, worst
    for name in ("mpc_cond_rti_step", "wheel_qp", "duty_qp"):
        assert times[name]["flag"] == 0, name
    assert times["wheel_qp"]["max"] <= WHEEL_QP_INSTRUCTIONS, \
        times["wheel_qp"]
    for name in ("duty_qp", "duty_qp:burn", "duty_qp:relaxed"):
        assert times[name]["median"] <= DUTY_QP_INSTRUCTIONS, times[name]
        assert times[name]["max"] <= DUTY_QP_M4F_FIRST_INSTRUCTIONS, \
            times[name]
    rec = res.extras["memory"]["functions"]["mpc_cond_rti_step"]
    assert rec["heap"] is False
    assert not [c for c in rec["library_calls"]
                if c.startswith("__aeabi_d") or c == "sqrt"], rec
    # the Functions in double arithmetic on the float-rounded inputs;
    # tolerances of tests/ocp/test_single_precision.py (TOL_WHEEL_QP of
    # m_max = 0.05, TOL_DUTY_QP)
    for name, atol in (("wheel_qp", 1e-5 * 0.05), ("duty_qp", 1e-4)):
        fn = res.functions[name]
        ref = fn(*[np.asarray(a, float).astype(np.float32).astype(float)
                   for a in res.samples[name]])
        got = times[name]["outputs"]
        np.testing.assert_allclose(got[0], np.asarray(ref[0]).ravel(),
                                   rtol=0, atol=atol)
    # the float duty_qp is certified where the double one is: same status
    assert times["duty_qp"]["outputs"][3][0] == float(ref[3])


#: The flight-code goals (docs/benchmarks.md, "The horizon against the
#: flight-code goals"), per step of the closed loop and for the flight
#: set linked together [instructions, bytes].
GOAL_MEDIAN, GOAL_WORST = 400_000, 2_000_000
GOAL_FLASH, GOAL_RAM = 256 * 1024, 64 * 1024


def _meets_the_step_goals(res, step: str = "mpc_cond_rti_step"
                          ) -> tuple[dict, dict]:
    """Run ``res``'s driver on its target and check the closed loop of
    ``step``: its median and worst step, its final error, the flight
    set's flash and RAM and that no function calls the heap; returns the
    counts and the memory report's functions."""
    times = run_target(res, timeout=600)
    loop = times[f"closed_loop:{step}"]
    steps = np.asarray(loop["steps"])
    assert np.median(steps) <= GOAL_MEDIAN, np.median(steps)
    assert steps.max() <= GOAL_WORST, steps.max()
    assert np.deg2rad(loop["final_error_deg"]) <= M4F_SINGLE_FINAL_ERROR_RAD
    mem = res.extras["memory"]["functions"]
    flight = mem[f"wheel_qp+duty_qp+{step}"]
    assert flight["flash"] <= GOAL_FLASH, flight
    assert flight["ram"] <= GOAL_RAM, flight
    assert not any(mem[n]["heap"] for n in res.functions)
    return times, mem


def test_m4f_single_horizon_7_meets_every_flight_goal(tmp_path):
    """In float on the emulated Cortex-M4F at horizon 7 the condensed RTI
    step and its flight set meet every figure of the goal table: the
    closed loop's median and worst step, cold included (measured 139,200,
    655,440 and 432,160 instructions), the flight set's flash and RAM
    (179,128 and 57,076 bytes), wheel_qp and duty_qp a call, no heap."""
    res = export_c(tmp_path / "n7", "demo", horizon=7, precision="single",
                   mpc_variants=("mpc_cond_rti_step",), target="cortex-m4f",
                   build=True, repeats=10)
    times, _ = _meets_the_step_goals(res)
    assert times["wheel_qp"]["max"] <= WHEEL_QP_INSTRUCTIONS
    assert times["duty_qp"]["median"] <= DUTY_QP_INSTRUCTIONS


@pytest.mark.parametrize("target, precision, horizon", [
    ("cortex-m7", "double", 6), ("cortex-m4f", "single", 11)])
def test_capped_pqp_step_meets_every_flight_goal(tmp_path, target,
                                                 precision, horizon):
    """With the condensed QP by pqp capped at 8 (no DAQP in the step), the
    flight set meets every figure of the goal table at horizon 6 in
    double on the emulated M7 (measured: worst step 284,800, flight set
    177,024 bytes of flash and 62,480 of RAM) and at horizon 11 in float
    on the M4F (718,560; 181,680 and 62,740)."""
    res = export_c(tmp_path / "pqp", "demo", horizon=horizon,
                   precision=precision, mpc_variants=("mpc_cond_rti_step",),
                   condensed_qp_plugin="pqp", condensed_qp_max_iter=8,
                   target=target, build=True, repeats=3)
    _, mem = _meets_the_step_goals(res)
    assert mem["mpc_cond_rti_step"]["static_ram"] <= 64  # no DAQP workspace
