"""Single-precision C export (`ocp.codegen.precision`, issue #28 item 4).

The float allocation laws and QPs are compiled for the host and called
through ctypes on a few hundred random demands against the double
Functions; the transform must leave no double literal or double math
call (grep, ``nm``) and compile clean under ``-Wall -Wextra -Werror
-Wdouble-promotion -Wfloat-conversion``.
"""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess

import casadi as ca
import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from allocation import conic_allocator_function, min_norm_function
from ocp.codegen.export import duty_qp_function, export_c
from ocp.codegen.precision import (
    FLOAT_MAX_LITERAL,
    FLOAT_MIN_LITERAL,
    TOLERANCES,
    c_real,
    double_math_symbols,
    patch_qrqp_failure,
    tolerances,
    to_single,
    wheel_qp_options,
)
from ocp.spacecraft import load_spacecraft

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None
                                or shutil.which("nm") is None,
                                reason="needs gcc and nm")

STRICT = ["-Wall", "-Wextra", "-Werror", "-Wdouble-promotion",
          "-Wfloat-conversion"]

#: Measured (demo craft, 300 random demands, inputs rounded to float for
#: both): min_norm 6.7e-7 of m_max (demands up to 3x the attainable
#: set), wheel_qp 3.8e-7 (closed form) and 4.5e-7 (qrqp) of m_max,
#: alpha 1.1e-7; duty_qp duties 6.1e-7, scaled violation 1.0e-5. The
#: bounds below leave a margin of 15 or more. DAQP's float build
#: (`test_daqp_wheel_qp_float_vs_double`, 200 demands): wheel_qp 2.4e-6
#: of m_max, alpha 9.9e-7 (its primal_tol is 1e-6): margin 4.
TOL_MIN_NORM = 1e-5       # relative to m_max
TOL_WHEEL_QP = 1e-5       # relative to m_max (alpha: absolute)
TOL_DUTY_QP = 1e-4        # duty in [0, 1]


class _CFunction:
    """A generated C function of a shared library called through ctypes."""

    def __init__(self, lib, f: ca.Function, real=np.float32):
        self.real = real
        self.ct = ctypes.c_float if real == np.float32 else ctypes.c_double
        self.f = getattr(lib, f.name())
        sz = [ctypes.c_longlong() for _ in range(4)]
        getattr(lib, f.name() + "_work")(*[ctypes.byref(s) for s in sz])
        self.sz = [s.value for s in sz]
        self.n_out = [f.nnz_out(i) for i in range(f.n_out())]
        self.iw = (ctypes.c_longlong * (self.sz[2] + 1))()
        self.w = (self.ct * (self.sz[3] + 1))()
        self.mem = getattr(lib, f.name() + "_checkout")()

    def __call__(self, *args):
        P = ctypes.POINTER(self.ct)
        ins = [np.ascontiguousarray(np.asarray(a, float).ravel(),
                                    dtype=self.real) for a in args]
        outs = [np.zeros(max(n, 1), dtype=self.real) for n in self.n_out]
        arg = (P * (self.sz[0] + len(ins)))(
            *[i.ctypes.data_as(P) for i in ins])
        res = (P * (self.sz[1] + len(outs)))(
            *[o.ctypes.data_as(P) for o in outs])
        flag = self.f(arg, res, self.iw, self.w, ctypes.c_int(self.mem))
        assert flag == 0
        return [o.astype(float) for o in outs]


def _renamed(f: ca.Function, name: str) -> ca.Function:
    a = f.mx_in()
    return ca.Function(name, a, f.call(a), f.name_in(), f.name_out())


@pytest.fixture(scope="module")
def craft():
    return load_spacecraft("demo")


@pytest.fixture(scope="module")
def single_lib(craft, tmp_path_factory):
    """min_norm, wheel_qp (closed form, qrqp) and duty_qp in float C."""
    w = craft.wheels
    fns = {
        "min_norm": min_norm_function(w),
        "wheel_cf": _renamed(conic_allocator_function(
            w, dt=0.5, plugin="qrqp", fast_path=True,
            **wheel_qp_options("single")), "wheel_cf"),
        "wheel_qrqp": _renamed(conic_allocator_function(
            w, dt=0.5, plugin="qrqp", fast_path=False,
            **wheel_qp_options("single")), "wheel_qrqp"),
        "duty_qp": duty_qp_function(craft.thrusters, 2.0, 0.012,
                                    plugin="qrqp", precision="single"),
    }
    out = tmp_path_factory.mktemp("single")
    cg = ca.CodeGenerator("single.c", {"casadi_real": "float"})
    for f in fns.values():
        cg.add(f)
    cg.generate(f"{out}/")
    src = out / "single.c"
    text, counts = to_single(patch_qrqp_failure(src.read_text())[0])
    src.write_text(text)
    obj = out / "single.o"
    run = subprocess.run(["gcc", "-O2", "-fPIC", "-c", *STRICT,
                          "-Wno-unused-parameter", str(src), "-o",
                          str(obj)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    so = out / "single.so"
    subprocess.run(["gcc", "-shared", str(obj), "-o", str(so), "-lm"],
                   check=True)
    lib = ctypes.CDLL(str(so))
    return {"fns": fns, "text": text, "counts": counts, "obj": obj,
            "c": {k: _CFunction(lib, f) for k, f in fns.items()}}


def test_transform_literals_and_math():
    src = ("#define casadi_real double\n"
           "/* keep 1.5 and sqrt( in comments */\n"
           "static const char* s = \"%.16e sqrt(\";\n"
           "casadi_real f(casadi_real x) {\n"
           "  casadi_real a1e5 = 2.5000000000000000e-01*x + 1.;\n"
           "  a1e5 += 1e300 - 1.0000000000000000e-300 + 3e-39 + .5;\n"
           "  return sqrt(a1e5) + fabs(x) + casadi_fabs(x) + fmin(x, 2.)"
           " + atan2(x, 1e-8);\n}\n")
    text, counts = to_single(src)
    assert "#define casadi_real float" in text
    assert "2.5000000000000000e-01f*x + 1.f;" in text
    assert FLOAT_MAX_LITERAL in text and FLOAT_MIN_LITERAL in text
    assert text.count(FLOAT_MIN_LITERAL) == 2 and " .5f;" in text
    assert "sqrtf(a1e5) + fabsf(x) + casadi_fabs(x) + fminf(x, 2.f)" in text
    assert "atan2f(x, 1e-8f)" in text
    assert "keep 1.5 and sqrt( in comments" in text
    assert '"%.16e sqrt("' in text
    assert counts == {"literals": 5, "clamped": 3, "math": 4, "double": 0}
    # CasADi's DAQP runtime declares casadi_real arrays as double
    text, counts = to_single("int s(const double** arg, double* w) {\n"
                             "  double lb = 1.;\n}\n")
    assert "const casadi_real** arg, casadi_real* w" in text
    assert "casadi_real lb = 1.f;" in text and counts["double"] == 3


def test_tolerance_table_and_options():
    assert set(TOLERANCES["single"]) == set(TOLERANCES["double"])
    for key, v in TOLERANCES["single"].items():
        assert v >= TOLERANCES["double"][key], key
        assert v >= 8 * 1.19e-7 or key == "regularization", key
    assert tolerances("double")["row_tol"] == 1e-10
    assert c_real("single") == "float" and c_real("double") == "double"
    with pytest.raises(InvalidValueError, match="precision"):
        tolerances("half")


def test_single_source_has_no_double(single_lib):
    text = single_lib["text"]
    assert "#define casadi_real float" in text
    code = re.sub(r'/\*.*?\*/|"(?:\\.|[^"\\\n])*"', " ", text, flags=re.S)
    # every floating literal of the code carries the f suffix
    bare = re.findall(r"(?<![\w.])(?:\d+\.\d*|\.\d+|\d+(?=[eE]))"
                      r"(?:[eE][+-]?\d+)?(?![\w.])", code)
    assert bare == []
    assert not re.search(r"(?<![\w.>])(sqrt|fabs|fmin|fmax|sin|cos|exp)"
                         r"\s*\(", code)
    assert double_math_symbols(single_lib["obj"]) == []
    assert single_lib["counts"]["literals"] > 100


def test_min_norm_and_wheel_qp_float_vs_double(single_lib, craft):
    w = craft.wheels
    m_max = float(np.max(w.m_max))
    rng = np.random.default_rng(28)
    c, fns = single_lib["c"], single_lib["fns"]
    err = {"min_norm": 0.0, "wheel_cf": 0.0, "wheel_qrqp": 0.0,
           "alpha": 0.0}
    for _ in range(300):
        # demands from inside to 3x beyond the attainable set
        M = rng.uniform(0.1, 3.0) * float(np.sum(w.m_max)) * \
            rng.normal(size=3) / 3
        h = np.asarray(w.h_max) * rng.uniform(-1, 1, w.n_wheels)
        M32 = M.astype(np.float32).astype(float)
        h32 = h.astype(np.float32).astype(float)
        ref = np.array(fns["min_norm"](M32)).ravel()
        err["min_norm"] = max(err["min_norm"], float(
            np.max(np.abs(c["min_norm"](M32)[0] - ref))) / m_max)
        for name in ("wheel_cf", "wheel_qrqp"):
            m, alpha, viol = fns[name](M32, h32)
            mc, ac, vc = c[name](M32, h32)
            err[name] = max(err[name], float(
                np.max(np.abs(mc - np.array(m).ravel()))) / m_max)
            err["alpha"] = max(err["alpha"], abs(float(ac[0]) - float(alpha)))
            assert vc[0] <= TOLERANCES["single"]["bound_tol"] * m_max
    print("float vs double / m_max:", {k: f"{v:.1e}" for k, v in err.items()})
    assert err["min_norm"] <= TOL_MIN_NORM, err
    assert err["wheel_cf"] <= TOL_WHEEL_QP, err
    assert err["wheel_qrqp"] <= TOL_WHEEL_QP, err
    assert err["alpha"] <= TOL_WHEEL_QP, err


def float_cycle(rng, i: int) -> np.ndarray:
    """A duty cycle's parameters (9,), a burn every third, float-exact."""
    burn = rng.uniform(0.0, 0.5) if i % 3 == 0 else 0.0
    theta = np.r_[burn, 0.01 * rng.normal(size=2),
                  0.008 * rng.uniform(-1, 1, 3), 1e-4 * rng.normal(size=3)]
    return theta.astype(np.float32).astype(float)


def test_duty_qp_float_vs_double(single_lib, craft):
    f_double = duty_qp_function(craft.thrusters, 2.0, 0.012, plugin="qrqp")
    c = single_lib["c"]["duty_qp"]
    rng = np.random.default_rng(4)
    worst, wv, statuses = 0.0, 0.0, []
    n = craft.thrusters.n
    for i in range(300):
        theta = float_cycle(rng, i)
        d, s, v, st = f_double(theta, np.ones(n))
        dc, sc, vc, stc = c(theta, np.ones(n))
        statuses.append(int(st))
        assert int(stc[0]) == int(st), (i, theta)
        if int(st) <= 1:
            worst = max(worst, float(np.max(np.abs(
                dc - np.array(d).ravel()))))
            wv = max(wv, float(vc[0]))
    print(f"duty_qp float vs double: duty {worst:.2e}, violation {wv:.2e}")
    assert wv <= TOLERANCES["single"]["duty_viol_tol"], wv
    assert worst <= TOL_DUTY_QP, worst
    assert statuses.count(0) > 50


def test_export_single_refuses_sqpmethod(tmp_path):
    for variant in ("mpc_step", "mpc_cond_step"):
        with pytest.raises(InvalidValueError, match="float"):
            export_c(tmp_path / "b", "demo", mpc_variants=(variant,),
                     precision="single")
    with pytest.raises(InvalidValueError, match="precision"):
        export_c(tmp_path / "c", "demo", mpc_variants=(),
                 precision="half")
    # the stage-wise RTI step in float: with rqp only (the interior
    # point's tolerance is not reachable in float)
    with pytest.raises(InvalidValueError, match="rqp"):
        export_c(tmp_path / "d", "demo", mpc_variants=("mpc_sw_rti_step",),
                 precision="single")


def test_export_single_builds_clean(tmp_path):
    """The export without MPC: float source, DAQP's float build (from
    its own types.h: no define passed here), driver, strict build, run."""
    res = export_c(tmp_path / "s", "demo", mpc_variants=(),
                   precision="single", repeats=3, wheel_qp_fast_path=False)
    assert res.extras["precision"] == "single"
    assert res.extras["wheel_qp_plugin"] == "daqp"
    assert res.extras["duty_qp_plugin"] == "daqp"
    assert res.extras["cflags"] == ["-DDAQP_SINGLE_PRECISION"]
    assert "-DDAQP_SINGLE_PRECISION" in res.makefile.read_text()
    assert "DAQP_SINGLE_PRECISION" in (
        res.out_dir / "CMakeLists.txt").read_text()
    assert "## Single precision" in res.readme.read_text()
    objs = []
    for src in [res.source, *res.extras["solver_sources"]]:
        objs.append(tmp_path / f"{src.stem}.o")
        run = subprocess.run(["gcc", "-O1", *STRICT, "-c", str(src), "-o",
                              str(objs[-1])], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr[-3000:]
        assert double_math_symbols(objs[-1]) == [], src
    run = subprocess.run(["gcc", "-O1", *STRICT, f"-I{res.out_dir}",
                          str(res.driver), *map(str, objs), "-o",
                          str(tmp_path / "drv"), "-lm"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    run = subprocess.run([str(tmp_path / "drv")], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0 and "flag=1" not in run.stdout
    assert "TIME duty_qp " in run.stdout


@pytest.fixture(scope="module")
def daqp_single(tmp_path_factory):
    """The float export with DAQP's float build: wheel_qp through DAQP
    (no fast path) and duty_qp, as a shared library."""
    out = tmp_path_factory.mktemp("daqp_single")
    res = export_c(out, "demo", mpc_variants=(), precision="single",
                   wheel_qp_fast_path=False, build=True, repeats=3)
    assert res.extras["wheel_qp_plugin"] == "daqp"
    assert res.extras["duty_qp_plugin"] == "daqp"
    assert res.extras["warnings"] == 0, res.extras["warning_text"]
    lib = ctypes.CDLL(str(res.shared_library))
    return {k: _CFunction(lib, res.functions[k])
            for k in ("wheel_qp", "duty_qp")}


def test_daqp_wheel_qp_float_vs_double(daqp_single, craft):
    """wheel_qp solved by DAQP's float build equals the double DAQP
    Function within TOL_WHEEL_QP of m_max."""
    w = craft.wheels
    m_max = float(np.max(w.m_max))
    f = conic_allocator_function(w, dt=0.5, plugin="daqp", fast_path=False)
    rng = np.random.default_rng(41)
    err = alpha = 0.0
    for _ in range(200):
        M = rng.uniform(0.1, 3.0) * float(np.sum(w.m_max)) * \
            rng.normal(size=3) / 3
        h = np.asarray(w.h_max) * rng.uniform(-1, 1, w.n_wheels)
        M, h = (v.astype(np.float32).astype(float) for v in (M, h))
        m, a, _ = f(M, h)
        mc, ac, vc = daqp_single["wheel_qp"](M, h)
        err = max(err, float(np.max(np.abs(mc - np.array(m).ravel()))))
        alpha = max(alpha, abs(float(ac[0]) - float(a)))
        assert vc[0] <= TOLERANCES["single"]["bound_tol"] * m_max
    print(f"DAQP wheel_qp float vs double: {err / m_max:.1e} of m_max, "
          f"alpha {alpha:.1e}")
    assert err / m_max <= TOL_WHEEL_QP and alpha <= TOL_WHEEL_QP


def test_single_export_duty_qp_vs_double_daqp(daqp_single, craft):
    """The float export's duty_qp (DAQP's float build with its proximal
    iterations, ``duty_daqp_eps_prox``) against the double export's
    (DAQP): same status, duties within TOL_DUTY_QP, scaled violation
    within duty_viol_tol. Without the proximal iterations every one of
    these cycles failed its certificate (status 4): DAQP's dual form
    cancels terms 1e4 times the point on this nearly-LP QP."""
    f = duty_qp_function(craft.thrusters, 2.0, 0.012, plugin="daqp")
    rng = np.random.default_rng(5)
    n = craft.thrusters.n
    worst, wv, statuses = 0.0, 0.0, []
    for i in range(1000):
        theta = float_cycle(rng, i)
        d, _, _, st = f(theta, np.ones(n))
        dc, _, vc, stc = daqp_single["duty_qp"](theta, np.ones(n))
        statuses.append(int(st))
        assert int(stc[0]) == int(st), (i, theta)
        if int(st) <= 1:
            worst = max(worst, float(np.max(np.abs(
                dc - np.array(d).ravel()))))
            wv = max(wv, float(vc[0]))
    print(f"DAQP duty_qp float vs double: duty {worst:.2e}, violation "
          f"{wv:.2e}, statuses {np.bincount(statuses)}")
    assert wv <= TOLERANCES["single"]["duty_viol_tol"], wv
    assert worst <= TOL_DUTY_QP, worst
    assert statuses.count(0) > 20 and statuses.count(1) > 20
