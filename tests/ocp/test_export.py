"""C export: compiles, agrees with the CasADi Functions, driver runs."""

import shutil

import casadi as ca
import numpy as np
import pytest

from allocation import WheelArray, conic_allocator_function
from adcs_common.exceptions import InvalidValueError
from ocp.codegen.export import (
    CompilerNotFound,
    daqp_available,
    export_c,
    patch_qrqp,
    run_driver,
)
from thrusters import six_thruster_unit

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc"),
]

RNG = np.random.default_rng(11)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("export")
    arr = WheelArray.pyramid(h_max=0.2, m_max=0.05)
    return export_c(out, wheels=arr, thrusters=six_thruster_unit(),
                    mpc_variants=("mpc_rti_step",), build=True,
                    repeats=200)


def test_files_written(exported):
    r = exported
    for p in (r.source, r.header, r.driver, r.makefile, r.readme,
              r.executable, r.shared_library):
        assert p.exists(), p
    text = r.header.read_text()
    for name in ("min_norm", "wheel_qp", "duty_qp", "dynamics", "rk4",
                 "mpc_rti_step"):
        assert f"int {name}(" in text
    assert "mpc_rti_step" in r.readme.read_text()
    # 4 wheels: the wheel QP is solved in closed form, no solver library
    plugin = "daqp" if daqp_available() else "qrqp"
    assert r.extras["wheel_qp_plugin"] == plugin
    assert r.extras["wheel_qp_method"] == "closed form"
    assert "daqp/api.h" not in r.source.read_text()
    assert "libdaqpstat.a" not in r.makefile.read_text()
    assert "-O3" in r.makefile.read_text()


@pytest.mark.skipif(not daqp_available(), reason="needs casadi daqp")
def test_wheel_qp_conic_daqp_links_daqp(tmp_path):
    arr = WheelArray.pyramid(h_max=0.2, m_max=0.05)
    res = export_c(tmp_path, wheels=arr, mpc_variants=(),
                   wheel_qp_fast_path=False, build=True, repeats=50)
    assert res.extras["wheel_qp_method"] == "conic"
    assert "daqp/api.h" in res.source.read_text()
    assert "libdaqpstat.a" in res.makefile.read_text()
    _check_wheel_qp_c(res)


@pytest.mark.parametrize("failed", [(), (1,)])
def test_closed_form_wheel_qp_c_equals_conic(tmp_path, failed):
    """The exported closed form equals the conic QP, saturated or not."""
    arr = WheelArray.pyramid(h_max=0.2, m_max=0.05).with_failed(*failed)
    res = export_c(tmp_path, wheels=arr, mpc_variants=(), build=True,
                   repeats=50)
    assert res.extras["wheel_qp_method"] == "closed form"
    assert "SOLVER_LIBS = -lm" in res.makefile.read_text()
    _check_wheel_qp_c(res, reference=conic_allocator_function(
        arr, dt=0.5, plugin="qrqp", fast_path=False))
    t = run_driver(res)
    assert t["wheel_qp:saturated"]["median_us"] > 0.0


def _check_wheel_qp_c(res, reference=None):
    """C wheel_qp equals its Function (and ``reference``).

    On interior, saturated and momentum-bound demands.
    """
    f = res.functions["wheel_qp"]
    ext = ca.external("wheel_qp", str(res.shared_library))
    wheels_m = 0.05
    saturated = 0
    for k in range(60):
        scale = (0.02, 0.1, 0.4)[k % 3]
        args = [scale * RNG.normal(size=3),
                0.2 * RNG.uniform(-1.0, 1.0, 4)]
        a = [np.asarray(x).ravel() for x in f.call(args)]
        b = [np.asarray(x).ravel() for x in ext.call(args)]
        for ya, yb in zip(a, b):
            np.testing.assert_allclose(yb, ya, atol=1e-10, rtol=0)
        assert np.all(np.abs(b[0]) <= wheels_m + 1e-15)
        saturated += a[1][0] < 1.0
        if reference is not None:
            c = [np.asarray(x).ravel() for x in reference.call(args)]
            if c[2][0] < 1e-9:   # the reference QP is feasible
                np.testing.assert_allclose(b[0], c[0], atol=1e-10, rtol=0)
                assert b[1][0] == pytest.approx(c[1][0], abs=1e-15)
                assert b[2][0] < 1e-12
    assert 10 < saturated < 50


def test_wheel_qp_qrqp_fallback_is_self_contained(tmp_path):
    arr = WheelArray.pyramid(h_max=0.2, m_max=0.05)
    res = export_c(tmp_path, wheels=arr, mpc_variants=(),
                   wheel_qp_plugin="qrqp", build=True, repeats=50)
    assert res.extras["wheel_qp_plugin"] == "qrqp"
    assert "daqp" not in res.source.read_text()
    assert "SOLVER_LIBS = -lm" in res.makefile.read_text()
    f = res.functions["wheel_qp"]
    ext = ca.external("wheel_qp", str(res.shared_library))
    for _ in range(20):
        args = _random_inputs("wheel_qp", f, res.samples)
        for a, b in zip(f.call(args), ext.call(args)):
            np.testing.assert_allclose(np.asarray(b), np.asarray(a),
                                       atol=1e-10, rtol=0)
    with pytest.raises(InvalidValueError, match="wheel_qp_plugin"):
        export_c(tmp_path, wheels=arr, mpc_variants=(),
                 wheel_qp_plugin="osqp")


def _random_inputs(name, f, samples):
    """Perturbed sample inputs (random, within the physical ranges)."""
    out = []
    for a in samples[name]:
        a = np.asarray(a, dtype=float)
        out.append(a + 0.2 * np.abs(a).max(initial=1e-3)
                   * RNG.uniform(-1, 1, a.shape) if a.size else a)
    return out


@pytest.mark.parametrize("name", ["min_norm", "wheel_qp", "duty_qp",
                                  "dynamics", "rk4"])
def test_generated_c_equals_casadi(exported, name):
    f = exported.functions[name]
    ext = ca.external(name, str(exported.shared_library))
    for _ in range(20):
        args = _random_inputs(name, f, exported.samples)
        for a, b in zip(f.call(args), ext.call(args)):
            np.testing.assert_allclose(np.asarray(b), np.asarray(a),
                                       atol=1e-10, rtol=0)


def test_generated_mpc_step_equals_casadi(exported):
    name = "mpc_rti_step"
    f = exported.functions[name]
    ext = ca.external(name, str(exported.shared_library))
    args = list(exported.samples[name])
    # the source's qrqp reuses factorizations (patch_qrqp): same results
    assert exported.extras["qrqp_patched"]
    assert "ocp.codegen.patch_qrqp" in exported.source.read_text()
    for _ in range(8):       # closed loop: feed the plan back
        a = f.call(args)
        b = ext.call(args)
        for ya, yb in zip(a, b):
            np.testing.assert_allclose(np.asarray(yb), np.asarray(ya),
                                       atol=1e-10, rtol=0)
        args = [args[0], args[1], args[2], a[1], a[2], a[3]]
    assert np.max(np.abs(np.asarray(a[0]))) <= 0.05 + 1e-12


def test_driver_runs_and_times(exported):
    t = run_driver(exported)
    for name in ("min_norm", "wheel_qp", "wheel_qp:saturated", "duty_qp",
                 "dynamics", "rk4", "mpc_rti_step",
                 "closed_loop:mpc_rti_step"):
        assert t[name]["median_us"] > 0.0
    # the C closed loop (RK4 plant, 80 steps of 0.5 s) ends on target
    assert t["closed_loop:mpc_rti_step"]["final_error_deg"] < 1e-2
    # closed forms are sub-microsecond, the MPC step is milliseconds
    assert t["min_norm"]["median_us"] < 5.0
    assert t["wheel_qp"]["median_us"] < 50.0
    assert t["closed_loop:mpc_rti_step"]["median_us"] < 50_000.0


def test_patch_qrqp_needs_its_text():
    text = "int main(void) { return 0; }\n"
    assert patch_qrqp(text) == (text, False)


def test_missing_compiler_is_a_clear_error(tmp_path):
    arr = WheelArray.pyramid(h_max=0.2, m_max=0.05)
    with pytest.raises(CompilerNotFound, match="no-such-cc"):
        export_c(tmp_path, wheels=arr, mpc_variants=(), build=True,
                 cc="no-such-cc")
    assert (tmp_path / "adcs_codegen.c").exists()


def test_cli_export_writes_sources(tmp_path, capsys):
    from adcs.cli import main

    assert main(["export", "--out", str(tmp_path), "--mpc", ""]) == 0
    assert (tmp_path / "adcs_codegen.c").exists()
    assert (tmp_path / "main.c").exists()
    assert "wrote" in capsys.readouterr().out
