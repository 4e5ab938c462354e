"""`benchmarks.embedded_profile`: the instructions of each call of an
exported step, by function, from qemu's block trace; every loop step's
total equals the driver's SysTick count of it."""

from collections import Counter

import numpy as np
import pytest

from benchmarks.embedded_profile import (Symbols, format_profile,
                                         generated_names, loop_profiles,
                                         object_parts, parse_trace,
                                         profile_export)
from ocp.codegen.export import export_c
from ocp.codegen.target import toolchain_missing

#: functions at 0x100 (the step), 0x200 (a kernel), 0x300 (the driver's
#: loop), 0x400 (SysTick's handler)
SYMBOLS = Symbols([0x100, 0x200, 0x300, 0x400], [0x180, 0x280, 0x380, 0x480],
                  ["step", "kernel", "loop", "SysTick_Handler"])


def _block(host: str, addrs: list[int], name: str) -> list[str]:
    return (["----------------", f"IN: {name}"]
            + [f"0x{a:08x}:  4298       cmp      r0, r3" for a in addrs]
            + ["", _trace(host, addrs[0], name)])


def _trace(host: str, pc: int, name: str) -> str:
    return f"Trace 0: {host} [00800408/{pc:08x}/00000110/ff020200] {name}"


def test_a_call_counts_its_blocks_until_the_driver_runs_again():
    log = [
        *_block("0x7f01", [0x300, 0x302], "loop"),         # before: not counted
        *_block("0x7f02", [0x100, 0x102, 0x104], "step"),  # call 1
        *_block("0x7f03", [0x200, 0x202, 0x204, 0x206], "kernel"),
        # the kernel's block rewound at its third instruction (I/O)
        "cpu_io_recompile: rewound execution of TB to 00000204",
        *_block("0x7f04", [0x204, 0x206], "kernel"),
        *_block("0x7f05", [0x400], "SysTick_Handler"),     # counts, no end
        _trace("0x7f03", 0x200, "kernel"),                 # again: 4
        # traced, then stopped before it ran: nothing
        _trace("0x7f03", 0x200, "kernel"),
        "Stopped execution of TB chain before 0x7f03 [00000200] kernel",
        _trace("0x7f01", 0x300, "loop"),                   # the call ends
        _trace("0x7f03", 0x200, "kernel"),                 # outside a call
        # the entry traced, stopped before it ran: no call yet
        _trace("0x7f02", 0x100, "step"),
        "Stopped execution of TB chain before 0x7f02 [00000100] step",
        _trace("0x7f02", 0x100, "step"),                   # call 2
        _trace("0x7f03", 0x200, "kernel"),
    ]
    calls = parse_trace(log, SYMBOLS, "step", {"loop", "SysTick_Handler"})
    assert calls == [Counter(step=3, kernel=2 + 2 + 4, SysTick_Handler=1),
                     Counter(step=3, kernel=4)]


def test_loop_profiles_refuse_a_trace_that_misses_the_driver_counts():
    solve = "adcs_rqp_20x11x4x8_cap8_rqp_solve.constprop.0"
    calls = [Counter(a=5), Counter({"a": 1000, solve: 200}), Counter(a=3000)]
    fig = {"closed_loop:s": {"steps": [1240.0, 3040.0]}}
    loop, counts = loop_profiles(calls, fig, "s")
    assert loop == calls[1:] and list(counts) == [1240.0, 3040.0]
    with pytest.raises(Exception, match="do not match"):
        loop_profiles(calls, {"closed_loop:s": {"steps": [1240.0, 9040.0]}},
                      "s")
    text = format_profile({"median": calls[1], "worst": calls[2]},
                          {"a": "rqp", solve: "rqp"}, {"a": "sw_lin"})
    assert "| sw_lin | 1,000 | 3,000 |" in text
    assert "| rqp_solve | 200 | 0 |" in text   # the wrapper's prefix off
    assert "| rqp | 1,200 (100 %) | 3,000 (100 %) |" in text
    assert "| **step** | **1,200** | **3,000** |" in text


@pytest.mark.slow
@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
def test_m7_profile_of_a_short_horizon_step_sums_to_the_driver_counts(
        tmp_path):
    """The condensed RTI step at horizon 3 on the emulated M7: each of
    the closed loop's traced calls within 200 instructions of the
    driver's count, the generated functions by their names."""
    res = export_c(tmp_path, "demo", horizon=3,
                   mpc_variants=("mpc_cond_rti_step",), target="cortex-m7",
                   build=True, repeats=5)
    calls, figures = profile_export(res, "mpc_cond_rti_step", timeout=300)
    loop, counts = loop_profiles(calls, figures, "mpc_cond_rti_step")
    assert len(loop) == len(counts) > 50
    totals = np.array([sum(c.values()) for c in loop])
    assert np.all(np.abs(totals - counts) <= 200)
    names = generated_names(res.out_dir)
    assert "rk4" in names.values()
    parts = object_parts(res, "cortex-m7")
    assert parts["mpc_cond_rti_step"] == "generated (CasADi)"
    assert "DAQP" in {parts.get(f) for c in loop for f in c}
