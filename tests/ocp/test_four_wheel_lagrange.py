"""[3]: Lagrange model by automatic differentiation, the 150 s run."""

import matplotlib

matplotlib.use("Agg")

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from adcs_common import InvalidValueError  # noqa: E402
from ocp.models.angles import body_rates_from_angle_rates  # noqa: E402
from ocp.missions.four_wheel_lagrange import (  # noqa: E402
    FOUR_WHEEL_INERTIA,
    four_wheel_run,
    four_wheel_craft,
)


def _ne_rates_from_lagrange(sc):
    """ω̇ and Ḣ_w implied by the Lagrange equations (exact, by AD)."""
    x = ca.SX.sym("x", 14)
    u = ca.SX.sym("u", 4)
    tau = ca.SX.sym("tau", 3)
    xdot = sc.lagrange(x, u, tau)
    w = body_rates_from_angle_rates(x[:3], x[7:10])
    h = ca.DM(sc.spin_inertia) * (ca.DM(sc.wheels.axes).T @ w + x[10:14])
    return ca.Function("ne_rates", [x, u, tau],
                       [ca.jtimes(w, x, xdot), ca.jtimes(h, x, xdot)])


@pytest.mark.parametrize("with_offsets", [False, True])
def test_lagrange_equations_equal_newton_euler_on_random_states(
        with_offsets):
    rng = np.random.default_rng(7)
    offsets = 0.4 * rng.normal(size=(3, 4)) if with_offsets else None
    sc = four_wheel_craft(offsets=offsets)
    f = _ne_rates_from_lagrange(sc)
    for _ in range(25):
        x = np.r_[rng.uniform(-1.3, 1.3, 3), rng.normal(size=4),
                  0.05 * rng.normal(size=3), 200 * rng.normal(size=4)]
        u = 0.034 * rng.uniform(-1, 1, 4)
        tau = 0.01 * rng.uniform(-1, 1, 3)
        wdot, hdot = (np.asarray(v).ravel() for v in f(x, u, tau))
        ne = np.asarray(sc.newton_euler.dynamics(
            sc.to_newton_euler(x), u, tau)).ravel()
        np.testing.assert_allclose(wdot, ne[4:7], rtol=0, atol=1e-9 *
                                   max(1.0, np.abs(ne[4:7]).max()))
        np.testing.assert_allclose(hdot, u, atol=1e-12)  # Ḣ_w = m
        np.testing.assert_allclose(hdot, ne[7:], atol=1e-12)


def test_newton_euler_inertia_adds_transverse_and_offset_terms():
    r = np.zeros((3, 4))
    r[:, 3] = [0.2, 0.0, 0.0]
    sc = four_wheel_craft(offsets=r, mass=3.0)
    It = sc.transverse_inertia
    expected = FOUR_WHEEL_INERTIA + np.diag([It[0] * 0 + It[1] + It[2],
                                          It[0] + It[2], It[0] + It[1]])
    a = sc.wheels.axes[:, 3]
    expected = expected + It[3] * (np.eye(3) - np.outer(a, a))
    expected = expected + 3.0 * np.diag([0.0, 0.04, 0.04])
    np.testing.assert_allclose(sc.inertia, expected, atol=1e-14)
    # 17M71: I_s = 4.27 N·m·s / 366.5 rad/s
    assert sc.spin_inertia[0] == pytest.approx(4.27 / (3500 * np.pi / 30))


def test_kinetic_energy_is_quadratic_in_rates():
    sc = four_wheel_craft()
    q = np.r_[0.1, 0.2, 0.3, np.zeros(4)]
    qd = np.r_[0.01, 0.0, 0.0, np.zeros(4)]
    T = float(sc.kinetic_energy(q, qd))
    # rolling about X at 0.01 rad/s: ½ (Ixx + It2 + It3) ω², rotors locked
    Jxx = sc.inertia[0, 0] + sc.spin_inertia[0] \
        + sc.spin_inertia[3] * 0.25
    assert T == pytest.approx(0.5 * Jxx * 1e-4, rel=1e-12)


def test_four_wheel_150s_open_loop_run_matches_paper_ranges():
    run = four_wheel_run()
    assert run.t[-1] == pytest.approx(150.0)
    roll = run.angles[:, 0]
    # free wheels (H_w = 0) add no spin inertia: γ = ½ τ t² / J_xx, 74.8°
    jxx = four_wheel_craft().inertia[0, 0]
    assert np.rad2deg(roll[-1]) == pytest.approx(
        np.rad2deg(0.5 * 1e-2 * 150 ** 2 / jxx), rel=2e-3)
    assert np.rad2deg(roll[-1]) == pytest.approx(74.8, abs=0.05)
    assert np.all(np.abs(np.rad2deg(run.angles)) <= 80.0)
    assert np.all(np.abs(run.wheel_speed) <= 366.0)
    # free wheels keep their absolute momentum (zero)
    np.testing.assert_allclose(run.wheel_momentum, 0.0, atol=1e-6)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_four_wheel_stabilised_run_absorbs_the_disturbance(axis):
    sc = four_wheel_craft()
    run = four_wheel_run(sc, controller="pd", disturbance_axis=axis,
                      reltol=1e-8, abstol=1e-10)
    assert np.max(np.abs(np.rad2deg(run.angles))) < 3.0
    assert np.all(np.abs(run.wheel_speed) <= 366.0)
    assert np.max(np.abs(run.wheel_torque)) <= 0.034 + 1e-12
    # total momentum: the wheels hold the disturbance impulse (1.5 N·m·s)
    H_body = sc.inertia @ run.w[-1] + sc.wheels.axes @ run.wheel_momentum[-1]
    assert H_body[axis] == pytest.approx(1.5, rel=0.05)


def test_four_wheel_custom_disturbance_and_plot():
    run = four_wheel_run(t_final=20.0, dt=1.0,
                      disturbance=lambda t: np.array([0, 0, 1e-2 * np.sign(
                          10.0 - t)]))
    assert run.disturbance.shape == (20, 3)
    assert run.disturbance[0, 2] == 1e-2 and run.disturbance[-1, 2] == -1e-2
    assert abs(run.w[-1, 2]) < 1e-6  # +impulse then -impulse
    fig = run.plot()
    assert len(fig.axes) == 3


def test_four_wheel_bad_arguments():
    with pytest.raises(InvalidValueError, match="controller"):
        four_wheel_run(controller="lqr")
    with pytest.raises(InvalidValueError, match="disturbance_axis"):
        four_wheel_run(disturbance_axis=3)
