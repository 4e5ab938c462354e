"""Robust (multi-stage) MPC: one plan per scenario, one shared command.

With one scenario, the nominal craft, it is the nominal stage-wise MPC
(1e-10); with the nine inertia corners every scenario keeps its bounds,
all share the first command, and the step is the scenario tree's QP
solution (equal to the dense QP of the stacked scenarios, DAQP).
"""

from concurrent.futures import ThreadPoolExecutor

import casadi as ca
import daqp
import numpy as np
import pytest

from adcs_common.exceptions import (InvalidValueError, SolverError,
                                   ThreadOwnershipError)
from allocation import WheelArray
from ocp import quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import (AttitudeMPC, RobustMPC, Scenario, inertia_corners,
                     scenario_grid, simulate_mpc)
from ocp.mpc.robust_qp import _RobustParts, param_rk4, robust_qp_function
from ocp.spacecraft import load_spacecraft

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
MODEL = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS)
QF = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))


def _loop(mpc, n, x=None):
    """(x, z_prev) and the step of the first n steps of a closed loop."""
    rk4 = MODEL.rk4_step(1)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0]) if x is None else x
    out = []
    for _ in range(n):
        z_prev = mpc._plan if mpc._plan is not None else \
            mpc.initial_guess(x)
        s = mpc.step(x, QF)
        out.append((x.copy(), z_prev.copy(), s))
        x = np.array(rk4(x, s.u, np.zeros(3), 0.5)).ravel()
    return out


def test_one_nominal_scenario_is_the_nominal_mpc():
    nom = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                      rti=True)
    rob = RobustMPC(MODEL, [Scenario(MODEL.inertia)], horizon=20, dt=0.5,
                    rti=True)
    for (_, _, a), (_, _, b) in zip(_loop(nom, 6), _loop(rob, 6)):
        np.testing.assert_allclose(b.u, a.u, rtol=0, atol=1e-10)
        np.testing.assert_allclose(b.plan, a.plan, rtol=0, atol=1e-10)


def test_the_parametric_rk4_is_the_model_s():
    mpc = RobustMPC(MODEL, [Scenario(MODEL.inertia)], horizon=3, rti=True)
    rng = np.random.default_rng(4)
    from ocp.mpc.robust_qp import scenario_parameters
    th = scenario_parameters(mpc)[:, 0]
    f, g = param_rk4(mpc), MODEL.rk4_step(1)
    for _ in range(5):
        x = MODEL.state(rng.normal(size=4), 0.05 * rng.normal(size=3),
                        0.1 * rng.normal(size=4))
        u, tau = 0.05 * rng.normal(size=4), 1e-3 * rng.normal(size=3)
        np.testing.assert_allclose(np.array(f(x, u, tau, th)),
                                   np.array(g(x, u, tau, 0.5)),
                                   rtol=0, atol=1e-15)


@pytest.fixture(scope="module")
def corners_loop():
    mpc = RobustMPC(MODEL, inertia_corners(MODEL.inertia, 0.2),
                    horizon=20, dt=0.5, rti=True)
    return mpc, _loop(mpc, 5)


def test_the_scenarios_share_the_first_command(corners_loop):
    mpc, steps = corners_loop
    for _, _, s in steps:
        plans = mpc.scenario_plans(s.plan)
        u0 = np.array([p[mpc._us[0]] for p in plans])
        np.testing.assert_allclose(u0, np.tile(s.u, (9, 1)), rtol=0,
                                   atol=1e-15)
        assert s.qp_kkt <= 1e-8


def test_every_scenario_keeps_its_bounds(corners_loop):
    mpc, steps = corners_loop
    h_max, m_max = np.asarray(WHEELS.h_max), np.asarray(WHEELS.m_max)
    for _, _, s in steps:
        for plan in mpc.scenario_plans(s.plan):
            for k in range(20):
                u = plan[mpc._us[k]]
                h = plan[mpc._xs[k + 1]][7:]
                assert np.all(np.abs(u) <= m_max * (1 + 1e-9))
                assert np.all(np.abs(h) <= h_max * (1 + 1e-9))
        assert s.violation <= 1e-9


@pytest.mark.parametrize("k", [2, 3])
def test_one_robust_step_is_the_dense_stacked_qp(corners_loop, k):
    """The tree's QP written out densely (every scenario's δx through its
    own sensitivities, the shared δu_0 one variable) and solved by DAQP.

    Step 3: the same point to 1e-10. Step 2: the QP is flat along one
    direction (1e-5 N·m in δu moves its cost 1e-9 of itself): the
    interior point, stopped at a KKT residual of 1e-9, and DAQP agree on
    the optimal cost to 1e-9 (relative) and on the point to 2e-5 N·m.
    """
    mpc, steps = corners_loop
    x, z_prev, _ = steps[k]
    p = np.r_[x, QF, np.zeros(3)]
    z0 = np.array(mpc.shift_function(x, z_prev, np.zeros(mpc.nz),
                                     np.zeros(mpc.ng))[0]).ravel()
    out = mpc.rti_function(x, QF, np.zeros(3), z_prev, np.zeros(mpc.nz),
                           np.zeros(mpc.ng))
    data = [np.array(v) for v in robust_qp_function(mpc)(z0, p)]
    H, grad, C, lb, ub, T, c = _dense_tree(_RobustParts(mpc, 1e-9, 1),
                                           *data)
    v, _, flag, _ = daqp.solve(H, grad, C, ub, lb)
    assert flag == 1
    S, N = 9, 20
    plans = np.array(out[1]).reshape(S, -1)
    base = z0.reshape(S, -1)
    got = np.concatenate([plans[s][mpc._us[k]] - base[s][mpc._us[k]]
                          for s in range(S) for k in range(N)])
    vo = np.linalg.lstsq(T, got - c, rcond=None)[0]   # ours in v
    np.testing.assert_allclose(T @ vo + c, got, rtol=0, atol=1e-14)

    def cost(v):
        return 0.5 * v @ H @ v + grad @ v

    assert abs(cost(vo) - cost(v)) <= 1e-9 * abs(cost(v))
    assert np.all(C @ vo <= ub + 1e-12) and np.all(C @ vo >= lb - 1e-12)
    np.testing.assert_allclose(got, T @ v + c, rtol=0,
                               atol=1e-10 if k == 3 else 2e-5)


def _dense_tree(parts, dU0, dX0, A, B, Q, q, g, r, lo, hi):
    """The stacked scenarios' QP in the free controls (numpy).

    Returns ``(H, grad, C, lb, ub, T, c)``: δu = T v + c (c the start's
    offset, the shared u_0 and each scenario's later controls in v).
    """
    N, S, nx, nu = 20, 9, 11, 4
    Eu, Ex = np.array(parts.lay.Eu), np.array(parts.lay.Ex)
    spa, spb, spq = parts.sparsity
    T = np.zeros((S * N * nu, nu + S * (N - 1) * nu))
    for s in range(S):
        T[s * N * nu:s * N * nu + nu, :nu] = np.eye(nu)
        for k in range(1, N):
            j = nu + (s * (N - 1) + k - 1) * nu
            T[(s * N + k) * nu:(s * N + k + 1) * nu, j:j + nu] = np.eye(nu)
    c = dU0.T.ravel()
    n = S * N * nu
    H, grad = np.zeros((n, n)), np.zeros(n)
    rows, lbs, ubs = [], [], []
    for s in range(S):
        G = np.zeros((nx, n))
        for k in range(N):
            col = s * N + k
            Ak, Bk, Qk = (np.array(ca.DM(sp, ca.DM(list(M[:, col]))))
                          for sp, M in ((spa, A), (spb, B), (spq, Q)))
            G = Ak @ G
            G[:, col * nu:(col + 1) * nu] += Bk
            e = dX0[:, col] - G @ c        # the start's δx less G c
            H += G.T @ Qk @ G
            grad += G.T @ (Qk @ e + q[:, col])
            sl = slice(col * nu, (col + 1) * nu)
            H[sl, sl] += np.diag(r[:, col])
            grad[sl] += g[:, col]
            rows.append(Eu @ np.eye(nu, n, col * nu) + Ex @ G)
            lbs.append(lo[:, col] - Ex @ e)
            ubs.append(hi[:, col] - Ex @ e)
    Cm = np.vstack(rows)
    return (T.T @ H @ T, T.T @ (grad + H @ c), Cm @ T,
            np.concatenate(lbs) - Cm @ c, np.concatenate(ubs) - Cm @ c,
            T, c)


def test_scenario_sets_are_built_and_checked():
    grid = scenario_grid(MODEL.inertia, inertia_scale=(0.8, 1.0, 1.2))
    assert len(grid) == 27
    lam = np.sort(np.linalg.eigvalsh(grid[0].inertia))
    np.testing.assert_allclose(lam, np.sort(0.8 * np.array([3.0, 2.5, 3.5])),
                               rtol=1e-14)
    corners = inertia_corners(MODEL.inertia, 0.2)
    assert len(corners) == 9 and corners[0].label == "nominal"
    tilted = scenario_grid(MODEL.inertia, WHEELS.axes,
                           misalignment=(np.deg2rad(0.5),))[0]
    ang = np.arctan2(np.linalg.norm(np.cross(tilted.axes.T, WHEELS.axes.T),
                                    axis=1),
                     np.sum(tilted.axes * WHEELS.axes, 0))
    np.testing.assert_allclose(ang, np.deg2rad(0.5), rtol=1e-12)
    with pytest.raises(InvalidValueError, match="weight"):
        Scenario(MODEL.inertia, weight=0.0)
    with pytest.raises(InvalidValueError, match="scenarios"):
        RobustMPC(MODEL, [])
    with pytest.raises(InvalidValueError, match="misalignment"):
        scenario_grid(MODEL.inertia, misalignment=(0.01,))


CRAFT_TOML = """
name = "user-robust"
description = "A user's pyramid craft, products of inertia known roughly"
inertia = [[3.0, 0.05, -0.02], [0.05, 2.5, 0.03], [-0.02, 0.03, 3.5]]

[wheels]
pyramid = { delta_deg = 55.0, gamma_deg = 45.0 }
h_max = 0.2    # N·m·s
m_max = 0.05   # N·m
"""


def test_a_robust_closed_loop_on_a_toml_craft_reaches_its_target(tmp_path):
    path = tmp_path / "craft.toml"
    path.write_text(CRAFT_TOML)
    sc = load_spacecraft(path)
    mpc = RobustMPC(sc, inertia_corners(sc.inertia, 0.2), horizon=20,
                    dt=0.5, rti=True)
    r = simulate_mpc(mpc, [1, 0, 0, 0], QF, t_final=30.0)
    assert r.final_error < np.deg2rad(0.01)
    assert r.momentum_violation <= 1e-9 and r.torque_violation <= 1e-9


def test_the_closed_loop_can_fly_another_plant():
    """simulate_mpc(plant=…): the MPC plans with its model, the plant flown
    has 20 % more inertia about x (a Monte Carlo draw)."""
    plant = rigid_spacecraft(np.diag([3.6, 2.5, 3.5]), WHEELS)
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                      rti=True)
    same = simulate_mpc(mpc, [1, 0, 0, 0], QF, t_final=10.0)
    other = simulate_mpc(mpc, [1, 0, 0, 0], QF, t_final=10.0, plant=plant)
    d = np.abs(same.trajectory.w - other.trajectory.w).max()
    assert d > 1e-3                      # the plant's inertia was used
    with pytest.raises(InvalidValueError, match="plant"):
        simulate_mpc(mpc, [1, 0, 0, 0], QF, t_final=1.0, plant="x")


def test_every_scenario_plans_with_its_own_dynamics():
    """Converged, each scenario's plan follows its own craft (its inertia,
    axes and disturbance), integrated by that craft's own RK4: a scenario's
    parameters must not leak into another's stages."""
    A = scenario_grid(MODEL.inertia, WHEELS.axes,
                      misalignment=(np.deg2rad(1.0),))[0].axes
    scen = [Scenario(MODEL.inertia),
            Scenario(np.diag([3.6, 2.0, 3.5]), tau=[1e-3, 0.0, -2e-3]),
            Scenario(np.diag([2.4, 3.0, 4.2]), axes=A)]
    mpc = RobustMPC(MODEL, scen, horizon=10, dt=0.5, rti=False)
    x0 = MODEL.state([1.0, 0.0, 0.0, 0.0])
    s = mpc.step(x0, QF)
    assert s.defect <= 1e-9
    for sc, plan in zip(scen, mpc.scenario_plans(s.plan)):
        craft = rigid_spacecraft(sc.inertia, WHEELS if sc.axes is None
                                 else WHEELS.with_axes(sc.axes))
        f = craft.rk4_step(1)
        for k in range(10):
            nxt = np.array(f(plan[mpc._xs[k]], plan[mpc._us[k]], sc.tau,
                             0.5)).ravel()
            np.testing.assert_allclose(nxt, plan[mpc._xs[k + 1]], rtol=0,
                                       atol=1e-9)


def _thread_loop(mpc, n=6):
    """Commands of the first n steps of the slew (RK4 plant), after a
    reset in the calling thread."""
    rk4 = MODEL.rk4_step(1)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    mpc.reset()
    us = []
    for _ in range(n):
        u = mpc.step(x, QF).u
        x = np.array(rk4(x, u, np.zeros(3), mpc.dt)).ravel()
        us.append(u)
    return np.array(us)


def test_one_robust_mpc_per_thread_follows_its_trajectory_exactly():
    """RobustMPC is an AttitudeMPC: one trajectory per thread. Four
    threads, one RobustMPC each, fly the loop one thread flies alone."""
    scen = inertia_corners(MODEL.inertia, 0.2)
    ref = _thread_loop(RobustMPC(MODEL, scen, horizon=8, rti=True))
    assert np.abs(ref).max() > 1e-2            # the slew is under way
    mpcs = [RobustMPC(MODEL, scen, horizon=8, rti=True) for _ in range(4)]
    with ThreadPoolExecutor(4) as pool:
        runs = list(pool.map(_thread_loop, mpcs))
    for us in runs:
        np.testing.assert_allclose(us, ref, rtol=0, atol=1e-12)


def test_a_shared_robust_mpc_refuses_other_threads_until_reset():
    """Four threads on one RobustMPC: the owner's steps go on, the three
    others are refused (its warm start is the owner's trajectory) until
    one of them takes it over by reset()."""
    scen = inertia_corners(MODEL.inertia, 0.2)
    mpc = RobustMPC(MODEL, scen, horizon=8, rti=True)
    twin = RobustMPC(MODEL, scen, horizon=8, rti=True)   # never shared
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    u0 = mpc.step(x, QF).u
    np.testing.assert_allclose(twin.step(x, QF).u, u0, rtol=0, atol=0)
    with ThreadPoolExecutor(3) as pool:
        errors = [f.exception() for f in
                  [pool.submit(mpc.step, x, QF) for _ in range(3)]]
    assert all(isinstance(e, ThreadOwnershipError) for e in errors)
    assert "reset" in str(errors[0])
    # the refused calls left the owner's warm start alone: its second
    # step is the twin's
    x1 = np.array(MODEL.rk4_step(1)(x, u0, np.zeros(3), 0.5)).ravel()
    u1 = mpc.step(x1, QF).u
    np.testing.assert_allclose(u1, twin.step(x1, QF).u, rtol=0, atol=1e-12)
    assert np.abs(u1 - u0).max() > 1e-4        # a warm-started step
    with ThreadPoolExecutor(1) as pool:
        pool.submit(mpc.reset).result()        # hand it over
        u = pool.submit(mpc.step, x, QF).result().u
    np.testing.assert_allclose(u, u0, rtol=0, atol=1e-12)
    with pytest.raises(ThreadOwnershipError):
        mpc.step(x, QF)


RATE_MAX = 0.04      # rad/s: below the slew's unbounded peak rate


def _rate_bounded_loop(n):
    """Up to n steps of the slew by a rate-bounded RobustMPC (nominal,
    0.8³ and 1.2³ inertia; RTI, horizon 20; RK4 plant, nominal craft):
    ``(mpc, [(step, x after it)], refusal or None)``."""
    C = inertia_corners(MODEL.inertia, 0.2)
    mpc = RobustMPC(MODEL, [C[0], C[1], C[8]], horizon=20, dt=0.5,
                    rti=True, rate_max=RATE_MAX)
    rk4 = MODEL.rk4_step(1)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    flown = []
    for _ in range(n):
        try:
            s = mpc.step(x, QF)
        except SolverError as e:
            return mpc, flown, e
        x = np.array(rk4(x, s.u, np.zeros(3), 0.5)).ravel()
        flown.append((s, x))
    return mpc, flown, None


def test_a_rate_bounded_robust_loop_flies_the_slew_within_every_bound():
    """The 90° slew of a rate-bounded RobustMPC, 120 steps (60 s): every
    step's QP is certified, every step keeps torque, momentum and rate
    bounds in every scenario's plan (the rate bound reached), the
    scenarios share their first command, and the plant's rate stays
    within the bound.

    The scenarios' rate boxes at x_1 are all functions of the shared u_0
    and nearly parallel; in the cruise at the rate bound they are all
    nearly active, and the rate boxes of every later stage are active
    with barrier diagonals past 1e10. Until the Riccati step formed its
    subtracted term as WᵀW and the polish took the clearly active boxes
    (`stagewise_polish.clear_active`) and then the boxes its point broke,
    the tree's interior point stalled there (KKT 1.25e-6 at step 7) or
    went NaN, and the step was refused."""
    mpc, flown, refusal = _rate_bounded_loop(120)
    assert refusal is None and len(flown) == 120
    h_max, m_max = np.asarray(WHEELS.h_max), np.asarray(WHEELS.m_max)
    peak = 0.0
    for s, x in flown:
        assert s.qp_kkt <= 1e-8 and s.violation <= 1e-9
        plans = mpc.scenario_plans(s.plan)
        for plan in plans:
            np.testing.assert_allclose(plan[mpc._us[0]], s.u, rtol=0,
                                       atol=1e-15)
            for k in range(20):
                w = plan[mpc._xs[k + 1]][4:7]
                assert np.all(np.abs(plan[mpc._us[k]]) <= m_max * (1 + 1e-9))
                assert np.all(np.abs(plan[mpc._xs[k + 1]][7:])
                              <= h_max * (1 + 1e-9))
                assert np.all(np.abs(w) <= RATE_MAX * (1 + 1e-9))
                peak = max(peak, float(np.abs(w).max()))
        assert np.all(np.abs(x[4:7]) <= RATE_MAX * (1 + 1e-9))
    assert peak >= RATE_MAX * (1 - 1e-6)        # the rate box is active
    err = 2.0 * np.arccos(min(1.0, abs(float(np.dot(flown[-1][1][:4], QF)))))
    assert err < np.deg2rad(0.01)               # the slew is done
