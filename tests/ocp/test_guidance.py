"""Closed-form slews of theory §4: eigenaxis bang–coast–bang, quaternion PD."""

import numpy as np
import pytest

from adcs_common import InvalidValueError
from allocation import WheelArray
from allocation.zonotope import radial_extent, zonotope_facets
from adcs_common.quaternion import quat_from_axis_angle
from ocp.guidance import eigenaxis_slew, quaternion_feedback_slew
from ocp.models.rigid import rigid_spacecraft

J_METEOR = np.diag([120.0, 95.0, 80.0])
Q0 = np.array([1.0, 0.0, 0.0, 0.0])


def test_eigenaxis_bang_bang_unit_box_is_2_sqrt_pi():
    """Bilimoria & Wie (1993): 180° about x, J = I, |u_i| <= 1: 2√π."""
    s = eigenaxis_slew(np.eye(3), Q0, [0, 1, 0, 0], torque_max=1.0)
    assert s.T == pytest.approx(2 * np.sqrt(np.pi), rel=1e-14)
    assert s.t_coast == 0.0


def test_eigenaxis_coast_time_formula():
    s = eigenaxis_slew(np.eye(3), Q0, quat_from_axis_angle([0, 0, 1], 2.0),
                       torque_max=0.5, rate_max=0.4)
    # t_a = 0.4 / 0.5, t_c = 2 / 0.4 - 0.4 / 0.5
    assert s.t_accel == pytest.approx(0.8)
    assert s.t_coast == pytest.approx(4.2)
    assert s.T == pytest.approx(5.8)


def test_eigenaxis_acceleration_is_zonotope_radial_extent(pyramid):
    """α = ρ_Zm(J e)/|J e|, Z_m = A diag(m_max) [-1, 1]^4."""
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    axis = np.array([0.3, -0.5, 0.8])
    qf = quat_from_axis_angle(axis, 1.2)
    s = eigenaxis_slew(J_METEOR, Q0, qf, wheels=arr)
    Je = J_METEOR @ s.axis
    normals, offsets = zonotope_facets(arr.axes * arr.m_max)
    rho = radial_extent(normals, offsets, Je)
    assert s.alpha == pytest.approx(rho / np.linalg.norm(Je), rel=1e-9)
    # torque pattern reaches the bound, momentum bound sets the coast
    assert np.max(np.abs(s.alpha * s.wheel_pattern)) == pytest.approx(0.2)
    assert np.max(np.abs(s.rate_max * s.wheel_pattern)) == pytest.approx(4.0)
    np.testing.assert_allclose(arr.axes @ s.wheel_pattern, -Je, atol=1e-9)


def test_eigenaxis_trajectory_is_a_solution_of_the_model():
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    qf = quat_from_axis_angle([1, 1, 0], np.deg2rad(90))
    s = eigenaxis_slew(J_METEOR, Q0, qf, wheels=arr)
    tr = s.trajectory(200)
    assert s.t_coast > 0  # the momentum bound is reached
    model = rigid_spacecraft(J_METEOR, arr)
    X = model.simulate(model.state(Q0), tr.t, tr.wheel_torque)
    np.testing.assert_allclose(X[:, :4], tr.q, atol=1e-6)
    np.testing.assert_allclose(X[:, 7:], tr.wheel_momentum, atol=1e-9)
    assert tr.final_error < 1e-12
    assert tr.peak_wheel_torque == pytest.approx(0.2)
    assert tr.peak_wheel_momentum == pytest.approx(4.0)
    assert tr.T == pytest.approx(45.7676, abs=1e-4)


def test_eigenaxis_off_principal_box_respects_bounds_with_gyroscopic_term():
    J = np.array([[3.0, 0.4, 0.0], [0.4, 2.0, 0.2], [0.0, 0.2, 1.5]])
    qf = quat_from_axis_angle([1, 2, -1], 2.5)
    s = eigenaxis_slew(J, Q0, qf, torque_max=[0.3, 0.2, 0.25])
    tr = s.trajectory(400)
    assert np.all(np.abs(tr.torque) <= np.array([0.3, 0.2, 0.25]) + 1e-12)
    assert np.max(np.abs(tr.torque) / [0.3, 0.2, 0.25]) > 0.99


def test_quaternion_feedback_reaches_target_with_saturated_wheels():
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    qf = quat_from_axis_angle([1, 1, 0], np.deg2rad(90))
    fb = quaternion_feedback_slew(J_METEOR, Q0, qf, wheels=arr,
                                  natural_frequency=0.05, t_final=400.0,
                                  dt=0.5)
    assert fb.success and fb.status == "settled"
    assert fb.final_error < 1e-4
    assert fb.peak_wheel_torque == pytest.approx(0.2)  # saturated
    assert fb.peak_wheel_momentum <= 4.0 + 1e-9
    eig = eigenaxis_slew(J_METEOR, Q0, qf, wheels=arr)
    assert fb.T > eig.T  # the linear PD settles later than bang-coast-bang
    # total momentum stays zero (no external torque)
    Hb = (J_METEOR @ fb.w.T + arr.axes @ fb.wheel_momentum.T)
    assert np.max(np.abs(Hb)) < 1e-8


def test_quaternion_feedback_torque_box_and_not_settled_status():
    qf = quat_from_axis_angle([0, 0, 1], 1.0)
    fb = quaternion_feedback_slew(np.eye(3), Q0, qf, torque_max=1.0,
                                  natural_frequency=1.0, t_final=20.0)
    assert fb.success and fb.T < 10.0
    assert np.max(np.abs(fb.torque)) <= 1.0 + 1e-12
    short = quaternion_feedback_slew(np.eye(3), Q0, qf, torque_max=1.0,
                                     natural_frequency=1.0, t_final=1.0)
    assert not short.success and short.status == "not_settled"
    assert np.isnan(short.T)


def test_bad_arguments_raise_naming_the_argument():
    with pytest.raises(InvalidValueError, match="exactly one"):
        eigenaxis_slew(np.eye(3), Q0, Q0)
    with pytest.raises(InvalidValueError, match="q0"):
        eigenaxis_slew(np.eye(3), np.zeros(4), Q0, torque_max=1.0)
    with pytest.raises(InvalidValueError, match="rate_max"):
        eigenaxis_slew(np.eye(3), Q0, Q0, torque_max=1.0, rate_max=-1.0)
    with pytest.raises(InvalidValueError, match="natural_frequency"):
        quaternion_feedback_slew(np.eye(3), Q0, Q0, torque_max=1.0,
                                 natural_frequency=0.0, t_final=1.0)


def test_eigenaxis_trajectory_plot_shows_wheels():
    import matplotlib

    matplotlib.use("Agg")
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    qf = quat_from_axis_angle([1, 1, 0], np.deg2rad(90))
    fig = eigenaxis_slew(J_METEOR, Q0, qf, wheels=arr).trajectory(50).plot()
    assert len(fig.axes[3].get_lines()) == 4  # one momentum line per wheel
    assert "eigenaxis" in fig.axes[0].get_title()


def test_eigenaxis_on_two_working_wheels_names_the_rank():
    from adcs_common.exceptions import RankError

    wheels = WheelArray.pyramid(h_max=1.0, m_max=0.1).with_failed(0, 2)
    with pytest.raises(RankError, match=r"rank 2 < 3 \(failed wheels "
                       r"\[1, 3\]\)"):
        eigenaxis_slew(np.diag([3.0, 2.5, 3.5]), Q0,
                       quat_from_axis_angle([1, 1, 1], np.pi / 2),
                       wheels=wheels)
