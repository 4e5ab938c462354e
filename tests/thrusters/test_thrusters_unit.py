"""[4]: the six-thruster unit, eqs. (1), (3)-(6), Table 1, transients."""

import casadi as ca
import numpy as np
import pytest

from thrusters import (
    KGF_PER_CM2,
    InvalidValueError,
    ShapeError,
    ThrusterSet,
    force_torque_function,
    six_thruster_unit,
    six_unit_function,
)

R, L, P = 0.25, 0.3, 0.5
S3 = np.sqrt(3.0) / 2.0


@pytest.fixture
def unit():
    return six_thruster_unit(R=R, L=L, thrust=P)


def test_table1_arms_group1_as_reconstructed(unit):
    M = unit.torque_matrix()
    # Table 1 (theory §2): Mx, Mz of D1..D3 for thrust P
    np.testing.assert_allclose(M[0, :3], [0.0, S3 * R * P, -S3 * R * P],
                               atol=1e-15)
    np.testing.assert_allclose(M[2, :3], [-R * P, 0.5 * R * P, 0.5 * R * P],
                               atol=1e-15)


def test_table1_group2_pairs_reverse_the_arms(unit):
    M = unit.torque_matrix()
    for i, j in [(0, 3), (1, 5), (2, 4)]:          # D1-D4, D2-D6, D3-D5
        np.testing.assert_allclose(M[:, j], -M[:, i], atol=1e-15)
    assert unit.pairs == ((0, 3), (1, 5), (2, 4))


def test_forces_along_y_make_no_y_torque_and_groups_oppose(unit):
    F, M = unit.force_matrix(), unit.torque_matrix()
    np.testing.assert_allclose(M[1], 0.0, atol=1e-15)
    np.testing.assert_allclose(F[1], [P] * 3 + [-P] * 3)
    np.testing.assert_allclose(F[[0, 2]], 0.0)
    # all of one group firing equally: pure force, no torque (nominal)
    np.testing.assert_allclose(M @ [1, 1, 1, 0, 0, 0], 0.0, atol=1e-15)


def test_geometry_circle_and_planes(unit):
    pos = unit.positions
    np.testing.assert_allclose(np.hypot(pos[0], pos[2]), R)
    np.testing.assert_allclose(pos[1], [-L] * 3 + [L] * 3)
    theta = np.rad2deg(np.arctan2(pos[2, :3], pos[0, :3])) % 360
    np.testing.assert_allclose(theta, [180.0, 300.0, 60.0])


def test_eq1_eq4_thrust_model_linear_in_pressure():
    unit = six_thruster_unit(thrust=0.5, thrust_offset=0.1,
                             correction=0.9)
    p9 = 9 * KGF_PER_CM2
    np.testing.assert_allclose(unit.steady_thrust, 0.5)
    np.testing.assert_allclose(unit.pressure_slope * p9 + 0.1, 0.5)
    low = unit.with_pressure(0.5 * p9)
    np.testing.assert_allclose(low.steady_thrust, 0.5 * 0.4 + 0.1)
    np.testing.assert_allclose(low.cycle_thrust, 0.9 * 0.3)


def test_eq5_6_mean_unit_thrust_is_sum_of_throttled_thrusts(unit):
    k = np.array([0.2, 0.5, 0.7, 0, 0, 0])
    Kd = unit.correction * k                     # K_di = K_pi t_rdi / T_T
    assert unit.force_matrix()[1] @ k == pytest.approx(
        np.sum(Kd * unit.steady_thrust))


def test_casadi_six_unit_equals_numpy_to_1e12():
    f = six_unit_function()
    rng = np.random.default_rng(3)
    for _ in range(5):
        Rr, Lr = rng.uniform(0.1, 1.0, 2)
        p = rng.uniform(2e5, 1e6)
        b = rng.uniform(0.0, 0.1, 6)
        a = rng.uniform(3e-7, 8e-7, 6)
        kp = rng.uniform(0.8, 1.0, 6)
        unit = ThrusterSet(
            six_thruster_unit(R=Rr, L=Lr).positions,
            six_thruster_unit().directions, pressure_slope=a,
            thrust_offset=b, pressure=p, correction=kp)
        F, M, lev = f(Rr, Lr, p, a, b, kp)
        np.testing.assert_allclose(np.array(F), unit.force_matrix(),
                                   atol=1e-12)
        np.testing.assert_allclose(np.array(M), unit.torque_matrix(),
                                   atol=1e-12)
        np.testing.assert_allclose(np.array(lev).ravel(), unit.cycle_thrust,
                                   atol=1e-12)


def test_casadi_general_function_equals_numpy_with_offset_com():
    unit = six_thruster_unit(center_of_mass=(0.01, -0.02, 0.005),
                             correction=[0.9, 1, 1, 0.95, 1, 1])
    f = force_torque_function(6)
    F, M = f(unit.positions, unit.directions, unit.center_of_mass,
             unit.pressure, unit.pressure_slope, unit.thrust_offset,
             unit.correction)
    np.testing.assert_allclose(np.array(F), unit.force_matrix(), atol=1e-12)
    np.testing.assert_allclose(np.array(M), unit.torque_matrix(), atol=1e-12)
    # with the centre of mass off the axis, a group firing equally leaves
    # a torque ([4]'s misalignment disturbance)
    assert np.linalg.norm(np.array(M) @ [1, 1, 1, 0, 0, 0]) > 1e-3


def test_casadi_jacobian_of_torque_in_R_is_the_arm_per_metre():
    f = six_unit_function()
    Rs = ca.SX.sym("R")
    F, M, _ = f(Rs, 0.3, 9 * KGF_PER_CM2, [0.5 / (9 * KGF_PER_CM2)] * 6,
                [0] * 6, [1] * 6)
    J = ca.Function("j", [Rs], [ca.jacobian(M[2, 0], Rs)])
    assert float(J(0.25)) == pytest.approx(-0.5)       # Mz1 = -R P1


def test_transients_short_pulse_mean_thrust_below_kP(unit):
    T = 2.0
    k = np.full(6, 0.015)                   # 30 ms pulse
    true = unit.mean_thrust(k, T)
    assert np.all(true < 0.8 * k * unit.steady_thrust)
    # long pulse: within 1 % of k P
    long = unit.mean_thrust(np.full(6, 0.5), 10.0)
    np.testing.assert_allclose(long, 0.5 * unit.steady_thrust, rtol=1e-2)


def test_transient_impulse_formula_matches_integrated_profile(unit):
    t = np.linspace(0.0, 1.0, 400001)
    on = np.array([0.03, 0.05, 0.1, 0.2, 0.015, 0.5])
    prof = unit.thrust_profile(t, on)
    numeric = np.trapezoid(prof, t, axis=1)
    np.testing.assert_allclose(unit.pulse_impulse(on), numeric, rtol=1e-5)


def test_correction_coefficient_follows_from_transients(unit):
    T, k = 2.0, 0.05
    Kp = unit.correction_coefficient(T, k)
    cal = unit.calibrated(T, k)
    np.testing.assert_allclose(cal.correction, Kp)
    # with K_p the linear cycle model reproduces the true mean thrust
    np.testing.assert_allclose(cal.force_matrix()[1, :3] * k,
                               unit.mean_thrust(np.full(6, k), T)[:3])
    # K_p tends to 1 - (delta_o - delta_c + tau_r - tau_d)/t_on
    c = unit.open_delay - unit.close_delay + unit.rise_time - unit.tail_time
    np.testing.assert_allclose(unit.correction_coefficient(10.0, 1.0),
                               1 - c / 10.0, rtol=1e-12)


def test_no_pulse_no_impulse_and_sub_delay_pulse(unit):
    assert np.all(unit.pulse_impulse(np.zeros(6)) == 0.0)
    tiny = unit.open_delay - unit.close_delay - 1e-3
    assert np.all(unit.pulse_impulse(np.full(6, tiny)) == 0.0)


@pytest.mark.parametrize("kwargs, name", [
    (dict(R=np.nan), "R"),
    (dict(R=-0.1), "R"),
    (dict(thrust=[0.5] * 5), "thrust"),
    (dict(pressure=-1.0), "pressure"),
    (dict(thrust=[0.5, 0.5, 0.5, 0.5, 0.5, -0.5]), "thrust"),
])
def test_bad_unit_arguments_name_the_argument(kwargs, name):
    with pytest.raises((InvalidValueError, ShapeError), match=name):
        six_thruster_unit(**kwargs)


def test_negative_pressure_on_set_rejected(unit):
    with pytest.raises(InvalidValueError, match="pressure"):
        unit.with_pressure(-2e5)


def test_unknown_kwarg_rejected():
    with pytest.raises(TypeError, match="colour"):
        six_thruster_unit(colour="red")


def test_cycle_shorter_than_min_on_time(unit):
    with pytest.raises(InvalidValueError, match="cycle"):
        unit.mean_thrust(np.ones(6), 0.01)


def test_non_unit_directions_rejected(unit):
    with pytest.raises(InvalidValueError, match="directions"):
        ThrusterSet(unit.positions, 2 * unit.directions)


def test_bad_pairs_rejected(unit):
    with pytest.raises(InvalidValueError, match="pairs"):
        ThrusterSet(unit.positions, unit.directions, pairs=((0, 4),),
                    pressure_slope=unit.pressure_slope)


def test_cumulative_impulse_integrates_the_profile(unit):
    on = np.array([0.03, 0.05, 0.1, 0.2, 0.0, 0.5])
    t = np.linspace(0.0, 0.8, 200001)
    prof = unit.thrust_profile(t, on)
    for tk in (0.01, 0.04, 0.07, 0.3, 0.8):
        sel = t <= tk
        np.testing.assert_allclose(unit.cumulative_impulse(tk, on),
                                   np.trapezoid(prof[:, sel], t[sel],
                                                axis=1), atol=2e-7)
    np.testing.assert_allclose(unit.cumulative_impulse(50.0, on),
                               unit.pulse_impulse(on), rtol=1e-12)


def test_thrusters_is_a_leaf_package():
    import subprocess
    import sys
    code = ("import sys, thrusters, thrusters.scenarios; "
            "bad = [m for m in ('allocation', 'ocp') if m in sys.modules]; "
            "print(bad); sys.exit(1 if bad else 0)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_public_api_is_listed():
    import thrusters
    for name in thrusters.__all__:
        assert hasattr(thrusters, name)
    assert "DutyCycleAllocator" in thrusters.__all__
