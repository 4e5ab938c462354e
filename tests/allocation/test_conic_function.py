"""The QP allocator as one casadi Function: equal to QPAllocator, and C."""

import shutil
import subprocess

import casadi as ca
import numpy as np
import pytest

from allocation import (
    QPAllocator,
    SolverNotFound,
    WheelArray,
    conic_allocator_function,
    min_norm_function,
)
from allocation.qp.conic_function import conic_c_flags, wheel_qp_method
from conftest import DELTA, GAMMA

RNG = np.random.default_rng(7)


def _array():
    return WheelArray.pyramid(DELTA, GAMMA, h_max=4.0, m_max=0.2)


@pytest.mark.parametrize("plugin", ["daqp", "qrqp"])
def test_conic_function_equals_qp_allocator(plugin):
    arr = _array()
    V = [1.0, 2.0, 0.5, 1.5]
    f = conic_allocator_function(arr, V, dt=0.5, plugin=plugin)
    qa = QPAllocator(arr, V, solver="daqp")
    saturated = 0
    for _ in range(40):
        M = RNG.normal(size=3) * 0.3
        h = RNG.uniform(-3.9, 3.9, 4)
        m, alpha, violation = (x.full().ravel() for x in f(M, h))
        ref = qa.allocate(M, wheel_momentum=h, dt=0.5)
        np.testing.assert_allclose(m, ref.torques, atol=1e-9)
        assert alpha[0] == pytest.approx(ref.alpha, abs=1e-12)
        assert violation[0] < 1e-12
        saturated += ref.status == "saturated"
    assert 5 < saturated < 35


def test_conic_function_without_momentum_has_one_input():
    f = conic_allocator_function(_array())
    assert f.name_in() == ["M"]
    assert f.name_out() == ["m", "alpha", "violation"]


def test_conic_function_unknown_plugin():
    with pytest.raises(SolverNotFound, match="casadi:nosuch"):
        conic_allocator_function(_array(), plugin="nosuch")


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_generated_c_matches_casadi(tmp_path):
    """Codegen round trip: generate, compile, load with external, compare."""
    arr = _array()
    funcs = [min_norm_function(arr), conic_allocator_function(arr, dt=0.5)]
    for f in funcs:
        src = tmp_path / f"{f.name()}.c"
        lib = tmp_path / f"{f.name()}.so"
        cg = ca.CodeGenerator(src.name, {"with_header": False})
        cg.add(f)
        cg.generate(str(tmp_path) + "/")
        subprocess.run(["gcc", "-O2", "-fPIC", "-shared", str(src), "-o",
                        str(lib), *conic_c_flags("daqp")], check=True,
                       capture_output=True)
        ext = ca.external(f.name(), str(lib))
        for _ in range(10):
            args = [RNG.normal(size=3) * 0.3]
            if f.n_in() == 2:
                args.append(RNG.uniform(-3.9, 3.9, 4))
            for a, b in zip(f(*args) if f.n_out() > 1 else [f(*args)],
                            ext(*args) if f.n_out() > 1 else [ext(*args)]):
                np.testing.assert_allclose(a.full(), b.full(), atol=1e-10)


@pytest.mark.parametrize("plugin", ["daqp", "qrqp"])
@pytest.mark.parametrize("n_wheels, failed", [(4, ()), (4, (2,)), (5, ()),
                                              (6, (0,))])
def test_fast_path_equals_conic_qp(plugin, n_wheels, failed):
    """Fast paths give the conic's optimum, saturated or not.

    Closed form with 3-4 working wheels, min-norm check with 5 or more;
    interior, saturated and momentum-bound demands.
    """
    axes = np.c_[_array().axes, np.eye(3)][:, :n_wheels]
    arr = WheelArray(axes, h_max=np.full(n_wheels, 4.0),
                     m_max=np.full(n_wheels, 0.2)).with_failed(*failed)
    V = np.linspace(0.5, 2.0, n_wheels)
    fast = conic_allocator_function(arr, V, dt=0.5, plugin=plugin)
    ref = conic_allocator_function(arr, V, dt=0.5, plugin=plugin,
                                   fast_path=False)
    expected = "closed form" if n_wheels - len(failed) <= 4 else \
        "min-norm check + conic"
    assert wheel_qp_method(arr) == expected
    assert wheel_qp_method(arr, fast_path=False) == "conic"
    kinds = {"interior": 0, "saturated": 0}
    for k in range(120):
        M = RNG.normal(size=3) * (0.02, 0.1, 0.4)[k % 3]
        h = RNG.uniform(-3.95, 3.95, n_wheels)
        a = [x.full().ravel() for x in fast(M, h)]
        b = [x.full().ravel() for x in ref(M, h)]
        np.testing.assert_allclose(a[0], b[0], atol=1e-10, rtol=0)
        assert a[1][0] == b[1][0]
        assert a[2][0] < 1e-12
        kinds["saturated" if a[1][0] < 1.0 else "interior"] += 1
    assert min(kinds.values()) > 20


def test_closed_form_bounds_are_the_numpy_laws_bit_for_bit():
    """The momentum bound clamped to ±m_max is `torque_bounds` exactly,
    wheels driven back past h_max and a failed wheel included."""
    from allocation.qp.conic_function import _torque_bounds
    from allocation.qp.problem import torque_bounds

    arr = _array().with_failed(1)
    h = ca.SX.sym("h", 4)
    lo, hi = _torque_bounds(arr, h, 0.5)
    f = ca.Function("b", [h], [ca.vertcat(*lo), ca.vertcat(*hi)])
    driven_back = 0
    for k in range(300):
        hk = RNG.uniform(-4.2, 4.2, 4)
        if k % 3 == 0:
            hk[k % 4] = (4.0 + 0.1 * 0.5 + 1e-3) * (-1) ** k
        ref_lo, ref_hi, over = torque_bounds(arr, hk, 0.5)
        got_lo, got_hi = (x.full().ravel() for x in f(hk))
        np.testing.assert_array_equal(got_lo, ref_lo)
        np.testing.assert_array_equal(got_hi, ref_hi)
        driven_back += int(over.sum())
    assert driven_back > 50


def test_facets_pair_up_and_the_violation_flags_only_nonfinite_input():
    from allocation.qp.conic_function import _facet_pairs
    from allocation.qp.problem import facet_normals

    pairs, singles = _facet_pairs(facet_normals(_array().axes))
    assert (len(pairs), singles) == (6, [])
    f = conic_allocator_function(_array(), dt=0.5)
    M, h = np.array([0.01, -0.02, 0.005]), np.array([1.0, -2.0, 0.5, 3.0])
    for i in range(7):
        for bad in (np.nan, np.inf, -np.inf):
            x = np.r_[M, h]
            x[i] = bad
            assert np.isnan(float(f.call([x[:3], x[3:]])[2]))
    # huge but finite input: a scaled sum, no overflow to a false NaN
    m, alpha, viol = f.call([np.array([1e308, -1e308, 1e308]),
                             np.array([1e308, -1e308, 1e308, -1e308])])
    assert 0.0 <= float(viol) < 1e-12
    assert float(alpha) < 1e-300 and np.abs(m.full()).max() <= 0.2
