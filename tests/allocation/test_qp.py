"""Bounded QP allocation: every backend against the closed forms."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allocation import (
    InvalidValueError,
    RankError,
    ShapeError,
    SolverNotFound,
    WheelArray,
    WheelMotor,
    min_norm_gains,
    weighted_gains,
)
from allocation.qp import QPAllocator, available_solvers
from allocation.zonotope import radial_extent, zonotope_facets
from conftest import DELTA, GAMMA

BACKENDS = [s for s in available_solvers() if not s.startswith("qpsolvers:")]
#: per-backend agreement with the exact reference on bounded cases
TOL = {"default": 1e-6}
WORST = np.array([-0.577, 0.563, 0.592]) / np.linalg.norm(
    [-0.577, 0.563, 0.592])


def small_pyramid(**kw) -> WheelArray:
    return WheelArray.pyramid(DELTA, GAMMA, h_max=4.0, m_max=0.2, **kw)


@pytest.mark.parametrize("solver", BACKENDS)
def test_qp_equals_eq5_when_no_bound_is_active(solver):
    arr = small_pyramid()
    qa = QPAllocator(arr, solver=solver)
    M = np.array([0.05, 0.02, -0.03])
    res = qa.allocate(M)
    assert res.status == "optimal" and res.alpha == 1.0
    np.testing.assert_allclose(res.torques, min_norm_gains(arr) @ M,
                               atol=1e-8)
    np.testing.assert_allclose(res.achieved, M, atol=1e-9)


@pytest.mark.parametrize("solver", BACKENDS)
def test_weighted_qp_equals_weighted_law_when_no_bound_is_active(solver):
    arr = small_pyramid()
    V = np.array([1.0, 4.0, 0.5, 2.0])
    res = QPAllocator(arr, weights=V, solver=solver).allocate(
        [0.02, -0.04, 0.01])
    np.testing.assert_allclose(
        res.torques, weighted_gains(arr, V) @ [0.02, -0.04, 0.01], atol=1e-8)


def _bounded_case(solver):
    arr = small_pyramid()
    qa = QPAllocator(arr, weights=[1.0, 3.0, 1.0, 0.5], solver=solver)
    # a demand the minimum-norm law cannot meet but the QP can
    M = 0.95 * radial_extent(*zonotope_facets(arr.axes * 0.2), WORST) * WORST
    return arr, qa.allocate(M), M


def test_bounded_case_is_beyond_the_minimum_norm_law():
    arr, res, M = _bounded_case("daqp")
    assert np.max(np.abs(min_norm_gains(arr) @ M)) > 0.2
    assert res.status == "optimal"
    assert np.isclose(np.max(np.abs(res.torques)), 0.2)


@pytest.mark.parametrize("solver", BACKENDS)
def test_backends_agree_on_a_bounded_case(solver):
    _, ref, M = _bounded_case("quadprog")
    _, res, _ = _bounded_case(solver)
    np.testing.assert_allclose(res.torques, ref.torques, atol=TOL["default"])
    np.testing.assert_allclose(res.achieved, M, atol=1e-9)


@pytest.mark.parametrize("solver", BACKENDS)
def test_saturated_demand_keeps_its_direction(solver):
    """Theory §1.2: in the worst direction the QP reaches 1.973 m_max."""
    arr = WheelArray.pyramid(DELTA, GAMMA, h_max=1.0, m_max=1.0)
    res = QPAllocator(arr, solver=solver).allocate(3.0 * WORST)
    assert res.status == "saturated" and res.mode == "scale"
    reach = np.linalg.norm(res.achieved)
    assert reach == pytest.approx(1.9725, abs=1e-4)
    assert res.alpha == pytest.approx(reach / 3.0, rel=1e-8)
    np.testing.assert_allclose(np.cross(res.achieved, WORST), 0, atol=1e-8)
    assert np.all(np.abs(res.torques) <= 1.0)
    np.testing.assert_allclose(res.shortfall, 3.0 * WORST - res.achieved)


def test_min_norm_law_reaches_only_1_334_in_the_worst_direction():
    arr = WheelArray.pyramid(DELTA, GAMMA, m_max=1.0)
    G = min_norm_gains(arr)
    assert 1.0 / np.max(np.abs(G @ WORST)) == pytest.approx(1.334, abs=1e-3)


@pytest.mark.parametrize("solver", ["osqp", "daqp", "casadi:daqp"])
def test_least_squares_fallback_is_the_closest_attainable_torque(solver):
    arr = small_pyramid()
    M = np.array([0.6, -0.1, 0.05])
    res = QPAllocator(arr, solver=solver,
                      saturation="least_squares").allocate(M)
    assert res.status == "saturated" and res.mode == "least_squares"
    # no vertex of the attainable set is closer to M
    signs = np.array(np.meshgrid(*[[-1, 1]] * 4)).reshape(4, -1)
    vertices = arr.axes @ (0.2 * signs)
    dist = np.linalg.norm(M - res.achieved)
    assert dist <= np.min(np.linalg.norm(vertices - M[:, None], axis=0))
    scaled = QPAllocator(arr, solver=solver).allocate(M)
    assert dist < np.linalg.norm(M - scaled.achieved)


@pytest.mark.parametrize("solver", ["osqp", "daqp", "casadi:qrqp"])
def test_momentum_bound_after_the_step(solver):
    arr = small_pyramid()
    h = np.array([3.95, 0.0, -1.0, -3.95])
    res = QPAllocator(arr, solver=solver).allocate(
        [0.1, 0.1, 0.1], wheel_momentum=h, dt=1.0)
    assert np.all(np.abs(res.momentum_after) <= 4.0 + 1e-12)
    assert res.torques[0] <= 0.05 + 1e-12 and res.torques[3] >= -0.05 - 1e-12
    np.testing.assert_allclose(res.achieved, [0.1, 0.1, 0.1], atol=1e-9)


def test_wheel_beyond_its_momentum_limit_is_driven_back():
    arr = small_pyramid()
    alloc = QPAllocator(arr, solver="daqp", saturation="least_squares")
    res = alloc.allocate([0.0, 0.0, 0.0], wheel_momentum=[5.0, 0, 0, 0],
                         dt=1.0)
    assert res.torques[0] == -0.2
    # the other three wheels cancel its torque: the zero demand is still met
    assert res.status == "optimal"
    np.testing.assert_allclose(res.achieved, 0.0, atol=1e-9)
    assert res.momentum_after[0] == pytest.approx(4.8)


@pytest.mark.parametrize("solver", ["osqp", "daqp"])
def test_failed_wheels_are_exactly_zero(solver):
    arr = small_pyramid(failed=[2])
    for M in ([0.1, 0.0, 0.0], [0.3, 0.3, -0.3]):
        res = QPAllocator(arr, solver=solver).allocate(M)
        assert res.torques[2] == 0.0


def test_with_one_failure_qp_equals_the_failure_law():
    arr = small_pyramid(failed=[0])
    M = np.array([0.03, -0.02, 0.01])
    res = QPAllocator(arr, weights=[5, 1, 2, 3], solver="daqp").allocate(M)
    np.testing.assert_allclose(res.torques, min_norm_gains(arr) @ M,
                               atol=1e-12)


def test_null_space_term_drives_momentum_without_changing_torque():
    arr = small_pyramid()
    h = np.array([1.0, -0.5, 0.3, 2.0])
    plain = QPAllocator(arr, solver="daqp").allocate(
        [0.01, 0, 0], wheel_momentum=h, dt=1.0)
    managed = QPAllocator(arr, solver="daqp", momentum_target=np.zeros(4),
                          momentum_gain=0.05).allocate(
        [0.01, 0, 0], wheel_momentum=h, dt=1.0)
    np.testing.assert_allclose(managed.achieved, plain.achieved, atol=1e-12)
    assert np.linalg.norm(managed.momentum_after) < np.linalg.norm(
        plain.momentum_after)


def test_power_optimal_cost_matches_a_null_space_search():
    arr = small_pyramid()
    motor = WheelMotor(regen_efficiency=0.3)
    h = np.array([2.0, -2.5, 1.0, 0.5]) * motor.rotor_inertia * 100
    M = np.array([0.05, 0.03, -0.02])
    res = QPAllocator(arr, solver="daqp", motor=motor).allocate(
        M, wheel_momentum=h)
    speed = motor.speed(h)
    m0 = min_norm_gains(arr) @ M
    null = np.linalg.svd(arr.axes)[2][-1]
    ts = np.linspace(-0.2, 0.2, 400001)
    cand = m0[:, None] + null[:, None] * ts
    ok = np.all(np.abs(cand) <= 0.2, axis=0)
    power = np.sum(motor.electrical_power(cand, speed[:, None]), axis=0)
    best = np.min(power[ok])
    got = np.sum(motor.electrical_power(res.torques, speed))
    assert got <= best + 1e-9
    assert got < np.sum(motor.electrical_power(m0, speed)) - 1e-3


def test_unknown_solver_lists_installed_and_extra():
    with pytest.raises(SolverNotFound) as err:
        QPAllocator(small_pyramid(), solver="gurobi9")
    assert "daqp" in str(err.value) and "adcs-toolbox[solvers]" in str(
        err.value)
    assert "osqp" in err.value.available


@pytest.mark.parametrize("bad, exc, match", [
    ([np.nan, 0, 0], InvalidValueError, "torque must be finite"),
    ([np.inf, 0, 0], InvalidValueError, "torque must be finite"),
    ([1.0, 0.0], ShapeError, "torque must have shape"),
])
def test_bad_demand_raises(bad, exc, match):
    with pytest.raises(exc, match=match):
        QPAllocator(small_pyramid(), solver="daqp").allocate(bad)


def test_bad_options_raise():
    arr = small_pyramid()
    with pytest.raises(InvalidValueError, match="weights must be positive"):
        QPAllocator(arr, weights=[1, 1, -1, 1])
    with pytest.raises(ShapeError, match="weights"):
        QPAllocator(arr, weights=[1, 1])
    with pytest.raises(InvalidValueError, match="saturation"):
        QPAllocator(arr, saturation="clip")
    with pytest.raises(TypeError):
        QPAllocator(arr, tolerance=1e-3)  # unknown keyword
    qa = QPAllocator(arr, solver="daqp")
    with pytest.raises(InvalidValueError, match="needs wheel_momentum"):
        qa.allocate([0.1, 0, 0], dt=1.0)
    with pytest.raises(InvalidValueError, match="dt must be positive"):
        qa.allocate([0.1, 0, 0], wheel_momentum=np.zeros(4), dt=-1.0)
    with pytest.raises(ShapeError, match="wheel_momentum"):
        qa.allocate([0.1, 0, 0], wheel_momentum=np.zeros(3), dt=1.0)


def test_rank_deficient_array_raises():
    with pytest.raises(RankError, match="rank 2"):
        QPAllocator(small_pyramid(failed=[0, 1]))


# ------------------------------------------------------ property tests
ANGLES = st.floats(0.2, 1.4)


@settings(max_examples=60, deadline=None)
@given(delta=ANGLES, gamma=st.floats(0.2, 1.37),
       mx=st.lists(st.floats(0.05, 0.5), min_size=4, max_size=4),
       demand=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       failed=st.sampled_from([(), (0,), (1,), (2,), (3,)]),
       h=st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4))
def test_property_bounds_kept_and_attainable_demands_met(
        delta, gamma, mx, demand, failed, h):
    arr = WheelArray.pyramid(delta, gamma, h_max=1.0, m_max=mx,
                             failed=failed)
    qa = QPAllocator(arr, solver="daqp")
    h = np.array(h) * 0.99
    res = qa.allocate(demand, wheel_momentum=h, dt=0.5)
    m = res.torques
    assert np.all(np.abs(m) <= arr.m_max)
    assert np.all(np.abs(h + m * 0.5) <= 1.0 + 1e-12)
    for i in failed:
        assert m[i] == 0.0
    if res.status == "optimal":
        np.testing.assert_allclose(arr.working_axes @ m, demand, atol=1e-9)
    else:
        # saturated: the direction is kept (to the allocator's checks,
        # 1e-6 relative, after clipping into the bounds)
        np.testing.assert_allclose(res.achieved, res.alpha *
                                   np.asarray(demand), atol=1e-7)
        assert res.alpha < 1.0


@settings(max_examples=40, deadline=None)
@given(n=st.integers(4, 7), seed=st.integers(0, 10_000),
       scale=st.floats(0.01, 3.0), n_failed=st.integers(0, 2),
       solver=st.sampled_from(["osqp", "daqp", "casadi:daqp"]))
def test_property_random_arrays(n, seed, scale, n_failed, solver):
    rng = np.random.default_rng(seed)
    arr = WheelArray.from_axes(rng.normal(size=(3, n)), h_max=1.0,
                               m_max=rng.uniform(0.05, 0.3, n),
                               normalize=True,
                               failed=rng.choice(n, n_failed, replace=False))
    if arr.rank < 3:
        with pytest.raises(RankError):
            QPAllocator(arr, solver=solver)
        return
    M = rng.normal(size=3) * scale * 0.2
    h = rng.uniform(-0.9, 0.9, n)
    res = QPAllocator(arr, solver=solver).allocate(M, wheel_momentum=h,
                                                   dt=1.0)
    assert np.all(np.abs(res.torques) <= arr.m_max)
    assert np.all(np.abs(h + res.torques) <= 1.0 + 1e-12)
    assert np.all(res.torques[list(arr.failed)] == 0.0)
    if res.status == "optimal":
        np.testing.assert_allclose(res.achieved, M, atol=1e-8)
    else:
        np.testing.assert_allclose(res.achieved, res.alpha * M, atol=1e-7)
        # the scale reached is the attainable maximum: a little more is not
        # attainable by any allocation (checked with an LP)
        from scipy.optimize import linprog
        lo = np.maximum(-arr.m_max, -1.0 - h) * arr.active
        hi = np.minimum(arr.m_max, 1.0 - h) * arr.active
        lp = linprog(np.r_[np.zeros(n), -1.0],
                     A_eq=np.c_[arr.working_axes, -M], b_eq=np.zeros(3),
                     bounds=list(zip(lo, hi)) + [(0, 1)], method="highs")
        assert lp.status == 0
        assert res.alpha == pytest.approx(-lp.fun, abs=1e-6)


# fast path: one buffer call of conic_allocator_function, checked ---------
@pytest.mark.parametrize("arr", [
    small_pyramid(), small_pyramid().with_failed(2),
    WheelArray.orthogonal_pairs(h_max=1.0, m_max=0.1)],
    ids=["pyramid", "pyramid_failed", "six_wheels"])
def test_allocate_fast_equals_allocate_inside_and_saturated(arr):
    rng = np.random.default_rng(11)
    alloc = QPAllocator(arr, solver="daqp",
                        weights=rng.uniform(0.5, 2.0, arr.n_wheels))
    saturated = 0
    out = np.full(arr.n_wheels, np.nan)
    for _ in range(200):
        M = rng.normal(size=3) * 0.3
        h = rng.uniform(-0.99, 0.99, arr.n_wheels) * arr.h_max
        for args in ((M,), (M, h, 0.5)):
            ref = alloc.allocate(*args)
            got = alloc.allocate_fast(*args, out=out)
            assert got is out
            np.testing.assert_allclose(got, ref.torques, atol=1e-12)
            assert alloc.fast_alpha == pytest.approx(ref.alpha, abs=1e-12)
            saturated += ref.status == "saturated"
    assert saturated > 50
    assert alloc.fast_fallbacks == 0


def test_allocate_fast_falls_back_where_the_laws_differ_or_input_is_bad():
    arr = small_pyramid()
    alloc = QPAllocator(arr, solver="daqp")
    # one wheel beyond h_max: it must brake; allocate may then fall back
    # to least squares, so every such call goes through allocate
    rng = np.random.default_rng(1)
    least_squares = 0
    for _ in range(150):
        M = rng.normal(size=3) * 0.3
        h = rng.uniform(-1.0, 1.0, 4) * 4.0
        h[rng.integers(4)] = rng.choice([-1.0, 1.0]) * rng.uniform(4.2, 6.0)
        ref = alloc.allocate(M, h, 1.0)
        least_squares += ref.mode == "least_squares"
        np.testing.assert_allclose(alloc.allocate_fast(M, h, 1.0),
                                   ref.torques, atol=1e-12)
    assert least_squares > 5
    assert alloc.fast_fallbacks == 150
    # within the momentum bounds the Function answers every demand
    alloc.fast_fallbacks = 0
    for _ in range(150):
        M = rng.normal(size=3) * 0.3
        h = rng.uniform(-1.0, 1.0, 4) * 4.0
        np.testing.assert_allclose(alloc.allocate_fast(M, h, 1.0),
                                   alloc.allocate(M, h, 1.0).torques,
                                   atol=1e-12)
    assert alloc.fast_fallbacks == 0
    alloc.fast_fallbacks = 0
    with pytest.raises(InvalidValueError, match="torque"):
        alloc.allocate_fast([np.nan, 0.0, 0.0])
    with pytest.raises(ShapeError, match="torque"):
        alloc.allocate_fast([0.1, 0.0])
    with pytest.raises(InvalidValueError, match="dt"):
        alloc.allocate_fast([0.1, 0.0, 0.0], [0.0] * 4, -1.0)
    assert alloc.fast_fallbacks == 3
    # a null-space momentum term is not in the fast Function: allocate
    managed = QPAllocator(arr, solver="daqp", momentum_target=np.zeros(4))
    args = ([0.05, 0.02, -0.01], [1.0, -1.0, 0.5, 0.0], 0.5)
    np.testing.assert_array_equal(managed.allocate_fast(*args),
                                  managed.allocate(*args).torques)
    assert managed.fast_fallbacks == 1


def test_allocate_fast_keeps_a_bounded_number_of_step_lengths():
    alloc = QPAllocator(small_pyramid(), solver="daqp")
    M, h = [0.1, 0.2, -0.1], [1.0, -2.0, 0.5, 3.9]
    for dt in np.linspace(0.1, 1.0, 10):
        np.testing.assert_allclose(alloc.allocate_fast(M, h, dt),
                                   alloc.allocate(M, h, dt).torques,
                                   atol=1e-12)
    assert len(alloc.fast_step_lengths) <= 4
    assert alloc.fast_fallbacks == 0
