"""The driver's closed loops from many starts (`ocp.codegen.loop_starts`):
one loop per start on the host and on the emulated Cortex-M7, the same
final states, and the default driver unchanged."""

import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from benchmarks.mpc_worst_case import random_states
from ocp.codegen.build import build_exported, run_driver
from ocp.codegen.export import export_c
from ocp.codegen.loop_starts import loop_key, write_loop_starts
from ocp.codegen.target import build_target, run_target, toolchain_missing
from ocp.models.rigid import rigid_spacecraft
from ocp.spacecraft import load_spacecraft

NAME = "mpc_cond_rti_step"

#: Horizon and loop length of the tests: short enough to cross-build and
#: emulate in ~10 s; 120 steps of 0.5 s as `benchmarks.mpc_worst_case`.
#: Measured at horizon 5 on the first two draws of seed 0: final errors
#: 9.9e-4° and 1.7e-3° (tolerance 0.01°), worst applied-step violations
#: 1.3e-14 and 8.3e-14 (tolerance 1e-6), 130,560 instructions a step
#: (median) on the M7.
HORIZON, STEPS = 5, 120


def _starts(k: int = 2) -> np.ndarray:
    """The first ``k`` random states of the host Monte Carlo (seed 0)."""
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    return np.array(random_states(model, k, np.random.default_rng(0)))


@pytest.fixture(scope="module")
def m7_export(tmp_path_factory):
    """A Cortex-M7 export of the condensed RTI step, its drivers flying
    two random starts to the identity."""
    out = tmp_path_factory.mktemp("starts")
    res = export_c(out, "demo", horizon=HORIZON, dt=0.5, target="cortex-m7",
                   mpc_variants=(NAME,), repeats=10)
    return write_loop_starts(res, _starts(), steps=STEPS)


@pytest.fixture(scope="module")
def host_times(m7_export):
    return run_driver(build_exported(m7_export), timeout=120)


def test_host_driver_flies_one_loop_per_start(m7_export, host_times):
    """Each start's loop is parsed under its own key, is 120 steps long,
    reaches the identity within the check's 0.01° and keeps the bounds;
    the sample's single loop is not flown."""
    starts = m7_export.extras["loop_starts"]
    assert starts.shape == (2, 11)
    assert f"closed_loop:{NAME}" not in host_times
    for k in range(2):
        t = host_times[loop_key(NAME, k)]
        assert t["loop_ok"] == 1 and t["loop_steps"] == STEPS
        assert len(t["steps_us"]) == STEPS and len(t["state"]) == 11
        assert t["final_error_deg"] < 0.005
        assert t["loop_worst_violation"] < 1e-10
        # the loop starts where asked: far from the target
        assert np.degrees(2 * np.arccos(abs(starts[k, 0]))) > 30.0
    # two starts, two different final states (each loop its own)
    a, b = (np.array(host_times[loop_key(NAME, k)]["state"])
            for k in range(2))
    assert np.abs(a - b).max() > 1e-9


def test_python_loop_flies_the_export_horizon(tmp_path, host_times):
    """`benchmarks.mpc_worst_case.fly` starts its plan at the horizon of
    the export it flies (here 5, not the benchmark's default 20) and ends
    where the C driver's loop from the same start ends."""
    import casadi as ca

    from benchmarks.mpc_worst_case import fly

    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    lib = export_c(tmp_path, sc, horizon=HORIZON, dt=0.5,
                   mpc_variants=(NAME,), build=True).shared_library
    f = ca.external(NAME, str(lib))
    assert f.nnz_in(3) == (HORIZON + 1) * model.nx + HORIZON * model.nu
    for k, x0 in enumerate(_starts()):
        loop = fly(f, model, x0, STEPS, 0.5)
        assert loop["times"].shape == (STEPS,)
        assert loop["kkt"].max() < 1e-6 and loop["violation"] < 1e-10
        c = host_times[loop_key(NAME, k)]["loop_final_error_deg"]
        assert np.rad2deg(loop["final_error"]) == pytest.approx(
            c, rel=1e-6, abs=1e-12)


@pytest.mark.slow
@pytest.mark.skipif(toolchain_missing() is not None,
                    reason=str(toolchain_missing()))
def test_m7_loops_equal_the_host_per_start(m7_export, host_times):
    """On the emulated M7 (double precision) every start's loop reaches
    its target and ends in the host driver's final state (1e-9); each
    step is counted, the cold first one above the median."""
    times = run_target(build_target(m7_export), timeout=300)
    for k in range(2):
        t, h = times[loop_key(NAME, k)], host_times[loop_key(NAME, k)]
        assert t["loop_ok"] == 1 and t["flag"] == 0
        assert t["final_error_deg"] < 0.005
        np.testing.assert_allclose(t["state"], h["state"], rtol=0,
                                   atol=1e-9)
        steps = np.array(t["steps"])
        assert steps.shape == (STEPS,)
        assert 5e4 < np.median(steps) < 5e5   # measured 130,560
        assert steps[0] > np.median(steps)
        assert t["max_warm"] == steps[1:].max()


def test_default_driver_has_one_loop_and_bad_starts_raise(tmp_path):
    """Without starts the driver flies the sample's loop (no start
    array); starts of the wrong shape, a short target or no MPC step
    are errors."""
    res = export_c(tmp_path / "a", "demo", horizon=HORIZON,
                   mpc_variants=(NAME,), repeats=10)
    text = res.driver.read_text()
    assert "loop_starts" not in text
    assert f'closed_loop("{NAME}", {NAME}' in text
    new = write_loop_starts(res, _starts(3), steps=40)
    text = new.driver.read_text()
    assert "static casadi_real loop_starts[33]" in text
    assert f'"{NAME}#2"' in text and new.extras["closed_loop"]["steps"] == 40
    with pytest.raises(InvalidValueError, match="starts must be"):
        write_loop_starts(res, np.zeros((2, 7)))
    with pytest.raises(InvalidValueError, match="qf must have 4"):
        write_loop_starts(res, _starts(1), qf=[1.0, 0.0, 0.0])
    with pytest.raises(InvalidValueError, match="finite"):
        write_loop_starts(res, np.full((1, 11), np.nan))
    none = export_c(tmp_path / "b", "demo", mpc_variants=(), repeats=10)
    with pytest.raises(InvalidValueError, match="no MPC step"):
        write_loop_starts(none, _starts(1))


def test_target_table_pools_every_step():
    """`benchmarks.mpc_worst_case.pool_loops` pools the loops' steps:
    median and worst after each cold step over all of them, the worst
    cold step apart; `format_target` tables them and names the draws of
    the worst steps."""
    from benchmarks.mpc_worst_case import (_loop_figures, format_target,
                                           pool_loops)

    steps = [np.array([9e6, 1e6, 2e6, 1e6]), np.array([5e6, 1e6, 3e6, 1e6])]
    fig = [_loop_figures(s) for s in steps]
    assert fig[0] == {"median": 1e6, "p99": pytest.approx(1.98e6),
                      "worst": 2e6, "cold": 9e6}
    loops = [{"angle_deg": 90.0, "rate": 0.02, "target": f,
              "host": {"median": 50.0, "worst": 90.0, "cold": 300.0},
              "final_error_deg": 1e-5, "violation": 1e-13, "ok": True,
              "host_final_error_deg": 1e-5, "python_final_error_deg": 1e-5,
              "python_violation": 1e-13, "state_diff": 0.0} for f in fig]
    out = {"target": "cortex-m7", "name": NAME, "draws": 2, "steps": 4,
           "seed": 0, "loops": loops, "ok": True,
           "seconds": {"build": 1.0, "emulation": 1.0},
           "all": pool_loops(steps),
           "host_all": {"median": 50.0, "p99": 90.0, "worst": 90.0,
                        "worst_cold": 300.0}}
    assert out["all"] == {"median": 1e6, "p99": pytest.approx(2.95e6),
                          "worst": 3e6, "worst_cold": 9e6}
    text = format_target(out)
    assert "| all 2 | | **1,000,000** | 2,950,000 | **3,000,000** | " \
           "**9,000,000** |" in text
    assert "Worst step after the cold one: draw 1; worst cold step: " \
           "draw 0; loops failing the driver's check: none" in text
