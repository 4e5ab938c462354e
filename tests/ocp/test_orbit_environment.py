"""Orbit environment of [2]: gravity gradient, dipole field, −Bdot."""

import casadi as ca
import numpy as np
import pytest

from adcs_common import InvalidValueError
from adcs_common.quaternion import quat_from_axis_angle
from ocp.missions.orbit_environment import (
    EARTH_DIPOLE,
    bdot_detumble,
    dipole_field_orbit,
    gravity_gradient_torque,
    orbit_model,
    orbit_rate,
)

CHIBIS_J = np.diag([1.02, 1.51, 1.73])  # [2], boom stowed
R_ORBIT = 6_850e3
INC = np.deg2rad(51.7)


def test_orbit_rate_and_dipole_field_of_the_chibis_orbit():
    w0 = orbit_rate(R_ORBIT)
    assert 2 * np.pi / w0 == pytest.approx(5642.2, abs=0.1)  # 94 min
    b0 = EARTH_DIPOLE / R_ORBIT ** 3
    assert b0 == pytest.approx(2.47e-5, rel=2e-3)
    B = dipole_field_orbit(np.array([0.0, np.pi / 2]), INC, R_ORBIT)
    np.testing.assert_allclose(np.linalg.norm(B[:, 0]), b0, rtol=1e-12)
    np.testing.assert_allclose(
        np.linalg.norm(B[:, 1]),
        b0 * np.sqrt(np.cos(INC) ** 2 + 4 * np.sin(INC) ** 2), rtol=1e-12)


def test_gravity_gradient_vanishes_on_principal_axes_and_restores():
    J = np.diag([12.0, 12.5, 1.7])
    w0 = 1e-3
    assert np.allclose(gravity_gradient_torque(J, [0, 0, 1.0], w0), 0.0)
    th = 0.01  # pitch about X2: E3 = (-sin θ, 0, cos θ)
    M = gravity_gradient_torque(J, [-np.sin(th), 0, np.cos(th)], w0)
    assert M[1] == pytest.approx(-3 * w0 ** 2 * np.sin(th) * np.cos(th)
                                 * (12.0 - 1.7), rel=1e-12)


def test_pitch_libration_period_with_a_gravity_boom():
    """Small pitch: J22 θ̈ = -3 ω0² (J11 - J33) θ."""
    J = np.diag([12.0, 12.5, 1.7])
    model = orbit_model(J, radius=R_ORBIT, inclination=INC)
    w0 = model.w0
    wp = w0 * np.sqrt(3 * (12.0 - 1.7) / 12.5)
    half = np.pi / wp
    th0 = np.deg2rad(2.0)
    q0 = quat_from_axis_angle([0, 1, 0], th0)
    # at rest in the orbit frame: absolute rate ω0 about the orbit normal
    x0 = np.r_[q0, 0.0, w0, 0.0]
    x = ca.MX.sym("x", 7)
    t = ca.MX.sym("t")
    ode = model.dynamics(x, ca.DM.zeros(3), ca.DM.zeros(3), t)
    F = ca.integrator("lib", "cvodes", {"x": x, "t": t, "ode": ode}, 0.0,
                      [half, 2 * half], {"abstol": 1e-12, "reltol": 1e-10})
    X = np.asarray(F(x0=x0)["xf"]).T
    pitch = 2 * np.arctan2(X[:, 2], X[:, 0])
    assert pitch[0] == pytest.approx(-th0, rel=2e-3)
    assert pitch[1] == pytest.approx(th0, rel=2e-3)


def test_field_rate_seen_by_body_matches_finite_difference():
    model = orbit_model(CHIBIS_J)
    x0 = np.r_[quat_from_axis_angle([1, 2, 3], 0.7), 0.02, -0.01, 0.03]
    x = ca.MX.sym("x", 7)
    t = ca.MX.sym("t")
    F = ca.integrator("f", "cvodes", {"x": x, "t": t, "ode": model.dynamics(
        x, ca.DM.zeros(3), ca.DM.zeros(3), t)}, 100.0, [100.001, 100.002],
        {"abstol": 1e-13, "reltol": 1e-13})
    xa = np.asarray(F(x0=x0)["xf"]).T
    Ba = [np.asarray(model.field_body(xi, ti)[0]).ravel()
          for xi, ti in ((x0, 100.0), (xa[1], 100.002))]
    fd = (Ba[1] - Ba[0]) / 0.002
    _, Bdot = model.field_body(xa[0], 100.001)
    np.testing.assert_allclose(np.asarray(Bdot).ravel(), fd, rtol=1e-5,
                               atol=1e-12)


@pytest.fixture(scope="module")
def detumble_runs():
    model = orbit_model(CHIBIS_J, radius=R_ORBIT, inclination=INC)
    x0 = np.r_[1.0, 0, 0, 0, 0.05, -0.04, 0.03]
    kw = dict(t_final=2 * 5642.0, gain=2e6, dipole_max=3.2, dt=2.0)
    return (bdot_detumble(model, x0, **kw),
            bdot_detumble(model, x0, failed_coils=(0,), **kw), model)


@pytest.mark.slow
def test_bdot_damps_the_rate_to_about_twice_the_orbit_rate(detumble_runs):
    nominal, _, model = detumble_runs
    rate = np.linalg.norm(nominal.w, axis=1)
    assert rate[0] == pytest.approx(0.0707, abs=1e-4)
    assert rate[-1] < 3 * model.w0  # −Bdot settles near 2 ω0
    assert np.max(np.abs(nominal.dipole)) <= 3.2 + 1e-12


@pytest.mark.slow
def test_bdot_with_one_coil_off_still_damps_but_slower(detumble_runs):
    nominal, failed, model = detumble_runs
    assert np.all(failed.dipole[:, 0] == 0.0)
    i = int(3000 / 2.0)
    assert (np.linalg.norm(failed.w[i]) > 1.5 * np.linalg.norm(nominal.w[i]))
    assert np.linalg.norm(failed.w[-1]) < 3 * model.w0


def test_bdot_rejects_bad_coil_index():
    model = orbit_model(CHIBIS_J)
    with pytest.raises(InvalidValueError, match="failed_coils"):
        bdot_detumble(model, np.r_[1, 0, 0, 0, 0, 0, 0.0], t_final=10.0,
                      gain=1e6, failed_coils=(3,))


def test_bdot_run_plot(detumble_runs):
    import matplotlib

    matplotlib.use("Agg")
    fig = detumble_runs[0].plot()
    assert len(fig.axes) == 2


def test_orbit_wheel_law_gives_the_linear_closed_loop_exactly():
    """Eq. (1.8): J ω̇_rel = -k_ω ω_rel - k_a S + M_gr (no field torque)."""
    from adcs_common.quaternion import quat_to_dcm
    from ocp.missions.orbit_environment import orbit_wheel_law

    model = orbit_model(CHIBIS_J)
    law = orbit_wheel_law(model, 0.02, 1e-4)
    x = ca.SX.sym("x", 10)
    t = ca.SX.sym("t")
    xdot = model.wheel_dynamics(x, law(x, t), ca.DM.zeros(3),
                                ca.DM.zeros(3), t)
    A = quat_to_dcm(x[:4]).T
    w_rel = x[4:7] - model.w0 * A[:, 1]
    f = ca.Function("f", [x, t], [ca.jtimes(w_rel, x, xdot), w_rel])
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.normal(size=4)
        xv = np.r_[q / np.linalg.norm(q), 0.01 * rng.normal(size=3),
                   0.02 * rng.normal(size=3)]
        wdot, wr = (np.asarray(v).ravel() for v in f(xv, 50.0))
        Av = quat_to_dcm(xv[:4]).T
        S = np.array([Av[1, 2] - Av[2, 1], Av[2, 0] - Av[0, 2],
                      Av[0, 1] - Av[1, 0]])
        m_gr = gravity_gradient_torque(CHIBIS_J, Av[:, 2], model.w0)
        np.testing.assert_allclose(CHIBIS_J @ wdot,
                                   -0.02 * wr - 1e-4 * S + m_gr,
                                   atol=1e-15)


def test_orbit_wheel_law_aligns_body_with_orbit_frame():
    from ocp.missions.orbit_environment import (
        orbit_wheel_law, simulate_wheel_law)

    model = orbit_model(CHIBIS_J)
    law = orbit_wheel_law(model, k_omega=0.024, k_a=1e-4)
    q0 = quat_from_axis_angle([1.0, -2.0, 0.5], np.deg2rad(20.0))
    x0 = np.r_[q0, 0.0, model.w0, 0.0, np.zeros(3)]
    t, X = simulate_wheel_law(model, law, x0, t_final=1500.0, dt=5.0)
    err = 2 * np.arccos(np.clip(np.abs(X[:, 0]), 0, 1))
    assert np.rad2deg(err[0]) == pytest.approx(20.0)
    assert np.rad2deg(err[-1]) < 0.05
    assert np.max(np.abs(X[:, 7:])) < 0.05  # Chibis-M pitch wheel 0.05
