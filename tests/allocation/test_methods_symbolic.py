"""The CasADi allocation methods equal the numpy ones (<= 1e-12)."""

import casadi as ca
import numpy as np
import pytest

from adcs_common.codegen import CompilerNotFound, find_compiler
from adcs_common.exceptions import InvalidValueError
from allocation import WheelArray, envelope
from allocation.methods import (
    METHODS,
    fixed_point,
    pseudo_inverse,
)
from allocation.methods.symbolic import (
    FIXED_POINT_STEPS,
    SYMBOLIC_METHODS,
    cascaded_inverse_function,
    daisy_chain_function,
    fixed_point_function,
    generate_methods_c,
    method_functions,
    pseudo_inverse_function,
    redistributed_pinv_function,
)

M_MAX = 0.2


def cone6(failed=()) -> WheelArray:
    """Six wheels on a 54.7356° cone, 60° apart."""
    b = np.arccos(1 / np.sqrt(3))
    az = 2 * np.pi * np.arange(6) / 6
    axes = np.vstack([np.sin(b) * np.cos(az), np.sin(b) * np.sin(az),
                      np.full(6, np.cos(b))])
    return WheelArray.from_axes(axes, h_max=4.0, m_max=M_MAX,
                                normalize=True, failed=list(failed))


ARRAYS = {
    "pyramid": WheelArray.pyramid(h_max=4.0, m_max=M_MAX),
    "pyramid, wheel 2 failed": WheelArray.pyramid(h_max=4.0, m_max=M_MAX,
                                                  failed=[1]),
    "3 + 1": WheelArray.orthogonal_plus_skew(h_max=4.0, m_max=M_MAX),
    "3 + 1, wheel 4 failed": WheelArray.orthogonal_plus_skew(
        h_max=4.0, m_max=M_MAX, failed=[3]),
    "six, orthogonal pairs": WheelArray.orthogonal_pairs(h_max=4.0,
                                                         m_max=M_MAX),
    "six, cone": cone6(),
    "six, cone, wheels 1 and 4 failed": cone6(failed=(0, 3)),
}


def cases(array, n=120, seed=3):
    """Demands (0.05 to 1.6 times the set's extent) and bounds.

    Every third case has the nominal bounds ±m_max, every third random
    tighter or one-sided bounds (momentum-limited wheels, some with
    lo = hi), the rest ±inf (no caller bounds).
    """
    rng = np.random.default_rng(seed)
    k = array.n_wheels
    u = rng.normal(size=(3, n))
    u /= np.linalg.norm(u, axis=0)
    r = envelope(array, "torque").radial_extent(u) * rng.uniform(0.05, 1.6,
                                                                 n)
    m_max = np.asarray(array.m_max, dtype=float)
    out = []
    for i, M in enumerate((u * r).T):
        if i % 3 == 0:
            lo, hi = -m_max, m_max.copy()
        elif i % 3 == 1:
            a = rng.uniform(-1.2, 0.3, k) * m_max
            b = np.maximum(a, -0.9 * m_max) + rng.uniform(0.0, 1.5,
                                                          k) * m_max
            same = rng.random(k) < 0.15                     # lo = hi
            a[same] = b[same] = np.clip(b[same], -0.9 * m_max[same],
                                        0.9 * m_max[same])
            lo, hi = a, b
        else:
            lo, hi = np.full(k, -np.inf), np.full(k, np.inf)
        out.append((M, lo, hi))
    return out


def numpy_method(name):
    if name == "fixed point":
        return lambda a, M, lo, hi: fixed_point(
            a, M, lo, hi, max_iter=FIXED_POINT_STEPS, tol=0.0)
    return METHODS[name]


def finite(b, m_max):
    return np.clip(b, -m_max, m_max)


@pytest.mark.parametrize("array_name", list(ARRAYS))
@pytest.mark.parametrize("name", list(SYMBOLIC_METHODS))
def test_casadi_equals_numpy(array_name, name):
    array = ARRAYS[array_name]
    f = SYMBOLIC_METHODS[name](array)
    ref = numpy_method(name)
    m_max = np.asarray(array.m_max, dtype=float)
    worst, saturated = 0.0, 0
    for M, lo, hi in cases(array):
        m_np = ref(array, M, finite(lo, m_max), finite(hi, m_max))
        m_ca = np.asarray(f(M, lo, hi)).ravel()
        worst = max(worst, float(np.max(np.abs(m_ca - m_np))))
        saturated += bool(np.any(np.isclose(np.abs(m_np), m_max)))
    assert worst <= 1e-12
    assert saturated >= 20          # the redistribution branches ran


def test_one_pass_is_the_clipped_pseudo_inverse():
    """Truncate redistribution to one pass: sat(A⁺M) by both rules.

    When no wheel starts fixed (lo < hi).
    """
    array = ARRAYS["pyramid"]
    one = [redistributed_pinv_function(array, passes=1),
           cascaded_inverse_function(array, passes=1)]
    full = redistributed_pinv_function(array)
    differ = 0
    for M, lo, hi in cases(array, 90):
        if np.any(finite(lo, M_MAX) >= finite(hi, M_MAX)):
            continue
        want = pseudo_inverse(array, M, finite(lo, M_MAX),
                              finite(hi, M_MAX))
        for f in one:
            np.testing.assert_allclose(np.asarray(f(M, lo, hi)).ravel(),
                                       want, rtol=0, atol=1e-15)
        differ += float(np.max(np.abs(np.asarray(full(M, lo, hi)).ravel()
                                      - want))) > 1e-6
    assert differ >= 10


@pytest.mark.parametrize("steps", [1, 7, 60])
def test_fixed_point_steps(steps):
    array = ARRAYS["six, cone"]
    f = fixed_point_function(array, iterations=steps, epsilon=1e-3)
    for M, lo, hi in cases(array, 30):
        lo, hi = finite(lo, M_MAX), finite(hi, M_MAX)
        want = fixed_point(array, M, lo, hi, epsilon=1e-3, max_iter=steps,
                           tol=0.0)
        np.testing.assert_allclose(np.asarray(f(M, lo, hi)).ravel(), want,
                                   rtol=0, atol=1e-12)


def test_daisy_chain_groups():
    array = ARRAYS["six, orthogonal pairs"]
    groups = [(1, 3, 5), (0, 2)]          # wheel 5 (index 4) in none
    f = daisy_chain_function(array, groups=groups)
    for M, lo, hi in cases(array, 30):
        lo, hi = finite(lo, M_MAX), finite(hi, M_MAX)
        want = METHODS["daisy chain"](array, M, lo, hi, groups=groups)
        got = np.asarray(f(M, lo, hi)).ravel()
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
        assert got[4] == np.clip(0.0, lo[4], hi[4])     # in no group


def test_pseudo_inverse_jacobian_inside():
    """AD through the graph: ∂m/∂M = A⁺ where no wheel saturates."""
    array = ARRAYS["3 + 1"]
    M = ca.MX.sym("M", 3)
    bound = M_MAX * np.ones(4)
    for f in (pseudo_inverse_function(array),
              redistributed_pinv_function(array)):
        jac = ca.Function("j", [M], [ca.jacobian(f(M, -bound, bound), M)])
        np.testing.assert_allclose(
            np.asarray(jac([0.02, -0.01, 0.03])),
            np.linalg.pinv(array.working_axes), atol=1e-14)


def test_bad_arguments():
    array = ARRAYS["pyramid"]
    with pytest.raises(InvalidValueError):
        fixed_point_function(array, iterations=0)
    with pytest.raises(InvalidValueError):
        redistributed_pinv_function(array, passes=0)
    with pytest.raises(InvalidValueError):
        daisy_chain_function(array, groups=[(0, 1), (1, 2)])
    with pytest.raises(InvalidValueError):
        pseudo_inverse_function("pyramid")
    with pytest.raises(InvalidValueError):
        fixed_point_function(array, epsilon=1.5)


def test_generated_c_equals_numpy(tmp_path):
    try:
        find_compiler()
    except CompilerNotFound:
        pytest.skip("no C compiler")
    array = ARRAYS["pyramid, wheel 2 failed"]
    fns = method_functions(array)
    lib = generate_methods_c(list(fns.values()), tmp_path, opt="-O1")
    for name, f in fns.items():
        ext = ca.external(f.name(), str(lib))
        for M, lo, hi in cases(array, 30):
            want = numpy_method(name)(array, M, finite(lo, M_MAX),
                                      finite(hi, M_MAX))
            np.testing.assert_allclose(np.asarray(ext(M, lo, hi)).ravel(),
                                       want, rtol=0, atol=1e-12)
