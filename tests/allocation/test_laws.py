"""Closed-form laws of [1]: eqs. (5), (7)-(9), failure laws, weights."""

import numpy as np
import pytest

from allocation import (
    EQ9_GAINS,
    PAPER_EQ9_GAINS_PRINTED,
    InfeasibleError,
    InvalidValueError,
    ShapeError,
    WheelArray,
    WheelMotor,
    min_norm_function,
    min_norm_gains,
    min_norm_law,
    pyramid_failure_gains,
    pyramid_min_norm_function,
    sign_matrix_function,
    sign_matrix_gains,
    weighted_function,
    weighted_gains,
)
from conftest import DELTA, GAMMA

RNG = np.random.default_rng(1)
DEMANDS = RNG.normal(size=(3, 50))


def test_eq5_min_norm_solves_Am_equals_M_with_least_norm(pyramid):
    G = min_norm_gains(pyramid)
    np.testing.assert_allclose(pyramid.axes @ G, np.eye(3), atol=1e-14)
    # any other solution m + n (n in the null space) is longer
    null = np.linalg.svd(pyramid.axes)[2][-1]
    m = G @ DEMANDS[:, 0]
    assert abs(m @ null) < 1e-14


def test_eq7_8_sign_matrix_form_equals_eq5(pyramid):
    np.testing.assert_allclose(sign_matrix_gains(DELTA, GAMMA),
                               min_norm_gains(pyramid), atol=1e-14)


def test_eq7_BBt_is_4I():
    from allocation.laws import SIGN_MATRIX
    np.testing.assert_array_equal(SIGN_MATRIX @ SIGN_MATRIX.T, 4 * np.eye(3))


def test_eq9_corrected_gains_match_the_law_to_four_decimals(pyramid):
    np.testing.assert_allclose(min_norm_gains(pyramid), EQ9_GAINS,
                               atol=5e-5)


def test_eq9_printed_m2_line_is_a_misprint(pyramid):
    G = min_norm_gains(pyramid)
    # the printed m2 row equals m1 ...
    np.testing.assert_array_equal(PAPER_EQ9_GAINS_PRINTED[1],
                                  PAPER_EQ9_GAINS_PRINTED[0])
    # ... and is not the law: it misses M_y's sign, off by 2 x 0.4316
    assert np.max(np.abs(PAPER_EQ9_GAINS_PRINTED[1] - G[1])) > 0.86
    # with the printed rows, A m != M: the printed law is not a solution
    M = np.array([0.0, 1.0, 0.0])
    assert np.linalg.norm(pyramid.axes @ PAPER_EQ9_GAINS_PRINTED @ M
                          - M) > 0.5
    assert np.linalg.norm(pyramid.axes @ EQ9_GAINS @ M - M) < 2e-4


@pytest.mark.parametrize("failed", [0, 1, 2, 3])
def test_paper_single_failure_law_equals_pinv_with_zeroed_column(
        pyramid, failed):
    paper = pyramid_failure_gains(failed, DELTA, GAMMA)
    general = min_norm_gains(pyramid.with_failed(failed))
    np.testing.assert_allclose(paper, general, atol=1e-13)
    np.testing.assert_array_equal(paper[failed], 0.0)


def test_failure_law_wheel_1_as_printed(pyramid):
    scale = np.array([np.sin(DELTA) * np.cos(GAMMA),
                      np.sin(DELTA) * np.sin(GAMMA), np.cos(DELTA)])
    M = np.array([0.3, -0.2, 0.1])
    Mh = M / scale
    m = min_norm_gains(pyramid.with_failed(0)) @ M
    np.testing.assert_allclose(
        m, [0, (-Mh[0] - Mh[2]) / 2, (-Mh[1] + Mh[2]) / 2,
            (-Mh[0] + Mh[1]) / 2], atol=1e-13)


def test_with_one_failure_every_exact_law_gives_the_same_torques(pyramid):
    arr = pyramid.with_failed(1)
    G = min_norm_gains(arr)
    Gw = weighted_gains(arr, [1.0, 7.0, 0.3, 2.0])
    np.testing.assert_allclose(G, Gw, atol=1e-12)


def test_general_failure_law_any_set(pyramid):
    arr = WheelArray.orthogonal_pairs().with_failed(0, 3, 4)
    G = min_norm_gains(arr)
    np.testing.assert_allclose(arr.working_axes @ G, np.eye(3), atol=1e-14)
    np.testing.assert_array_equal(G[[0, 3, 4]], 0.0)


def test_weighted_law_minimises_weighted_norm(pyramid):
    V = np.array([1.0, 4.0, 0.5, 2.0])
    G = weighted_gains(pyramid, V)
    M = DEMANDS[:, 1]
    m = G @ M
    np.testing.assert_allclose(pyramid.axes @ m, M, atol=1e-13)
    null = np.linalg.svd(pyramid.axes)[2][-1]
    # stationarity: gradient V*m is orthogonal to the null space
    assert abs((V * m) @ null) < 1e-12
    for t in (-0.1, 0.1):
        assert np.sum(V * (m + t * null) ** 2) > np.sum(V * m**2)


def test_weighted_law_with_equal_weights_is_eq5(pyramid):
    np.testing.assert_allclose(weighted_gains(pyramid, 3.0 * np.ones(4)),
                               min_norm_gains(pyramid), atol=1e-14)


def test_negative_weights_raise(pyramid):
    with pytest.raises(InvalidValueError, match="weights must be positive"):
        weighted_gains(pyramid, [1, -1, 1, 1])


def test_law_rejects_nan_and_bad_shape(pyramid):
    law = min_norm_law(pyramid)
    with pytest.raises(InvalidValueError, match="torque must be finite"):
        law.allocate([np.nan, 0, 0])
    with pytest.raises(ShapeError, match="torque must have shape"):
        law.allocate([1.0, 2.0])


def test_law_batch_equals_per_call(pyramid):
    law = min_norm_law(pyramid)
    batch = law.allocate(DEMANDS)
    for k in range(5):
        np.testing.assert_allclose(batch[:, k], law.allocate(DEMANDS[:, k]))


# ------------------------------------------------ numpy vs CasADi (1e-12)
def test_casadi_min_norm_equals_numpy(pyramid):
    f = min_norm_function(pyramid)
    np.testing.assert_allclose(f(DEMANDS).full(),
                               min_norm_gains(pyramid) @ DEMANDS,
                               rtol=0, atol=1e-12)


def test_casadi_min_norm_with_failure_equals_numpy(pyramid):
    arr = pyramid.with_failed(3)
    np.testing.assert_allclose(min_norm_function(arr)(DEMANDS).full(),
                               min_norm_gains(arr) @ DEMANDS, atol=1e-12)


def test_casadi_symbolic_pyramid_law_equals_numpy():
    f = pyramid_min_norm_function()
    dd = RNG.uniform(-0.01, 0.01, 4)
    dg = RNG.uniform(-0.01, 0.01, 4)
    arr = WheelArray.pyramid(DELTA, GAMMA, d_delta=dd, d_gamma=dg)
    for k in range(10):
        np.testing.assert_allclose(
            f(DEMANDS[:, k], DELTA + dd, GAMMA + dg).full().ravel(),
            min_norm_gains(arr) @ DEMANDS[:, k], atol=1e-12)


def test_casadi_sign_matrix_law_equals_numpy():
    f = sign_matrix_function()
    np.testing.assert_allclose(f(DEMANDS[:, 2], DELTA, GAMMA).full().ravel(),
                               sign_matrix_gains(DELTA, GAMMA)
                               @ DEMANDS[:, 2], atol=1e-12)


def test_casadi_weighted_law_equals_numpy(pyramid):
    V = np.array([1.0, 4.0, 0.5, 2.0])
    f = weighted_function(pyramid)
    np.testing.assert_allclose(f(DEMANDS[:, 3], V).full().ravel(),
                               weighted_gains(pyramid, V) @ DEMANDS[:, 3],
                               atol=1e-12)


# ------------------------------------------------------ electrical model
def test_current_weights_grow_with_speed():
    motor = WheelMotor()
    V = motor.current_weights([0.0, 100.0, 300.0, -300.0])
    assert V[0] < V[1] < V[2] and V[2] == pytest.approx(V[3])
    # V = 1/m_avail^2 with m_avail = k_t (U - k_e|w|)/R
    assert V[0] == pytest.approx((1.5 / (0.05 * 28.0)) ** 2)


def test_current_weights_past_no_load_speed_raise():
    motor = WheelMotor()
    with pytest.raises(InfeasibleError, match="no-load speed"):
        motor.current_weights([0.0, motor.no_load_speed + 1.0])


def test_electrical_power_regenerates_a_fraction():
    motor = WheelMotor(regen_efficiency=0.25)
    loss = motor.copper_coefficient() * 0.01
    assert motor.electrical_power(0.1, 100.0) == pytest.approx(loss + 10.0)
    assert motor.electrical_power(-0.1, 100.0) == pytest.approx(loss - 2.5)


def test_motor_rejects_bad_parameters():
    with pytest.raises(InvalidValueError, match="resistance"):
        WheelMotor(resistance=-1.0)
    with pytest.raises(InvalidValueError, match="regen_efficiency"):
        WheelMotor(regen_efficiency=1.5)


def test_allocate_min_norm_convenience(pyramid):
    from allocation import allocate_min_norm
    np.testing.assert_allclose(allocate_min_norm(pyramid, DEMANDS),
                               min_norm_gains(pyramid) @ DEMANDS)
    with pytest.raises(ShapeError):
        allocate_min_norm(pyramid, [1.0, 2.0])
