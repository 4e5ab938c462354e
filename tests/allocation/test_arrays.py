"""WheelArray: constructors of theory §1.1 / 1.4, failures, bad input."""

import casadi as ca
import numpy as np
import pytest

from allocation import (
    InvalidValueError,
    RankError,
    ShapeError,
    WheelArray,
    pyramid_axes_function,
)
from conftest import DELTA, GAMMA


def test_pyramid_columns_follow_spec_1_1(pyramid):
    sd, cd, sg, cg = np.sin(DELTA), np.cos(DELTA), np.sin(GAMMA), np.cos(GAMMA)
    expected = np.array([
        [-sd * cg, -sd * cg, -sd * cg, -sd * cg],
        [sd * sg, -sd * sg, -sd * sg, sd * sg],
        [-cd, -cd, cd, cd],
    ])
    np.testing.assert_allclose(pyramid.axes, expected, atol=1e-15)


def test_orthogonal_plus_skew_paper_axis_is_the_four_wheel_papers():
    arr = WheelArray.orthogonal_plus_skew()
    np.testing.assert_allclose(arr.axes[:, 3], [0.5, 0.5, -np.sqrt(0.5)],
                               atol=1e-15)
    np.testing.assert_allclose(arr.axes[:, :3], np.eye(3))


def test_orthogonal_plus_skew_equal_angle():
    arr = WheelArray.orthogonal_plus_skew(skew="equal_angle")
    np.testing.assert_allclose(arr.axes[:, 3], np.ones(3) / np.sqrt(3))


def test_orthogonal_pairs_has_two_wheels_per_axis():
    arr = WheelArray.orthogonal_pairs()
    assert arr.n_wheels == 6
    np.testing.assert_allclose(arr.axes @ np.ones(6), [2, 2, 2])
    assert arr.with_failed(0, 1).rank == 2


def test_with_failed_returns_new_array_and_zeroes_column(pyramid):
    failed = pyramid.with_failed(2)
    assert pyramid.failed == () and failed.failed == (2,)
    np.testing.assert_array_equal(failed.working_axes[:, 2], 0.0)
    assert failed.rank == 3
    assert failed.with_failed(0).failed == (0, 2)


def test_two_failures_of_the_pyramid_lose_rank(pyramid):
    with pytest.raises(RankError, match="rank 2"):
        pyramid.with_failed(0, 1).require_full_rank()


def test_pyramid_mounting_errors_use_per_wheel_angles():
    dd = np.array([0.01, -0.02, 0.0, 0.005])
    dg = np.array([0.0, 0.01, -0.01, 0.02])
    arr = WheelArray.pyramid(DELTA, GAMMA, d_delta=dd, d_gamma=dg)
    f = pyramid_axes_function(per_wheel=True)
    np.testing.assert_allclose(arr.axes, f(DELTA + dd, GAMMA + dg).full(),
                               atol=1e-15)


def test_generic_mounting_errors_tilt_by_the_given_angle(pyramid):
    tilt = np.array([0.01, 0.02, 0.03, 0.04])
    tilted = pyramid.with_mounting_errors(tilt, np.zeros(4))
    cosines = np.sum(tilted.axes * pyramid.axes, axis=0)
    np.testing.assert_allclose(np.arccos(cosines), tilt, atol=1e-12)


def test_scale_errors_change_the_actual_torque(pyramid):
    arr = pyramid.with_scale_errors([0.02, 0.0, -0.01, 0.0])
    m = np.array([1.0, 0.0, 1.0, 0.0])
    np.testing.assert_allclose(
        arr.body_torque(m), pyramid.axes @ (m * [1.02, 1, 0.99, 1]))


def test_symbolic_axes_jacobian_matches_finite_difference():
    f = pyramid_axes_function(per_wheel=False)
    d = ca.SX.sym("d")
    g = ca.SX.sym("g")
    jac = ca.Function("j", [d, g], [ca.jacobian(ca.vec(f(d, g)), d)])
    eps = 1e-7
    fd = (f(DELTA + eps, GAMMA).full() - f(DELTA - eps, GAMMA).full()) / (
        2 * eps)
    np.testing.assert_allclose(jac(DELTA, GAMMA).full().ravel(),
                               fd.ravel(order="F"), atol=1e-8)


def test_zero_length_axis_is_rejected():
    with pytest.raises(InvalidValueError, match="wheel\\(s\\) \\[2\\]"):
        WheelArray.from_axes([[1, 0, 0], [0, 0, 1], [0, 0, 0]],
                             normalize=True)


def test_non_unit_axis_is_rejected_unless_normalized():
    axes = [[2, 0, 0], [0, 1, 0], [0, 0, 1]]
    with pytest.raises(InvalidValueError, match="unit columns"):
        WheelArray.from_axes(axes)
    arr = WheelArray.from_axes(axes, normalize=True)
    np.testing.assert_allclose(arr.axes, np.eye(3))


def test_wrong_shapes_name_the_argument():
    with pytest.raises(ShapeError, match="axes must have shape"):
        WheelArray.from_axes(np.eye(4))
    with pytest.raises(ShapeError, match="h_max"):
        WheelArray.pyramid(h_max=[1.0, 2.0])


def test_nan_and_negative_limits_are_rejected():
    with pytest.raises(InvalidValueError, match="axes must be finite"):
        WheelArray.from_axes([[np.nan, 0, 0], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(InvalidValueError, match="m_max must be positive"):
        WheelArray.pyramid(m_max=-0.1)


def test_failed_index_out_of_range(pyramid):
    with pytest.raises(InvalidValueError, match="0-based"):
        pyramid.with_failed(4)


def test_arrays_are_immutable(pyramid):
    with pytest.raises(ValueError):
        pyramid.axes[0, 0] = 1.0


@pytest.mark.parametrize("call", [
    lambda: WheelArray.pyramid(55, 45),
    lambda: WheelArray.pyramid(np.deg2rad(55), 45),
    lambda: WheelArray.pyramid(d_delta=[0.0, 0.0, 30.0, 0.0]),
    lambda: WheelArray.orthogonal_plus_skew(phi2=45),
    lambda: WheelArray.pyramid().with_mounting_errors([0, 0, 0, 10],
                                                      [0, 0, 0, 0]),
], ids=["delta", "gamma", "d_delta", "phi2", "tilt"])
def test_degrees_for_radians_are_named_with_the_fix(call):
    with pytest.raises(InvalidValueError, match=r"np\.deg2rad"):
        call()


def test_quaternion_angle_in_degrees_is_refused():
    from adcs_common.quaternion import quat_from_axis_angle

    with pytest.raises(InvalidValueError, match=r"np\.deg2rad\(90\)"):
        quat_from_axis_angle([0, 0, 1], 90)
    q = quat_from_axis_angle([0, 0, 1], -2 * np.pi)
    np.testing.assert_allclose(q, [-1, 0, 0, 0], atol=1e-15)
