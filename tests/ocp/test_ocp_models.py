"""Models of theory §3: quaternion and Euler–Krylov kinematics, wheels."""

import casadi as ca
import numpy as np
import pytest

from adcs_common import InvalidValueError, ShapeError
from allocation import WheelArray
from adcs_common.quaternion import (
    quat_from_axis_angle,
    quat_mul,
    quat_rate,
    quat_to_dcm,
    rotation_between,
)
from ocp.models.angles import (
    body_rates_from_angle_rates,
    ek_angle_rates,
    ek_angle_rates_function,
    ek_from_quat,
    quat_from_ek,
)
from ocp.models.rigid import (
    dynamics_numpy,
    euler_krylov_model,
    rigid_spacecraft,
)
from thrusters import six_thruster_unit

J_METEOR = np.array([[120.0, 2.0, -1.5], [2.0, 95.0, 3.0], [-1.5, 3.0, 80.0]])


@pytest.fixture
def model():
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    return rigid_spacecraft(J_METEOR, arr)


def _random_state(rng, n):
    q = rng.normal(size=4)
    return np.concatenate([q / np.linalg.norm(q), 0.05 * rng.normal(size=3),
                           2.0 * rng.normal(size=n)])


def test_dynamics_function_has_named_inputs_and_outputs(model):
    f = model.dynamics
    assert f.name_in() == ["x", "u", "tau"]
    assert f.name_out() == ["xdot"]
    assert (model.nx, model.nu, model.n_wheels) == (11, 4, 4)


def test_casadi_dynamics_equal_numpy_reference(model):
    rng = np.random.default_rng(0)
    for _ in range(20):
        x = _random_state(rng, 4)
        u = 0.1 * rng.normal(size=4)
        tau = 0.01 * rng.normal(size=3)
        got = np.asarray(model.dynamics(x, u, tau)).ravel()
        ref = dynamics_numpy(J_METEOR, x, u, tau, model.wheels.axes)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-15)


def test_torque_box_model_equals_numpy_reference():
    m = rigid_spacecraft(np.diag([1.0, 2.0, 3.0]), torque_max=1.0)
    x = np.array([0.5, 0.5, 0.5, 0.5, 0.1, -0.2, 0.3])
    u = np.array([0.3, -0.1, 0.2])
    got = np.asarray(m.dynamics(x, u, np.zeros(3))).ravel()
    np.testing.assert_allclose(got, dynamics_numpy(np.diag([1, 2, 3]), x, u),
                               atol=1e-15)


def test_momentum_conserved_without_external_torque_cvodes(model):
    """Spec 3: R(q)(Jω + A H_w) is constant when τ_ext = 0."""
    rng = np.random.default_rng(1)
    x0 = _random_state(rng, 4)
    t = np.linspace(0.0, 60.0, 31)
    u = 0.2 * np.sin(np.outer(t[:-1], [1.0, 0.7, 0.3, 0.11]))
    H = model.momentum_function()
    drift = []
    for tol in (1e-9, 1e-12):
        X = model.simulate(x0, t, u, options={"abstol": tol, "reltol": tol})
        H_all = np.array([np.asarray(H(x)).ravel() for x in X])
        drift.append(np.max(np.abs(H_all - H_all[0]))
                     / np.linalg.norm(H_all[0]))
    # the drift is the integrator's error: it falls with the tolerance
    assert drift[1] < 1e-9
    assert drift[1] < drift[0] / 100.0
    # wheel torques integrate to the wheel momenta exactly (Ḣ_w = m)
    np.testing.assert_allclose(X[-1, 7:] - X[0, 7:],
                               np.sum(u * np.diff(t)[:, None], axis=0),
                               atol=1e-8)


def test_quaternion_norm_preserved_by_cvodes(model):
    rng = np.random.default_rng(2)
    X = model.simulate(_random_state(rng, 4), np.linspace(0, 100, 11),
                       np.zeros((10, 4)))
    np.testing.assert_allclose(np.linalg.norm(X[:, :4], axis=1), 1.0,
                               atol=1e-9)


def test_rk4_step_matches_cvodes_to_fourth_order(model):
    rng = np.random.default_rng(3)
    x0 = _random_state(rng, 4)
    u = np.array([0.1, -0.05, 0.02, 0.0])
    tau = np.array([1e-3, 0.0, -2e-3])
    ref = np.asarray(model.integrator(5.0)(x0=x0, p=np.r_[u, tau])["xf"])
    errs = []
    for sub in (4, 8):
        xf = np.asarray(model.rk4_step(sub)(x0, u, tau, 5.0))
        errs.append(np.max(np.abs(xf - ref)))
    assert errs[1] < errs[0] / 12.0  # ~16 for a 4th-order method
    assert errs[1] < 1e-7


def test_external_torque_changes_inertial_momentum_by_its_impulse():
    m = rigid_spacecraft(np.diag([2.0, 3.0, 4.0]), torque_max=1.0)
    x0 = m.state([1, 0, 0, 0])
    t = np.linspace(0, 1.0, 11)
    tau = np.tile([0.0, 0.0, 0.5], (10, 1))
    X = m.simulate(x0, t, np.zeros((10, 3)), tau)
    # pure z-torque about a principal axis: ω_z = 0.5 t / 4
    np.testing.assert_allclose(X[-1, 6], 0.125, rtol=1e-9)
    np.testing.assert_allclose(np.asarray(m.momentum_function()(X[-1])).ravel(),
                               [0, 0, 0.5], atol=1e-9)


def test_failed_wheel_gives_no_torque():
    arr = WheelArray.pyramid(h_max=1.0, m_max=1.0, failed=(1,))
    m = rigid_spacecraft(np.eye(3), arr)
    xdot = np.asarray(m.dynamics(m.state([1, 0, 0, 0]),
                                 [0, 1.0, 0, 0], np.zeros(3))).ravel()
    np.testing.assert_allclose(xdot, 0.0, atol=1e-15)


def test_quaternion_kinematics_rotates_body_vectors_to_reference():
    # constant rate about body z for t: q(t) = axis-angle (z, ω t)
    q = quat_from_axis_angle([0, 0, 1], 0.3)
    R = quat_to_dcm(q)
    np.testing.assert_allclose(R @ [1, 0, 0], [np.cos(.3), np.sin(.3), 0],
                               atol=1e-15)
    qdot = quat_rate(q, np.array([0, 0, 2.0]))
    np.testing.assert_allclose(qdot, [-np.sin(.15), 0, 0, np.cos(.15)],
                               atol=1e-15)


def test_rotation_between_recovers_axis_and_angle():
    q0 = quat_from_axis_angle([1, 2, 3], 0.4)
    dq = quat_from_axis_angle([0.0, -1.0, 1.0], 2.5)
    axis, angle = rotation_between(q0, quat_mul(q0, dq))
    np.testing.assert_allclose(axis, np.array([0, -1, 1]) / np.sqrt(2),
                               atol=1e-12)
    assert angle == pytest.approx(2.5, abs=1e-12)


def test_four_wheel_eq1_body_rates_and_inverse():
    rng = np.random.default_rng(4)
    for _ in range(10):
        ang = rng.uniform(-1.2, 1.2, 3)
        rates = rng.normal(size=3)
        w = body_rates_from_angle_rates(ang, rates)
        np.testing.assert_allclose(ek_angle_rates(ang, w), rates, atol=1e-12)
        f = ek_angle_rates_function()
        np.testing.assert_allclose(np.asarray(f(ang, w)).ravel(), rates,
                                   atol=1e-12)


def test_four_wheel_eq1_matches_derivative_of_dcm():
    """Ċ = -[ω×] C for C = R1(γ)R2(ψ)R3(ϑ): eq. (1) is its kinematics."""
    rng = np.random.default_rng(5)
    ang = rng.uniform(-1.0, 1.0, 3)
    rates = rng.normal(size=3)
    eps = 1e-6
    from ocp.models.angles import dcm_body_from_ref_ek
    C = dcm_body_from_ref_ek(ang)
    Cdot = (dcm_body_from_ref_ek(ang + eps * rates)
            - dcm_body_from_ref_ek(ang - eps * rates)) / (2 * eps)
    W = -Cdot @ C.T
    w = np.array([W[2, 1], W[0, 2], W[1, 0]])
    np.testing.assert_allclose(w, body_rates_from_angle_rates(ang, rates),
                               atol=1e-8)


def test_euler_krylov_quaternion_round_trip_and_dcm():
    from ocp.models.angles import dcm_body_from_ref_ek
    ang = np.array([0.3, -0.7, 1.9])
    q = quat_from_ek(ang)
    np.testing.assert_allclose(quat_to_dcm(q).T, dcm_body_from_ref_ek(ang),
                               atol=1e-14)
    np.testing.assert_allclose(ek_from_quat(q), ang, atol=1e-12)


def test_euler_krylov_singularity_at_yaw_90_degrees():
    with pytest.raises(InvalidValueError, match="singularity"):
        ek_angle_rates([0.1, np.pi / 2, 0.0], [0.0, 0.0, 0.1])
    f = euler_krylov_model(np.eye(3))
    xdot = np.asarray(f([0.1, np.pi / 2, 0, 0, 0.0, 0.1], np.zeros(3),
                        np.zeros(3))).ravel()
    assert not np.all(np.isfinite(xdot[:3])) or np.max(np.abs(xdot[:3])) > 1e8


def test_euler_krylov_model_agrees_with_quaternion_model():
    arr = WheelArray.orthogonal_plus_skew(h_max=4.27, m_max=0.034)
    J = np.diag([86.215, 85.070, 113.565])
    fq = rigid_spacecraft(J, arr)
    fe = euler_krylov_model(J, arr)
    ang0 = np.array([0.1, 0.2, -0.3])
    w0 = np.array([0.01, -0.02, 0.015])
    h0 = np.array([0.5, -0.3, 0.2, 0.1])
    t = np.linspace(0, 50.0, 51)
    u = np.tile([0.01, -0.02, 0.005, 0.01], (50, 1))
    X = fq.simulate(np.r_[quat_from_ek(ang0), w0, h0], t, u)
    F = ca.integrator("ek", "cvodes", {
        "x": (xs := ca.MX.sym("x", 10)), "p": (p := ca.MX.sym("p", 4)),
        "ode": fe(xs, p, np.zeros(3))}, 0.0, t[1:],
        {"abstol": 1e-11, "reltol": 1e-11})
    Xe = np.asarray(F(x0=np.r_[ang0, w0, h0], p=u[0])["xf"]).T
    np.testing.assert_allclose(ek_from_quat(X[-1, :4]), Xe[-1, :3],
                               atol=1e-7)
    np.testing.assert_allclose(X[-1, 4:], Xe[-1, 3:], atol=1e-9)


def test_bad_inputs_raise_toolbox_errors_naming_the_argument():
    with pytest.raises(InvalidValueError, match="give an actuator"):
        rigid_spacecraft(np.eye(3))
    with pytest.raises(InvalidValueError, match="not both"):
        rigid_spacecraft(np.eye(3), WheelArray.pyramid(), torque_max=1.0)
    with pytest.raises(InvalidValueError, match="one of them"):
        rigid_spacecraft(np.eye(3), torque_max=1.0,
                         thrusters=six_thruster_unit())
    with pytest.raises(InvalidValueError, match="ThrusterSet"):
        rigid_spacecraft(np.eye(3), thrusters=np.eye(3))
    with pytest.raises(ShapeError, match="inertia"):
        rigid_spacecraft(np.eye(2), torque_max=1.0)
    with pytest.raises(InvalidValueError, match="positive definite"):
        rigid_spacecraft(-np.eye(3), torque_max=1.0)
    with pytest.raises(InvalidValueError, match="torque_max"):
        rigid_spacecraft(np.eye(3), torque_max=[1.0, 0.0, 1.0])
    m = rigid_spacecraft(np.eye(3), torque_max=1.0)
    with pytest.raises(ShapeError, match="u"):
        m.simulate(m.state([1, 0, 0, 0]), [0, 1], np.zeros((1, 4)))
    with pytest.raises(InvalidValueError, match="method"):
        m.integrator(1.0, method="euler")


def test_idas_and_cvodes_agree_on_a_torque_free_tumble():
    m = rigid_spacecraft(np.diag([1.0, 2.0, 3.0]), torque_max=1.0)
    x0 = m.state([1, 0, 0, 0], [0.1, 0.2, 0.3])
    t = np.linspace(0.0, 20.0, 5)
    a = m.simulate(x0, t, np.zeros((4, 3)), method="idas")
    b = m.simulate(x0, t, np.zeros((4, 3)), method="cvodes")
    np.testing.assert_allclose(a, b, atol=1e-8)
    # torque-free: kinetic energy ½ ωᵀJω is conserved too
    e = 0.5 * np.einsum("ki,ij,kj->k", a[:, 4:], m.inertia, a[:, 4:])
    np.testing.assert_allclose(e, e[0], rtol=1e-8)


# thrusters as the external torque ([4]'s spacecraft) ---------------
J54 = np.diag([3.0, 2.5, 3.5])          # [4]'s 54 kg spacecraft


def test_wheels_plus_thrusters_equal_the_numpy_reference():
    unit = six_thruster_unit()
    arr = WheelArray.pyramid(m_max=0.01, h_max=0.012)
    m = rigid_spacecraft(J54, arr, thrusters=unit)
    assert (m.nx, m.nu, m.n_wheels, m.n_thrusters) == (11, 10, 4, 6)
    rng = np.random.default_rng(5)
    for _ in range(5):
        x = m.state(rng.normal(size=4), rng.normal(size=3) * 0.1,
                    rng.normal(size=4) * 0.01)
        u = np.r_[rng.uniform(-0.01, 0.01, 4), rng.uniform(0, 1, 6)]
        tau = rng.normal(size=3) * 1e-3
        ref = dynamics_numpy(J54, x, u, tau, axes=arr.axes,
                             thruster_torque=unit.torque_matrix())
        got = np.array(m.dynamics(x, u, tau)).ravel()
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-15)


def test_thrusters_change_total_momentum_by_their_mean_torque():
    """dH_ref/dt = R(q) T k: the thrusters are the only external torque."""
    unit = six_thruster_unit()
    arr = WheelArray.pyramid(m_max=0.01, h_max=0.012)
    m = rigid_spacecraft(J54, arr, thrusters=unit)
    x = m.state([0.9, 0.1, -0.3, 0.2], [0.01, -0.02, 0.03],
                [0.002, -0.001, 0.0, 0.004])
    k = np.array([0.3, 0.0, 0.7, 0.1, 0.0, 0.5])
    u = np.r_[[0.002, -0.004, 0.001, 0.0], k]
    xs = ca.SX.sym("x", m.nx)
    dH = ca.Function("dH", [xs], [ca.jacobian(m.momentum_function()(xs),
                                              xs)])
    rate = np.array(dH(x)) @ np.array(m.dynamics(x, u, 0)).ravel()
    R = quat_to_dcm(x[:4])
    np.testing.assert_allclose(rate, R @ unit.torque_matrix() @ k,
                               atol=1e-15)
    np.testing.assert_allclose(m.body_control_torque(u),
                               -arr.body_torque(u[:4])
                               + unit.torque_matrix() @ k, atol=1e-15)


def test_thruster_only_spacecraft_and_control_bounds():
    unit = six_thruster_unit()
    m = rigid_spacecraft(J54, thrusters=unit)
    assert (m.nx, m.nu, m.n_wheels) == (7, 6, 0)
    lb, ub = m.control_bounds()
    np.testing.assert_array_equal(lb, np.zeros(6))
    np.testing.assert_array_equal(ub, np.ones(6))
    x = m.state([1, 0, 0, 0])
    k = np.array([1.0, 0, 0, 0, 0, 0])    # D1 alone: its Table 1 torque
    wdot = np.array(m.dynamics(x, k, 0)).ravel()[4:7]
    np.testing.assert_allclose(J54 @ wdot, unit.torque_matrix()[:, 0],
                               atol=1e-15)
    arr = WheelArray.pyramid(m_max=0.01, h_max=0.012).with_failed(2)
    lb, ub = rigid_spacecraft(J54, arr, thrusters=unit).control_bounds()
    np.testing.assert_array_equal(ub, [0.01, 0.01, 0.0, 0.01] + [1.0] * 6)
    np.testing.assert_array_equal(lb, [-0.01, -0.01, 0.0, -0.01] + [0] * 6)
