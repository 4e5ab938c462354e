"""The Chibis-M closed loop ([2]) against hand values and eq. (3.7)."""

import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from ocp.missions.magnetic_boom import (
    ChibisConfig,
    CircularOrbit,
    deployed_inertia,
    dipole_scale_gain,
    initial_state,
    pitch_offset_eq37,
    planar_boom_rotates,
    planar_model_critical_dipole,
    simulate,
)

ORBIT = CircularOrbit()


def test_orbit_rate_and_period_by_hand():
    w0 = np.sqrt(3.986004418e14 / 6850e3**3)
    assert ORBIT.rate == pytest.approx(w0)
    assert ORBIT.period / 60 == pytest.approx(94.04, abs=0.01)


def test_orbit_rejects_a_radius_in_km():
    with pytest.raises(InvalidValueError, match="radius"):
        CircularOrbit(radius=6850.0)


def test_torque_free_motion_conserves_angular_momentum_and_norm():
    # no field effect (coils off), no gravity: put the orbit far away
    far = CircularOrbit(radius=4.2e8)
    cfg = ChibisConfig(orbit=far)
    x0 = initial_state(cfg, (10, 20, 30), (1.0, -2.0, 0.5), H0=(0.01, 0, 0))
    r = simulate(cfg, x0, 200.0, n_out=50, rtol=1e-10, atol=1e-12)
    J = np.diag(cfg.inertia)
    # inertial angular momentum: R(q) (J w + H)
    from adcs_common.quaternion import quat_to_dcm
    L = np.array([quat_to_dcm(q) @ (J @ w + h)
                  for q, w, h in zip(r.q, r.w, r.H)])
    # the orbit frame turns by w0 t about X2: take L to inertial axes
    ang = far.rate * r.t
    back = np.array([[[np.cos(a), 0, np.sin(a)], [0, 1, 0],
                      [-np.sin(a), 0, np.cos(a)]] for a in ang])
    Li = np.einsum("kij,kj->ki", back, L)
    assert np.max(np.abs(Li - Li[0])) < 1e-7 * np.linalg.norm(Li[0]) + 1e-9


def test_bdot_with_coil_1_off_damps_slowest_about_axis_3():
    """[2] Fig. 2: the third component is damped more slowly."""
    cfg = ChibisConfig(bdot_gain=5e5, coils=(0, 1, 1))
    r = simulate(cfg, initial_state(cfg, (5, 5, 5), (10, 10, 10)),
                 2 * ORBIT.period, n_out=200)
    final = np.abs(np.degrees(r.w_rel[-1]))
    assert final[2] > final[0] and final[2] > final[1]
    assert np.linalg.norm(r.w_rel[-1]) < 0.3 * np.linalg.norm(r.w_rel[0])


def test_deployed_inertia_inferred_from_epsilon_and_six_degrees():
    A, B, C = deployed_inertia(ORBIT)
    eps = 0.1 * ORBIT.field_strength / (B * ORBIT.rate**2)
    assert eps == pytest.approx(0.16)
    assert np.degrees(pitch_offset_eq37(ORBIT, (A, B, C), 0.1)) == \
        pytest.approx(6.0)
    assert B > A > C  # stable orbital attitude with the boom ([2])


@pytest.mark.slow
def test_eq_3_7_pitch_offset_matches_the_3d_model():
    """-Bdot with dipole scale k and a 0.05 N·m·s pitch wheel (sec. 3.2)."""
    inertia = deployed_inertia(ORBIT)
    for k in (0.05, 0.2):
        cfg = ChibisConfig(inertia=inertia,
                           bdot_gain=dipole_scale_gain(ORBIT, k))
        r = simulate(cfg, initial_state(cfg, H0=(0, 0.05, 0)),
                     10 * ORBIT.period, n_out=1000)
        late = r.t > 5 * ORBIT.period
        mean = np.degrees(r.angles[late, 0].mean())
        assert mean == pytest.approx(
            np.degrees(pitch_offset_eq37(ORBIT, inertia, k)), rel=0.06)


def test_papers_linear_model_gives_the_0_35_boundary():
    k = planar_model_critical_dipole(deployed_inertia(ORBIT), ORBIT,
                                     0.6 * ORBIT.rate)
    assert k == pytest.approx(0.35, abs=0.01)


def test_planar_boom_oscillates_without_dipole_and_rotates_when_fast():
    inertia = deployed_inertia(ORBIT)
    assert not planar_boom_rotates(inertia, ORBIT, 0.0,
                                   rate0=0.6 * ORBIT.rate)
    # above the critical rate of eq. (3.3): sqrt(3 (A - C) / B) w0
    A, B, C = inertia
    fast = 1.05 * np.sqrt(3 * (A - C) / B) * ORBIT.rate
    assert planar_boom_rotates(inertia, ORBIT, 0.0, rate0=fast)


def test_closed_loop_ode_equals_orbit_model_with_bdot_and_wheel_law():
    """One closed loop, two builders, the same right-hand side.

    `closed_loop_ode` (continuous −Bdot, eq. 1.8 wheel law with symbolic
    gains) against `orbit_model` with the same laws applied to its
    ``field_body`` and ``orbit_wheel_law``.
    """
    import casadi as ca

    from ocp.missions.magnetic_boom import _params, closed_loop_ode
    from ocp.missions.orbit_environment import (
        bdot_dipole, orbit_model, orbit_wheel_law)

    J = (1.02, 1.51, 1.73)
    cfg = ChibisConfig(inertia=J, bdot_gain=3e5, max_dipole=0.5,
                       coils=(1, 0, 1), wheel_gains=(0.02, 0.003))
    f = closed_loop_ode(ORBIT, J)
    model = orbit_model(np.diag(J), radius=ORBIT.radius,
                        inclination=ORBIT.inclination)
    law = orbit_wheel_law(model, 0.02, 0.003)
    rng = np.random.default_rng(4)
    for _ in range(5):
        x = initial_state(cfg, rng.uniform(-40, 40, 3), rng.uniform(-2, 2, 3),
                          u0=rng.uniform(0, 2 * np.pi),
                          H0=rng.uniform(-0.01, 0.01, 3))
        t = x[10] / ORBIT.rate            # u = u0 + w0 t with u0 = 0
        xe = x[:10]
        xdot = np.array(f(x, _params(cfg))).ravel()
        _, Bdot = model.field_body(xe[:7], t)
        m = bdot_dipole(Bdot, 3e5, 0.5, ca.DM([1, 0, 1]))
        hdot = law(xe, t)
        ref = np.array(model.wheel_dynamics(xe, hdot, m, np.zeros(3),
                                            t)).ravel()
        np.testing.assert_allclose(xdot[:10], ref, rtol=1e-9, atol=1e-15)
        assert xdot[10] == pytest.approx(ORBIT.rate)
