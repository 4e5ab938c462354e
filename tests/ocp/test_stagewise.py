"""The stage-wise SQP (`solver="stagewise"`): the condensed SQP's steps,
solved by a Riccati interior point whose cost and code grow linearly in N.

One step equals the condensed step (DAQP, exact active set) to 1e-10 at
N = 20 and 50, on the demo craft and on a user's TOML craft; the closed
loops agree to the step tolerance; the generated C loops over the stages
(its size barely moves from N = 20 to N = 100).
"""

import casadi as ca
import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from allocation import WheelArray
from ocp import quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import AttitudeMPC, simulate_mpc
from ocp.mpc.stagewise import StageParts, stagewise_qp_function
from ocp.mpc.stagewise_ipm import IPM_MAX_ITER, IPM_TOL
from ocp.spacecraft import load_spacecraft
from thrusters import six_thruster_unit

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
MODEL = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS)
QF = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))

USER_TOML = """
name = "user-five"
description = "A user's five-wheel craft (cone of 50 degrees)"
inertia = [[12.0, 0.3, -0.1], [0.3, 9.0, 0.2], [-0.1, 0.2, 14.0]]   # kg·m²

[wheels]
axes = [[0.766044, 0.0, 0.642788],
        [0.236721, 0.728552, 0.642788],
        [-0.619743, 0.45027, 0.642788],
        [-0.619743, -0.45027, 0.642788],
        [0.236721, -0.728552, 0.642788]]
h_max = 0.4    # N·m·s
m_max = 0.02   # N·m
"""


def _states(mpc, x, qf, n):
    """(x, z_prev) of the first n steps of a closed loop of ``mpc``."""
    model = mpc.model
    rk4 = model.rk4_step(1)
    out = []
    for _ in range(n):
        z_prev = mpc._plan if mpc._plan is not None else \
            mpc.initial_guess(x)
        out.append((x.copy(), z_prev.copy()))
        s = mpc.step(x, qf)
        x = np.array(rk4(x, s.u, np.zeros(3), mpc.dt)).ravel()
    return out


def _compare_one_steps(model, qf, horizon, n=6, **kw):
    cond = AttitudeMPC(model, horizon=horizon, dt=0.5, solver="condensed",
                       rti=True, **kw)
    sw = AttitudeMPC(model, horizon=horizon, dt=0.5, solver="stagewise",
                     rti=True, **kw)
    x0 = model.state([1.0, 0.0, 0.0, 0.0])
    worst = 0.0
    for x, z_prev in _states(cond, x0, qf, n):
        args = (x, qf, np.zeros(3), z_prev, np.zeros(cond.nz),
                np.zeros(cond.ng))
        ref = cond.rti_function(*args)
        out = sw.rti_function(*args)
        assert float(out[-1]) <= 1e-9            # its KKT certificate
        plan = np.asarray(out[1])
        assert np.all(np.isfinite(plan))
        worst = max(worst, float(np.abs(plan - np.asarray(ref[1])).max()))
    return worst


@pytest.mark.parametrize("horizon", [20, 50])
def test_one_step_equals_the_condensed_step(horizon):
    # cold start, then saturated torques with momentum rows active
    assert _compare_one_steps(MODEL, QF, horizon) <= 1e-10


def _user_craft(tmp_path):
    path = tmp_path / "user.toml"
    path.write_text(USER_TOML)
    return load_spacecraft(path)


@pytest.mark.parametrize("horizon", [20, 50])
def test_one_step_equals_the_condensed_step_on_a_user_toml_craft(tmp_path,
                                                                 horizon):
    sc = _user_craft(tmp_path)
    qf = quat_from_axis_angle([0.0, 1.0, 1.0], np.deg2rad(60.0))
    assert _compare_one_steps(sc.model(), qf, horizon, n=4) <= 1e-10


def test_rate_bound_and_failed_wheel_steps_equal_the_condensed_ones():
    failed = WheelArray.pyramid(h_max=0.2, m_max=0.05).with_failed(2)
    model = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), failed)
    assert _compare_one_steps(model, QF, 20, n=4, rate_max=0.03) <= 1e-10


@pytest.mark.parametrize("craft,horizon", [("demo", 20), ("demo", 50),
                                           ("user", 20)])
def test_closed_loops_agree_to_the_step_tolerance(tmp_path, craft, horizon):
    model, qf = MODEL, QF
    if craft == "user":
        model = _user_craft(tmp_path).model()
        qf = quat_from_axis_angle([0.0, 1.0, 1.0], np.deg2rad(60.0))
    m_max = float(np.max(model.wheels.m_max))
    runs = {}
    for solver in ("condensed", "stagewise"):
        mpc = AttitudeMPC(model, horizon=horizon, dt=0.5, solver=solver)
        runs[solver] = simulate_mpc(mpc, [1, 0, 0, 0], qf, t_final=20.0)
    a, b = runs["condensed"], runs["stagewise"]
    # both converge each step to max |δu / m_max| <= 1e-6
    du = np.abs(a.trajectory.wheel_torque
                - b.trajectory.wheel_torque).max()
    assert du <= 10 * 1e-6 * m_max
    assert max(a.momentum_violation, b.momentum_violation) <= 1e-12
    assert abs(a.final_error - b.final_error) <= 1e-6


def test_the_qp_data_holds_the_dynamics_and_the_boxes():
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                      rti=True)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0], [0.01, 0.0, -0.02],
                    [0.1, -0.05, 0.0, 0.02])
    z0 = mpc.initial_guess(x)
    p = np.r_[x, QF, np.zeros(3)]
    dU0, dX0, *_, lo, hi = (np.array(v) for v in
                            stagewise_qp_function(mpc)(z0, p))
    assert np.all(dU0 == 0.0)
    # the start is the plan's defects carried along the linearisation:
    # δx_{k+1} = A δx_k + d with every node at x (A = ∂RK4/∂x, d = the
    # RK4 step's change), so δx_1 is the exact step
    X, U = ca.SX.sym("x", MODEL.nx), ca.SX.sym("u", MODEL.nu)
    F = MODEL.rk4_step(1)(X, U, np.zeros(3), 0.5)
    lin = ca.Function("lin", [X, U], [F, ca.jacobian(F, X)])
    Fx, A = (np.array(v) for v in lin(x, np.zeros(4)))
    d, dx = Fx.ravel() - x, np.zeros(MODEL.nx)
    for k in range(20):
        dx = A @ dx + d
        np.testing.assert_allclose(dX0[:, k], dx, rtol=0, atol=1e-15)
    # the scaled boxes span one unit each
    np.testing.assert_allclose(hi - lo, 1.0, rtol=0, atol=1e-15)


def test_the_interior_point_reports_its_residual_and_iterations():
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                      rti=True)
    s = mpc.step(MODEL.state([1.0, 0.0, 0.0, 0.0]), QF)
    assert s.status == "rti_step" and s.qp_kkt <= IPM_TOL
    assert np.abs(s.u).max() == pytest.approx(0.05, abs=1e-12)


def test_bad_configurations_are_refused():
    with pytest.raises(InvalidValueError, match="qp_solver None"):
        AttitudeMPC(MODEL, solver="stagewise", qp_solver="daqp")
    with pytest.raises(InvalidValueError, match="ipm_tol"):
        AttitudeMPC(MODEL, solver="stagewise",
                    solver_options={"row_tol": 1e-9})
    with_thr = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS,
                                thrusters=six_thruster_unit())
    with pytest.raises(InvalidValueError, match="wheel-only"):
        AttitudeMPC(with_thr, solver="stagewise")


def _generated_lines(horizon):
    mpc = AttitudeMPC(MODEL, horizon=horizon, dt=0.5, solver="stagewise",
                      rti=True)
    cg = ca.CodeGenerator("sw_size")
    cg.add(mpc.step_function)
    return cg.dump().count("\n")


def test_generated_code_does_not_grow_with_the_horizon():
    n20, n100 = _generated_lines(20), _generated_lines(100)
    assert n100 <= 2.0 * n20, (n20, n100)      # 23.5k and 36.6k lines


def test_move_blocking_step_equals_the_dense_blocked_qp():
    """δu = T v + c (T the blocks, c the start's offset to them): the
    condensed QP of `test_condensed` in v, solved by DAQP."""
    import daqp
    from test_condensed import _dense_qp

    blocks = (1, 2, 3, 4, 5, 5)
    sw = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                     rti=True, move_blocks=blocks)
    cond = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                       rti=True)
    first = np.repeat(np.r_[0, np.cumsum(blocks)[:-1]], blocks)
    T = np.kron(np.eye(20)[:, first].T @ np.eye(20)[:, np.r_[0, np.cumsum(
        blocks)[:-1]]], np.eye(4))
    for x, z_prev in _states(cond, MODEL.state([1.0, 0.0, 0.0, 0.0]), QF,
                             4):
        p = np.r_[x, QF, np.zeros(3)]
        z0 = np.array(cond.shift_function(x, z_prev, np.zeros(cond.nz),
                                          np.zeros(cond.ng))[0]).ravel()
        H, g, A, lba, uba, lo, hi, Gz, ez = _dense_qp(cond, z0, p)
        ubar = np.concatenate([z0[s] for s in cond._us])
        c = ubar[np.repeat(first, 4) * 4 + np.tile(np.arange(4), 20)] - ubar
        Hv, gv = T.T @ H @ T, T.T @ (g + H @ c)
        Cv = np.vstack([T, A @ T])
        v, _, flag, _ = daqp.solve(Hv, gv, Cv, np.r_[hi - c, uba - A @ c],
                                   np.r_[lo - c, lba - A @ c])
        assert flag == 1
        ref = z0 + Gz @ (T @ v + c) + ez
        out = sw.rti_function(x, QF, np.zeros(3), z_prev,
                              np.zeros(sw.nz), np.zeros(sw.ng))
        assert float(out[-1]) <= 1e-9
        np.testing.assert_allclose(np.asarray(out[1]).ravel(), ref,
                                   rtol=0, atol=1e-10)
        u = np.asarray(out[1]).ravel()
        U = np.stack([u[s] for s in sw._us])
        for k in range(20):          # every stage holds its block's first
            np.testing.assert_allclose(U[k], U[first[k]], rtol=0, atol=1e-15)


def test_move_blocks_are_checked():
    assert AttitudeMPC(MODEL, horizon=20, solver="stagewise",
                       move_blocks=6).move_blocks == (3, 3, 3, 3, 4, 4)
    for bad in (0, 21, (5, 5), (10, 10.0), "4"):
        with pytest.raises(InvalidValueError, match="move_blocks"):
            AttitudeMPC(MODEL, horizon=20, solver="stagewise",
                        move_blocks=bad)
    with pytest.raises(InvalidValueError, match="stagewise"):
        AttitudeMPC(MODEL, horizon=20, solver="condensed", move_blocks=4)


def test_a_blocked_closed_loop_reaches_the_target():
    mpc = AttitudeMPC(MODEL, horizon=40, dt=0.5, solver="stagewise",
                      rti=True, move_blocks=8)
    r = simulate_mpc(mpc, [1, 0, 0, 0], QF, t_final=40.0)
    assert r.final_error < np.deg2rad(0.01)       # 2.8e-3 deg seen
    assert r.momentum_violation <= 1e-12 and r.torque_violation <= 1e-12


def test_the_default_solver_follows_the_horizon():
    from ocp.mpc import default_mpc_solver
    from ocp.mpc.certificate import LONG_HORIZON

    assert default_mpc_solver(MODEL) == "condensed"
    assert default_mpc_solver(MODEL, LONG_HORIZON) == "condensed"
    assert default_mpc_solver(MODEL, LONG_HORIZON + 1) == "stagewise"
    assert AttitudeMPC(MODEL, horizon=60, rti=True).solver == "stagewise"


@pytest.mark.parametrize("rate_max, horizon", [(0.04, 20), (0.06, 20),
                                               (0.08, 20), (0.06, 60)])
def test_a_rate_bounded_closed_loop_keeps_its_certificate(rate_max,
                                                          horizon):
    """With a rate bound every RTI step of the slew is its QP's certified
    solution, and the rate stays within the bound. At 0.06 rad/s step 17
    failed (KKT 5e-6) until the Riccati step subtracted WᵀW: an active
    rate box drives the barrier's curvature past 1e12, and the textbook
    update left P_k indefinite. So the default solver at a long horizon
    is "stagewise" with a rate bound too."""
    mpc = AttitudeMPC(MODEL, horizon=horizon, dt=0.5, solver="stagewise",
                      rti=True, rate_max=rate_max)
    r = simulate_mpc(mpc, [1, 0, 0, 0], QF, t_final=40.0)
    assert np.max(np.abs(r.trajectory.w)) <= rate_max * (1 + 1e-6)
    assert r.momentum_violation <= 1e-12 and r.torque_violation <= 1e-12
    assert AttitudeMPC(MODEL, horizon=60, rti=True,
                       rate_max=rate_max).solver == "stagewise"


def test_a_hold_is_the_unconstrained_optimum_without_the_interior_point():
    """At the target the QP's unconstrained optimum keeps every box: one
    factor answers it (0 interior-point iterations, zero multipliers),
    exact, and equal to the condensed step's; a saturated slew runs the
    interior point."""
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                      rti=True)
    ipm = StageParts(mpc, IPM_TOL, IPM_MAX_ITER).ipm
    qp = stagewise_qp_function(mpc)
    hold = MODEL.state(QF, [1e-4, -2e-4, 1e-4], [0.01, 0.0, -0.01, 0.0])
    slew = MODEL.state([1.0, 0.0, 0.0, 0.0])
    for x, free in ((hold, True), (slew, False)):
        z0 = mpc.initial_guess(x)
        p = np.r_[x, QF, np.zeros(3)]
        dU, dX, lam, n, kkt = ipm(*qp(z0, p))
        assert (float(n) == 0) is free
        if free:
            assert np.all(np.array(lam) == 0.0) and float(kkt) <= 1e-12
    cond = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                       rti=True)
    args = (hold, QF, np.zeros(3), mpc.initial_guess(hold),
            np.zeros(mpc.nz), np.zeros(mpc.ng))
    a, b = mpc.rti_function(*args), cond.rti_function(*args)
    np.testing.assert_allclose(np.asarray(a[1]), np.asarray(b[1]), rtol=0,
                               atol=1e-12)
