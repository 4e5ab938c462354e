"""The export driver's closed-loop check: length from the craft, verdict.

The C check is tested on a driver built around two tiny Functions (an
"MPC" that steers the quaternion straight at the target with a gain, and
an "RK4" that adds the command): a second's compile, each case with its
known end. One real export (the demo craft, a loop forced too short)
runs through ``adcs export --run``.
"""

import math
import shutil
import subprocess
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from adcs_common.quaternion import quat_from_axis_angle
from ocp.codegen.build import run_driver
from ocp.codegen.checks import (
    LOOP_MIN_STEPS,
    LOOP_SLEW_FACTOR,
    DriverCheckError,
    driver_verdict,
    loop_plan,
)
from ocp.codegen.driver import _driver_source
from ocp.codegen.result import ExportResult
from ocp.models.rigid import rigid_spacecraft
from ocp.spacecraft import load_spacecraft

needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None,
                               reason="needs gcc")

#: the driver's slew: 90° about (1, 1, 0) from rest
QF = quat_from_axis_angle([1.0, 1.0, 0.0], math.radians(90.0))


def _plan(name: str, dt: float = 0.5) -> dict:
    sc = load_spacecraft(name)
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    samples = {"mpc_step": [model.state([1.0, 0.0, 0.0, 0.0]), QF]}
    return loop_plan(model, samples, dt, rate_max=sc.rate_max)


@pytest.mark.parametrize("name, slew_time, steps", [
    ("demo", 17.1834, 86),          # 2.5 x 17.18 s / 0.5 s = 85.9
    ("meteor-m", 233.776, 1169),    # the old fixed 80 steps: 40 s
])
def test_loop_length_is_sized_from_the_craft(name, slew_time, steps):
    plan = _plan(name)
    assert plan["slew_time"] == pytest.approx(slew_time, abs=1e-3)
    assert plan["steps"] == steps
    assert plan["steps"] == math.ceil(LOOP_SLEW_FACTOR * slew_time / 0.5)
    assert plan["seconds"] == steps * 0.5
    assert plan["final_error_tol"] == pytest.approx(math.radians(0.01))
    assert plan["violation_tol"] == 1e-6
    # a longer sample: as many seconds, fewer steps (at least 20)
    assert _plan(name, dt=6.0)["steps"] == max(
        LOOP_MIN_STEPS, math.ceil(2.5 * slew_time / 6))


def test_loop_steps_must_be_a_positive_integer():
    model = SimpleNamespace(nu=4, wheels=None)
    for bad in (0, -3, 2.5, True, "10"):
        with pytest.raises(InvalidValueError, match="loop_steps"):
            loop_plan(model, {}, 0.5, steps=bad)
    assert loop_plan(model, {}, 0.5, steps=np.int64(7))["steps"] == 7


def _fake_export(tmp_path, gain: float, viol: float, nan: bool = False,
                 steps: int = 10) -> ExportResult:
    """A built driver flying the fake MPC ``steps`` steps of 0.5 s.

    ``u = gain (qf - x)``, ``x+ = x + u``: gain 1 lands on the target in
    one step, gain 0.01 ends ``(1 - 0.99**steps)`` of the way; the
    applied step's violation is ``viol``, and ``nan`` makes u NaN.
    """
    x, qf = ca.SX.sym("x", 4), ca.SX.sym("qf", 4)
    tau, dt = ca.SX.sym("tau", 3), ca.SX.sym("dt")
    z, lx, lg = ca.SX.sym("z", 8), ca.SX.sym("lam_x", 8), ca.SX.sym("lg", 2)
    u = gain * (qf - x) + (ca.sqrt(x[0] - 2.0) if nan else 0.0)
    mpc = ca.Function("mpc_fake", [x, qf, tau, z, lx, lg],
                      [u, z, lx, lg, ca.sumsqr(u), 0.0,
                       viol + 0.0 * x[0], 0.0])
    uu = ca.SX.sym("u", 4)
    rk4 = ca.Function("rk4", [x, uu, tau, dt], [x + uu])
    fns = {"rk4": rk4, "mpc_fake": mpc}
    x0 = np.array([1.0, 0.0, 0.0, 0.0])
    samples = {"rk4": [x0, np.zeros(4), np.zeros(3), np.array(0.5)],
               "mpc_fake": [x0, QF, np.zeros(3), np.zeros(8), np.zeros(8),
                            np.zeros(2)]}
    cg = ca.CodeGenerator("adcs_codegen.c", {"with_header": True})
    for f in fns.values():
        cg.add(f)
    cg.generate(f"{tmp_path}/")
    plan = loop_plan(SimpleNamespace(nu=4, wheels=None), samples, 0.5,
                     steps=steps)
    main = tmp_path / "main.c"
    main.write_text(_driver_source(fns, samples, 3, SimpleNamespace(nu=4),
                                   0.5, loop=plan))
    exe = tmp_path / "adcs_driver"
    subprocess.run(["gcc", "-std=c99", "-O1", "-o", str(exe), str(main),
                    str(tmp_path / "adcs_codegen.c"), "-lm"], check=True)
    return ExportResult(out_dir=tmp_path, functions=fns, samples=samples,
                        source=tmp_path / "adcs_codegen.c",
                        header=tmp_path / "adcs_codegen.h", driver=main,
                        makefile=main, readme=main, executable=exe,
                        extras={"closed_loop": plan})


@needs_gcc
def test_a_loop_on_target_within_its_bounds_passes(tmp_path):
    res = _fake_export(tmp_path, gain=1.0, viol=1e-9)
    run = subprocess.run([str(res.executable)], capture_output=True)
    assert run.returncode == 0
    loop = run_driver(res)["closed_loop:mpc_fake"]
    assert loop["loop_ok"] == 1 and loop["loop_finite"] == 1
    assert loop["loop_steps"] == 10 and loop["loop_seconds"] == 5.0
    assert loop["loop_final_error_deg"] < 1e-6
    assert loop["loop_worst_violation"] == 1e-9
    assert loop["loop_tolerance_deg"] == pytest.approx(0.01)


@needs_gcc
@pytest.mark.parametrize("gain, viol, nan, why", [
    # x = qf + 0.99**10 (x0 - qf): 82.04° from qf (test below)
    (0.01, 0.0, False, r"mpc_fake ends 82° from the target after 10 "
     r"steps × 0\.5 s = 5 s \(tolerance 0\.01°\)"),
    (1.0, 1e-3, False, r"mpc_fake breaks a bound \(worst applied-step "
     r"violation 0\.001 > 1e-06\)"),
    # NaN compares false with every bound: it must still fail
    (1.0, 0.0, True, "mpc_fake goes NaN"),
])
def test_a_loop_that_misses_fails_the_driver(tmp_path, gain, viol, nan, why):
    res = _fake_export(tmp_path, gain=gain, viol=viol, nan=nan)
    run = subprocess.run([str(res.executable)], capture_output=True,
                         text=True)
    assert run.returncode == 1
    assert "FAIL closed_loop:mpc_fake" in run.stdout
    with pytest.raises(DriverCheckError, match=why) as info:
        run_driver(res)
    assert info.value.times["closed_loop:mpc_fake"]["loop_ok"] == 0
    passed, line = driver_verdict(info.value.times)
    assert not passed and line.startswith("driver checks FAILED: closed "
                                          "loop mpc_fake")
    # the figures all the same, unchecked
    loop = run_driver(res, check=False)["closed_loop:mpc_fake"]
    if gain < 1.0:
        x = QF + 0.99 ** 10 * (np.array([1.0, 0.0, 0.0, 0.0]) - QF)
        want = 2.0 * math.degrees(math.acos(abs(x @ QF)
                                            / np.linalg.norm(x)))
        assert want == pytest.approx(82.0418, abs=1e-4)
        assert loop["loop_final_error_deg"] == pytest.approx(want, rel=1e-12)
    if nan:
        assert math.isnan(loop["loop_final_error_deg"])


@pytest.mark.slow
@needs_gcc
def test_cli_export_run_fails_on_a_loop_too_short(tmp_path, capsys):
    """The demo craft's condensed RTI step flown 4 steps (2 s of its
    17.2 s slew): exit status 1, one line saying where the loop ends,
    its length and why."""
    from adcs.cli import main

    code = main(["export", "--out", str(tmp_path), "--mpc",
                 "mpc_cond_rti_step", "--loop-steps", "4", "--run"])
    out = capsys.readouterr().out
    assert code == 1
    assert ("driver's closed loop: 4 steps × 0.5 s = 2 s (eigenaxis slew "
            "17.2 s; default 2.5 times that)") in out
    last = out.strip().splitlines()[-1]
    assert last.startswith("driver checks FAILED: closed loop "
                           "mpc_cond_rti_step ends ")
    assert ("from the target after 4 steps × 0.5 s = 2 s (tolerance 0.01°; "
            "the loop is shorter than the craft's eigenaxis slew, 17.2 s)"
            ) in last
    error = float(last.split(" ends ")[1].split("°")[0])
    assert 10.0 < error < 90.0
