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
from thrusters import DUTY_STATUS, DutyCycleAllocator, six_thruster_unit

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
                    mpc_variants=("mpc_rti_step", "mpc_cond_rti_step",
                                  "mpc_cond_step", "mpc_sw_rti_step",
                                  "mpc_sw_step", "mpc_robust_rti_step"),
                    build=True, repeats=200)


def test_zeros_are_sized_for_the_public_inputs(exported):
    """`patch_zeros`: the NULL-argument zeros hold the largest public
    input, not the condensed QP's stacked rows (6,720 nonzeros) CasADi
    sized them for."""
    text = exported.source.read_text()
    size = int(text.split("casadi_zeros[")[1].split("]")[0])
    assert size == max(f.nnz_in(i) for f in exported.functions.values()
                       for i in range(f.n_in()))


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
    # the duty QP's fast path links DAQP when it is there
    assert r.extras["duty_qp_plugin"] == plugin
    # DAQP's sources travel in the folder, no library from elsewhere
    assert ('"daqp/api.h"' in r.source.read_text()) == (plugin == "daqp")
    assert ("daqp/api.c" in r.makefile.read_text()) == (plugin == "daqp")
    assert "libdaqpstat" not in r.makefile.read_text()
    assert "-O3" in r.makefile.read_text()
    # flight builds use -Werror: the source compiles warning-free, once
    assert r.extras["warnings"] == 0, r.extras["warning_text"][:2000]
    make = r.makefile.read_text()
    assert "-Wall -Wextra -Werror" in make
    assert "main.c $(ADCS_OBJECTS)" in make


@pytest.mark.skipif(not daqp_available(), reason="needs casadi daqp")
def test_wheel_qp_conic_daqp_links_daqp(tmp_path):
    arr = WheelArray.pyramid(h_max=0.2, m_max=0.05)
    res = export_c(tmp_path, wheels=arr, mpc_variants=(),
                   wheel_qp_fast_path=False, build=True, repeats=50)
    assert res.extras["wheel_qp_method"] == "conic"
    assert '"daqp/api.h"' in res.source.read_text()
    assert "daqp/api.c" in res.makefile.read_text()
    assert list(res.extras["daqp_static"]) != []
    _check_wheel_qp_c(res)


@pytest.mark.parametrize("failed", [(), (1,)])
def test_closed_form_wheel_qp_c_equals_conic(tmp_path, failed):
    """The exported closed form equals the conic QP, saturated or not."""
    arr = WheelArray.pyramid(h_max=0.2, m_max=0.05).with_failed(*failed)
    res = export_c(tmp_path, wheels=arr, mpc_variants=(), build=True,
                   repeats=50)
    assert res.extras["wheel_qp_method"] == "closed form"
    assert "ADCS_SOURCES = adcs_codegen.c\n" in res.makefile.read_text()
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
    assert "ADCS_SOURCES = adcs_codegen.c\n" in res.makefile.read_text()
    assert not (tmp_path / "daqp").exists()
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


def duty_cycles(rng, n):
    """Yield holds, burns, bound-relaxing and infeasible demands."""
    alloc = DutyCycleAllocator(six_thruster_unit(), 2.0, 0.012)
    for i in range(n):
        P_T = 0.0 if i % 2 else rng.uniform(0.0, 1.0)
        M = rng.uniform(-1, 1, 2) * (0.004, 0.02, 0.3)[i % 3]
        H = (rng.uniform(-0.01, 0.01), 0.0, rng.uniform(-0.01, 0.01))
        yield alloc, alloc.theta(P_T, M, H, rng.uniform(-1e-5, 1e-5, 3))


def test_duty_qp_in_c_equals_the_allocator_and_says_its_status(exported):
    """The C ``duty_qp`` is the Python allocator's answer (1e-10)."""
    ext = ca.external("duty_qp", str(exported.shared_library))
    seen = set()
    for alloc, th in duty_cycles(np.random.default_rng(4), 90):
        ref = alloc.solve_theta(th)
        duty, slack, viol, status = (np.asarray(v).ravel()
                                     for v in ext(th, np.ones(6)))
        status = DUTY_STATUS[int(status[0])]
        seen.add(status)
        assert status == ref.status
        if ref.success:
            np.testing.assert_allclose(duty, ref.duty, atol=1e-10, rtol=0)
            assert viol[0] <= 1e-6
    assert seen == {"optimal", "bound_relaxed", "infeasible"}
    for th, km in [(np.full(9, np.nan), np.ones(6)),
                   (np.zeros(9), np.r_[1.0, 1.0, 0.0, 1.0, 1.0, 1.0])]:
        out = [np.asarray(v).ravel() for v in ext(th, km)]
        assert DUTY_STATUS[int(out[3][0])] == "invalid_input"
        assert np.all(out[0] == 0.0)
    # DAQP conics: the duty QP's and two (bounds, rows) per condensed MPC
    # variant (RTI and to convergence)
    assert exported.extras["daqp_patched"] == (
        5 if exported.extras["duty_qp_plugin"] == "daqp" else 0)


def test_duty_qp_in_c_writes_every_output_on_every_call(exported):
    """Raw C calls with one set of output buffers: nothing is left over."""
    import ctypes

    lib = ctypes.CDLL(str(exported.shared_library))
    cint = ctypes.c_longlong
    sizes = [cint() for _ in range(4)]
    lib.duty_qp_work(*[ctypes.byref(v) for v in sizes])
    n_arg, n_res, n_iw, n_w = (max(v.value, 4) for v in sizes)
    iw = (cint * n_iw)()
    w = (ctypes.c_double * n_w)()
    theta = (ctypes.c_double * 9)()
    kmax = (ctypes.c_double * 6)(*np.ones(6))
    outs = [(ctypes.c_double * k)() for k in (6, 1, 1, 1)]
    arg = (ctypes.POINTER(ctypes.c_double) * n_arg)(
        ctypes.cast(theta, ctypes.POINTER(ctypes.c_double)),
        ctypes.cast(kmax, ctypes.POINTER(ctypes.c_double)))
    res = (ctypes.POINTER(ctypes.c_double) * n_res)(
        *[ctypes.cast(o, ctypes.POINTER(ctypes.c_double)) for o in outs])
    ext = ca.external("duty_qp", str(exported.shared_library))
    cases = [th for _, th in duty_cycles(np.random.default_rng(5), 12)]
    cases.insert(3, np.full(9, np.inf))
    for th in cases:
        for o in outs:            # poison: every value must be rewritten
                ctypes.memmove(o, (ctypes.c_double * len(o))(
                *[np.nan] * len(o)), ctypes.sizeof(o))
        theta[:] = list(th)
        assert lib.duty_qp(arg, res, iw, w, 0) == 0
        want = [np.asarray(v).ravel() for v in ext(th, np.ones(6))]
        for o, v in zip(outs, want):
            np.testing.assert_array_equal(np.array(o[:]), v)


def test_driver_runs_and_times(exported):
    t = run_driver(exported)
    for name in ("min_norm", "wheel_qp", "wheel_qp:saturated", "duty_qp",
                 "duty_qp:burn", "duty_qp:relaxed", "dynamics", "rk4",
                 "mpc_rti_step", "closed_loop:mpc_rti_step"):
        assert t[name]["median_us"] > 0.0
        assert t[name].get("flag", 0) == 0     # every call returned 0
    assert t["duty_qp"]["first_us"] > 0.0
    # the C closed loop (RK4 plant, 86 steps of 0.5 s: 2.5 times the
    # 17.2 s eigenaxis slew) ends on target and passes its check
    assert t["closed_loop:mpc_rti_step"]["final_error_deg"] < 1e-2
    for name in ("mpc_rti_step", "mpc_cond_rti_step", "mpc_cond_step",
                 "mpc_sw_rti_step", "mpc_sw_step", "mpc_robust_rti_step"):
        loop = t[f"closed_loop:{name}"]
        assert loop["loop_ok"] == 1 and loop["calls"] == 86
        assert loop["loop_seconds"] == 43.0
        assert loop["loop_worst_violation"] < 1e-9
    # closed forms are sub-microsecond, the MPC step is milliseconds
    assert t["min_norm"]["median_us"] < 5.0
    assert t["wheel_qp"]["median_us"] < 50.0
    assert t["closed_loop:mpc_rti_step"]["median_us"] < 50_000.0
    # the condensed RTI: same target, no bound broken, faster
    cond = t["closed_loop:mpc_cond_rti_step"]
    assert cond["final_error_deg"] < 1e-3
    assert cond["median_us"] < t["closed_loop:mpc_rti_step"]["median_us"]
    full = t["closed_loop:mpc_cond_step"]
    assert full["final_error_deg"] < 1e-3
    # the stage-wise steps end where the condensed ones do
    for sw, cn in (("mpc_sw_rti_step", "mpc_cond_rti_step"),
                   ("mpc_sw_step", "mpc_cond_step")):
        assert abs(t[f"closed_loop:{sw}"]["final_error_deg"]
                   - t[f"closed_loop:{cn}"]["final_error_deg"]) < 1e-6


@pytest.mark.parametrize("name", ["mpc_cond_rti_step", "mpc_cond_step",
                                  "mpc_sw_rti_step", "mpc_sw_step",
                                  "mpc_robust_rti_step"])
def test_generated_condensed_step_equals_casadi_in_closed_loop(exported,
                                                                name):
    """80 steps of the slew: the warm-started C returns what Python does.

    (DAQP starts from the shifted active set; ``mpc_cond_step`` iterates
    to convergence with Anderson acceleration; the stage-wise steps run
    their Riccati interior point, `ocp.mpc.stagewise`.)
    """
    from ocp.codegen.patches import patch_daqp_warm_start

    f = exported.functions[name]
    ext = ca.external(name, str(exported.shared_library))
    source = exported.source.read_text()
    if daqp_available():
        assert patch_daqp_warm_start(source)[1] == 0   # already applied
        assert "a dependent warm start: start cold" in source
    x, qf, tau, z, lx, lg = (np.asarray(a, float)
                             for a in exported.samples[name])
    rk4 = exported.functions["rk4"]
    active = 0
    for _ in range(80):
        a = f(x, qf, tau, z, lx, lg)
        b = ext(x, qf, tau, z, lx, lg)
        # lam_x (2) is not unique where a momentum row of stage 1 and the
        # bound of u_0 it scales are both active
        for i, (ya, yb) in enumerate(zip(a, b)):
            if i != 2:
                np.testing.assert_allclose(np.asarray(yb), np.asarray(ya),
                                           atol=1e-10, rtol=0)
        z, lx = np.asarray(a[1]).ravel(), np.asarray(a[2]).ravel()
        active += np.count_nonzero(lx)
        assert float(a[6]) <= 1e-9          # applied step within bounds
        x = np.asarray(rk4(x, a[0], tau, 0.5)).ravel()
    assert active > 100                     # the warm starts were used


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


def test_cli_export_run_prints_cold_and_warm_times_and_checks(tmp_path,
                                                              capsys):
    from adcs.cli import main

    assert main(["export", "--out", str(tmp_path), "--mpc", "", "--run",
                 "--cc", "gcc"]) == 0
    out = capsys.readouterr().out
    assert "first call" in out and "median" in out and "worst" in out
    assert "(-Wall -Wextra): 0 warnings" in out
    assert "driver checks: every call returned 0" in out
    assert main(["export", "--out", str(tmp_path), "--mpc", "", "--build",
                 "--cc", "no-such-cc"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no-such-cc" in err[0]


def _daqp_external(tmp_path, name: str, src: str):
    """``src`` (a patched DAQP conic's C) built with the vendored DAQP
    sources into ``tmp_path``, loaded as `casadi.external` ``name``."""
    import subprocess

    from ocp.codegen.daqp_static import copy_daqp_sources

    (tmp_path / f"{name}.c").write_text(src)
    lib = tmp_path / f"{name}.so"
    subprocess.run(["gcc", "-O2", "-fPIC", "-shared",
                    str(tmp_path / f"{name}.c"),
                    *map(str, copy_daqp_sources(tmp_path)), "-o", str(lib),
                    "-lm"], check=True)
    return ca.external(name, str(lib))


@pytest.mark.skipif(not daqp_available(), reason="needs casadi's daqp")
def test_daqp_warm_start_patch_survives_a_dependent_working_set(tmp_path):
    """A row equal to a bound, both in the warm start: the right point.

    DAQP's setup may refuse that working set: the patched conic then
    starts cold (in its static workspace, the vendored DAQP).
    """
    from ocp.codegen.daqp_static import patch_daqp_static
    from ocp.codegen.patches import patch_daqp_failure, patch_daqp_warm_start

    H, A = ca.DM.eye(2), ca.DM([[1.0, 0.0]])
    qp = ca.conic("q", "daqp", {"h": H.sparsity(), "a": A.sparsity()},
                  {"error_on_fail": False})
    g, lx0, la0 = ca.MX.sym("g", 2), ca.MX.sym("lx0", 2), ca.MX.sym("la0")
    sol = qp(h=H, g=g, a=A, lba=-10, uba=1, lbx=-10, ubx=1, lam_x0=lx0,
             lam_a0=la0)
    f = ca.Function("warm_qp", [g, lx0, la0], [sol["x"]])
    cg = ca.CodeGenerator("warm_qp.c")
    cg.add(f)
    cg.generate(f"{tmp_path}/")
    src = (tmp_path / "warm_qp.c").read_text()
    src, n_fail = patch_daqp_failure(src)
    src, n_warm = patch_daqp_warm_start(src)
    src, conics = patch_daqp_static(src)
    assert n_fail == 1 and n_warm == 3 and len(conics) == 1
    ext = _daqp_external(tmp_path, "warm_qp", src)
    for warm in ([1.0, 0.0], [1.0, 1.0], [0.0, 0.0], [-1.0, 1.0]):
        for la in (1.0, 0.0, -1.0):
            x = np.asarray(ext([-2.0, -2.0], warm, la)).ravel()
            np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-12)
            np.testing.assert_allclose(
                x, np.asarray(f([-2.0, -2.0], warm, la)).ravel(),
                atol=1e-12)


@pytest.mark.skipif(not daqp_available(), reason="needs casadi's daqp")
def test_a_small_conic_keeps_its_setup_only_while_h_and_a_stay(tmp_path):
    """A conic of few nonzeros (`KEEP_MAX_NNZ`) keeps DAQP's setup from
    one call to the next; with H and A as inputs, every change of either
    (and back, and a NaN) gives the answer of CasADi's own DAQP."""
    from ocp.codegen.daqp_static import (KEEP_MAX_NNZ, daqp_static_sizes,
                                         patch_daqp_static)

    H, A = ca.DM(ca.Sparsity.diag(2), [2.0, 1.0]), ca.DM([[1.0, 1.0]])
    qp = ca.conic("q", "daqp", {"h": H.sparsity(), "a": A.sparsity()},
                  {"error_on_fail": False})
    h, a = ca.MX.sym("h", H.sparsity()), ca.MX.sym("a", A.sparsity())
    g = ca.MX.sym("g", 2)
    sol = qp(h=h, g=g, a=a, lba=-10, uba=1, lbx=-10, ubx=10)
    f = ca.Function("kept_qp", [h, a, g], [sol["x"]])
    cg = ca.CodeGenerator("kept_qp.c")
    cg.add(f)
    cg.generate(f"{tmp_path}/")
    src, conics = patch_daqp_static((tmp_path / "kept_qp.c").read_text())
    assert KEEP_MAX_NNZ >= 4 and "casadi_daqp_same_data(d)" in src
    (name, (nw, _)), = conics.items()
    assert nw == daqp_static_sizes(2, 1, True, own_m=True)[0] + 4
    ext = _daqp_external(tmp_path, "kept_qp", src)
    cases = [([2.0, 1.0], [1.0, 1.0]), ([2.0, 1.0], [1.0, 1.0]),
             ([4.0, 0.5], [1.0, 1.0]), ([4.0, 0.5], [1.0, 1.0]),
             ([4.0, 0.5], [1.0, -2.0]), ([2.0, 1.0], [1.0, 1.0])]
    for hd, ad in cases:
        for gv in ([-3.0, -3.0], [1.0, -1.0], [-1.0, 0.0]):
            args = (ca.DM(ca.Sparsity.diag(2), hd), ca.DM([ad]), gv)
            got = np.asarray(ext(*args)).ravel()
            want = np.asarray(f(*args)).ravel()
            np.testing.assert_allclose(got, want, atol=1e-12)
    nan = np.asarray(ext(ca.DM(ca.Sparsity.diag(2), [np.nan, 1.0]),
                         ca.DM([[1.0, 1.0]]), [1.0, 1.0])).ravel()
    assert np.isnan(nan).any()           # never a kept setup's point
    again = np.asarray(ext(ca.DM(ca.Sparsity.diag(2), [2.0, 1.0]),
                           ca.DM([[1.0, 1.0]]), [-3.0, -3.0])).ravel()
    np.testing.assert_allclose(
        again, np.asarray(f(ca.DM(ca.Sparsity.diag(2), [2.0, 1.0]),
                            ca.DM([[1.0, 1.0]]), [-3.0, -3.0])).ravel(),
        atol=1e-12)


def test_an_aarch64_export_names_its_emulator_and_a_missing_one_is_an_error(
        tmp_path):
    """Without building, an aarch64 export is the host's folder plus the
    emulator its driver runs under; a driver whose emulator is not on the
    machine is the toolbox's error, naming what to install."""
    from adcs_common.exceptions import AdcsError
    from ocp.codegen.export import ExportResult, run_driver

    res = export_c(tmp_path / "a", "demo", mpc_variants=(),
                   target="aarch64")
    assert res.extras["runner"] == ["qemu-aarch64"]
    assert res.executable is None and (res.out_dir / "main.c").is_file()
    fake = ExportResult(**{**res.__dict__, "executable": tmp_path / "x",
                           "extras": {**res.extras,
                                      "runner": ["no-such-emulator-xyz"]}})
    with pytest.raises(AdcsError, match="no-such-emulator-xyz not found.*"
                       "apt-get install"):
        run_driver(fake)
