"""The condensed SQP (`solver="condensed"`): the same OCP, solved smaller.

One condensed step equals a dense numpy condensing of the same QP (every
sensitivity written out, DAQP's Python package); the converged plan equals
sqpmethod's; the closed loop meets every bound, rate bounds included.
"""

import casadi as ca
import daqp
import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError, SolverNotFound
from allocation import WheelArray
from ocp import quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import AttitudeMPC, simulate_mpc
from ocp.mpc.condensed import STEP_TOL, qp_factor_function
from ocp.mpc.condensed_qp import _independent_rows
from ocp.mpc.problem import BOUND_TOL
from thrusters import six_thruster_unit

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
MODEL = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS)
QF = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))


def _dense_step(mpc, z, p):
    """One Gauss–Newton SQP step by the book: x = x̄ + G δu + e."""
    H, g, A, lba, uba, lo, hi, Gz, ez = _dense_qp(mpc, z, p)
    du, _, flag, _ = daqp.solve(H, g, A, np.r_[hi, uba], np.r_[lo, lba])
    assert flag == 1
    return z + Gz @ du + ez


def _dense_qp(mpc, z, p):
    """Build the condensed QP with every sensitivity written out (numpy)."""
    N, nx, nu, dt = mpc.horizon, MODEL.nx, MODEL.nu, mpc.dt
    xs, us = mpc._xs, mpc._us
    X, U, T = ca.SX.sym("x", nx), ca.SX.sym("u", nu), ca.SX.sym("t", 3)
    F = MODEL.rk4_step(1)(X, U, T, dt)
    lin = ca.Function("lin", [X, U, T], [F, ca.jacobian(F, X),
                                         ca.jacobian(F, U)])
    zs, ps = ca.MX.sym("z", mpc.nz), ca.MX.sym("p", nx + 7)
    r = mpc._objective(zs, ps[:nx], ps[nx:nx + 4], ps[nx + 4:])[0]
    rJ = ca.Function("rJ", [zs, ps], [r, ca.jacobian(r, zs)])
    G = np.zeros((N + 1, nx, N * nu))
    e = np.zeros((N + 1, nx))
    for k in range(N):
        Fk, Ak, Bk = (np.array(v) for v in lin(z[xs[k]], z[us[k]], p[-3:]))
        G[k + 1] = Ak @ G[k]
        G[k + 1][:, k * nu:(k + 1) * nu] += Bk
        e[k + 1] = Ak @ e[k] + Fk.ravel() - z[xs[k + 1]]
    rv, J = (np.array(v) for v in rJ(z, p))
    M, c = np.zeros((rv.size, N * nu)), rv.ravel().copy()
    Gz = np.zeros((mpc.nz, N * nu))
    ez = np.zeros(mpc.nz)
    for k in range(N + 1):
        Gz[xs[k]], ez[xs[k]] = G[k], e[k]
        if k < N:
            Gz[us[k], k * nu:(k + 1) * nu] = np.eye(nu)
    M, c = J @ Gz, c + J @ ez
    # sqpmethod's QP: ½ δzᵀ(2JᵀJ + ρI)δz + ∇fᵀδz with δz = Gz δu + ez
    rho = mpc.regularization
    H = 2 * M.T @ M + rho * Gz.T @ Gz
    g = 2 * M.T @ c + rho * Gz.T @ ez
    lo, hi = MODEL.control_bounds()
    u_bar = np.concatenate([z[s] for s in us])
    h_max = np.asarray(WHEELS.h_max)
    A = np.concatenate([G[k][7:] for k in range(1, N + 1)])
    h_now = np.concatenate([z[xs[k]][7:] + e[k][7:] for k in range(1, N + 1)])
    return (H, g, A, -np.tile(h_max, N) - h_now, np.tile(h_max, N) - h_now,
            np.tile(lo, N) - u_bar, np.tile(hi, N) - u_bar, Gz, ez)


def _slew_states(n=4):
    """Shifted plans and states of the benchmark slew's first steps."""
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, rti=True,
                      solver="condensed")
    rk4 = MODEL.rk4_step(1)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    out = []
    for _ in range(n):
        z_prev = mpc._plan if mpc._plan is not None else \
            mpc.initial_guess(x)
        out.append((x.copy(), z_prev.copy()))
        s = mpc.step(x, QF)
        x = np.array(rk4(x, s.u, np.zeros(3), 0.5)).ravel()
    return mpc, out


def test_one_condensed_step_equals_the_dense_numpy_qp():
    mpc, cases = _slew_states(4)
    for x, z_prev in cases:             # cold, then saturated with
        p = np.r_[x, QF, np.zeros(3)]   # momentum rows active
        z0 = np.array(mpc.shift_function(x, z_prev, np.zeros(mpc.nz),
                                         np.zeros(mpc.ng))[0]).ravel()
        ref = _dense_step(mpc, z0, p)
        out = mpc.rti_function(x, QF, np.zeros(3), z_prev,
                               np.zeros(mpc.nz), np.zeros(mpc.ng))
        np.testing.assert_allclose(np.asarray(out[1]).ravel(), ref,
                                   atol=1e-12, rtol=0)      # 5e-14 seen


def test_riccati_factor_is_the_condensed_hessians():
    """W⁻ᵀ H W⁻¹ = I, the same gradient, momentum rows = A_mom W⁻¹, the
    same bounds."""
    mpc, cases = _slew_states(3)
    f = qp_factor_function(mpc)
    for x, z_prev in cases:
        p = np.r_[x, QF, np.zeros(3)]
        z0 = np.array(mpc.shift_function(x, z_prev, np.zeros(mpc.nz),
                                         np.zeros(mpc.ng))[0]).ravel()
        H, g, A, lba, uba, lbu, ubu = _dense_qp(mpc, z0, p)[:7]
        winv, rows, gc, *bounds = (np.array(v).ravel() if i > 2
                                   else np.array(v)
                                   for i, v in enumerate(f(z0, p)))
        for got, want in zip(bounds, (lbu, ubu, lba, uba)):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
        n = H.shape[0]
        np.testing.assert_allclose(winv.T @ H @ winv, np.eye(n), atol=1e-9)
        np.testing.assert_allclose(gc.ravel(), g, rtol=1e-10,
                                   atol=1e-10 * np.abs(g).max())
        np.testing.assert_allclose(rows, A @ winv, atol=1e-12)
        assert np.all(np.triu(winv, 4) == 0.0)     # block lower triangular


def test_condensed_rti_step_is_sqpmethods_rti_step():
    """The same QP: sqpmethod + qrqp on all of z, condensed on δu.

    Where qrqp's point fails its own certificate (``qp_kkt``; on the
    saturated steps 2 to 5 of the slew: 2e-3 to 2e-2) the
    condensed point is the certified one (and the dense QP's,
    `test_one_condensed_step_equals_the_dense_numpy_qp`)."""
    mpc, cases = _slew_states(6)
    sqp = AttitudeMPC(MODEL, solver="sqpmethod", horizon=20, dt=0.5, rti=True)
    compared = 0
    for x, z_prev in cases:
        a = mpc.rti_function(x, QF, np.zeros(3), z_prev, np.zeros(mpc.nz),
                             np.zeros(mpc.ng))
        b = sqp.rti_function(x, QF, np.zeros(3), z_prev, np.zeros(sqp.nz),
                             np.zeros(sqp.ng))
        assert float(a[-1]) <= 1e-12
        if float(b[-1]) > 1e-9:
            continue
        assert float(b[6]) <= BOUND_TOL        # qrqp's step is a good one
        np.testing.assert_allclose(np.asarray(a[1]), np.asarray(b[1]),
                                   atol=1e-12, rtol=0)      # 4e-14 seen
        compared += 1
    assert compared >= 2


def test_converged_condensed_plan_is_the_sqpmethod_plan():
    cond = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                       solver_options={"step_tol": 1e-10})
    sqp = AttitudeMPC(MODEL, solver="sqpmethod", horizon=20, dt=0.5)
    rk4 = MODEL.rk4_step(1)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    for _ in range(2):
        a, b = cond.step(x, QF), sqp.step(x, QF)
        assert a.status == "converged" and b.status == "Solve_Succeeded"
        assert a.defect < 1e-9 and a.violation <= BOUND_TOL
        # 2e-10 seen: sqpmethod stops at its tol_du = 1e-7
        np.testing.assert_allclose(a.plan, b.plan, atol=5e-10, rtol=0)
        x = np.array(rk4(x, a.u, np.zeros(3), 0.5)).ravel()


def test_anderson_cuts_the_slews_iterations_to_the_same_plans():
    loops = {}
    for m in (0, 3):
        mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                          solver_options={"anderson": m})
        iters, plans, step = [], [], mpc.step

        def record(*a, _step=step, _iters=iters, _plans=plans, **k):
            s = _step(*a, **k)
            _iters.append(s.iterations)
            _plans.append(s.plan)
            return s

        mpc.step = record
        r = simulate_mpc(mpc, [1.0, 0.0, 0.0, 0.0], QF, t_final=12.0)
        loops[m] = (np.array(iters), np.array(plans), r)
    plain, acc = loops[0], loops[3]
    # plain Gauss–Newton: 50 and 45 iterations on steps 3 and 4 of the
    # slew (linear convergence); with memory 3: 17 at the cold first
    # step, at most 10 after it
    assert plain[0].max() >= 45 and acc[0][1:].max() <= 10
    assert acc[0].max() <= 17 and acc[0].sum() < 0.6 * plain[0].sum()
    assert acc[2].extras["statuses"] == {"converged": len(acc[0])}
    # both stop on a step below 1e-6 · m_max: the same plans to ~1e-6
    assert np.abs(acc[1] - plain[1]).max() < 1e-6
    assert acc[2].torque_violation <= 1e-9
    assert acc[2].momentum_violation <= 1e-9


@pytest.mark.parametrize("rti", [True, False])
def test_condensed_closed_loop_settles_within_every_bound(rti):
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, rti=rti,
                      solver="condensed")
    r = simulate_mpc(mpc, [1.0, 0.0, 0.0, 0.0], QF, t_final=40.0)
    assert np.rad2deg(r.final_error) < 1e-3
    assert r.torque_violation <= 1e-9 and r.momentum_violation <= 1e-9
    assert STEP_TOL == 1e-6


def test_condensed_rate_rows_hold_the_rate_bound():
    rate_max = 0.02
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, rti=True,
                      solver="condensed", rate_max=rate_max)
    free = AttitudeMPC(MODEL, horizon=20, dt=0.5, rti=True,
                       solver="condensed")
    sqp = AttitudeMPC(MODEL, horizon=20, dt=0.5, rti=True, solver="sqpmethod",
                      rate_max=rate_max)
    r, f, s = (simulate_mpc(m, [1.0, 0.0, 0.0, 0.0], QF, t_final=100.0)
               for m in (mpc, free, sqp))
    assert np.abs(f.trajectory.w).max() > 1.5 * rate_max     # it binds
    assert np.abs(r.trajectory.w).max() <= rate_max * (1 + 1e-3)
    # 90° at 0.02 rad/s takes 79 s: settled by 100 s, as sqpmethod's
    assert np.rad2deg(r.final_error) < 0.01
    assert abs(r.settle_time - s.settle_time) <= 1.0


def test_dependent_momentum_rows_leave_the_warm_start():
    N, nu, nw = 4, 2, 2
    keep = _independent_rows(N, nu, nw, N * nw)
    lx = np.zeros(N * nu)
    lx[[0, 2]] = -1.0        # wheel 0: bounds of steps 0 and 1 active
    la = np.ones(N * nw)     # every momentum row active
    out = np.asarray(keep(lx, -np.ones(N * nu), np.ones(N * nu), la)).ravel()
    # wheel 0: rows 1, 2 are sums of active bounds (dropped), row 3 not;
    # row 4 follows row 3 with bound 3 inactive: kept
    assert out[0::2].tolist() == [0.0, 0.0, 1.0, 1.0]
    assert out[1::2].tolist() == [1.0, 1.0, 1.0, 1.0]
    # an equal (failed-wheel) bound counts as active
    lb = -np.ones(N * nu)
    lb[1::2] = 0.0
    ub = -lb
    ub[0::2] = 1.0
    out = np.asarray(keep(np.zeros(N * nu), lb, ub, la)).ravel()
    assert out[1::2].tolist() == [0.0, 0.0, 0.0, 0.0]


def test_condensed_refuses_what_it_cannot_solve():
    thr = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS,
                           thrusters=six_thruster_unit())
    with pytest.raises(InvalidValueError, match="wheel-only"):
        AttitudeMPC(thr, solver="condensed")
    with pytest.raises(InvalidValueError, match="step_tol"):
        AttitudeMPC(MODEL, solver="condensed",
                    solver_options={"max_iter": 3})
    with pytest.raises(InvalidValueError, match="step_tol"):
        AttitudeMPC(MODEL, solver="condensed",
                    solver_options={"step_tol": -1.0})
    for bad in (-1, 1.5, True, None):
        with pytest.raises(InvalidValueError, match="anderson"):
            AttitudeMPC(MODEL, solver="condensed",
                        solver_options={"anderson": bad})
    with pytest.raises(SolverNotFound):
        AttitudeMPC(MODEL, solver="condensed", qp_solver="osqp")


def test_condensed_with_a_failed_wheel_settles_as_sqpmethod():
    arr = WHEELS.with_failed(1)
    model = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), arr)
    qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(60.0))
    a, b = (simulate_mpc(AttitudeMPC(model, horizon=20, dt=0.5, rti=True,
                                     **kw), [1.0, 0.0, 0.0, 0.0], qf,
                         t_final=40.0)
            for kw in ({"solver": "condensed"}, {}))
    assert a.settle_time == b.settle_time
    assert a.torque_violation <= 1e-9 and a.momentum_violation <= 1e-9
    # the failed wheel (index 1) is never commanded
    assert np.abs(a.trajectory.wheel_torque[:, 1]).max() == 0.0


def test_converged_plans_over_the_slew_equal_ipopts():
    """From identical inputs at each of the first 30 steps of the slew
    (the saturated part), the converged condensed plan equals IPOPT's
    (tol 1e-12) to 1e-5 m_max (2.6e-6 seen over all 80 steps), while
    sqpmethod + qrqp stops up to 4.6e-5 m_max away (whatever its
    tol_du): the docs state both."""
    cond = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                       solver_options={"step_tol": 1e-10})
    ipo = AttitudeMPC(MODEL, solver="ipopt", horizon=20, dt=0.5,
                      solver_options={"ipopt": {"tol": 1e-12}})
    rk4 = MODEL.rk4_step(1)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    worst = 0.0
    for _ in range(30):
        z_prev = cond._plan if cond._plan is not None else \
            cond.initial_guess(x)
        a = cond.step(x, QF)
        ipo._plan = z_prev.copy()
        b = ipo.step(x, QF)
        ua = np.concatenate([a.plan[u] for u in cond._us])
        ub = np.concatenate([b.plan[u] for u in cond._us])
        worst = max(worst, float(np.abs(ua - ub).max()) / 0.05)
        assert a.qp_kkt <= 1e-9
        x = np.array(rk4(x, a.u, np.zeros(3), 0.5)).ravel()
    assert worst <= 1e-5


def test_condensed_refuses_qrqp_which_fails_its_qp():
    """qrqp on the condensed QP (Hessian I, the bounds as dense rows of
    W⁻¹) returned a point 0.72 from optimality after 3.5 s; the certificate
    showed it, and the condensed SQP now takes daqp only."""
    with pytest.raises(SolverNotFound, match="condensed:qrqp"):
        AttitudeMPC(MODEL, solver="condensed", qp_solver="qrqp")


def test_a_step_whose_certificate_fails_returns_its_warm_start():
    """Generated C cannot raise: a step whose QP fails its certificate
    returns the last plan shifted (its command planned within every bound)
    and still reports the failed certificate. Forced here with a
    certificate tolerance no QP meets."""
    strict = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                         rti=True, solver_options={"kkt_tol": 1e-300})
    mpc = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                      rti=True)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    z_prev = mpc.initial_guess(x)
    args = (x, QF, np.zeros(3), z_prev, np.zeros(mpc.nz), np.zeros(mpc.ng))
    ok, failed = mpc.rti_function(*args), strict.rti_function(*args)
    kkt = float(ok[-1])
    assert 0.0 < kkt <= 1e-12 and float(failed[-1]) == kkt
    z0 = np.asarray(mpc.shift_function(x, z_prev, np.zeros(mpc.nz),
                                       np.zeros(mpc.ng))[0]).ravel()
    np.testing.assert_array_equal(np.asarray(failed[1]).ravel(), z0)
    np.testing.assert_array_equal(np.asarray(failed[0]).ravel(),
                                  z0[mpc._us[0]])
    assert np.abs(np.asarray(ok[1]).ravel() - z0).max() > 1e-3
    with pytest.raises(InvalidValueError, match="kkt_tol"):
        AttitudeMPC(MODEL, solver="condensed",
                    solver_options={"kkt_tol": -1.0})


@pytest.mark.parametrize("bad", [None, "condensed", MODEL])
def test_qp_factor_function_refuses_what_is_not_an_mpc(bad):
    with pytest.raises(InvalidValueError, match="must be an AttitudeMPC"):
        qp_factor_function(bad)


def test_qp_factor_function_poses_any_solvers_qp():
    """The same QP from a stage-wise MPC of the same craft."""
    a = qp_factor_function(AttitudeMPC(MODEL, horizon=4, dt=0.5,
                                       solver="condensed", rti=True))
    b = qp_factor_function(AttitudeMPC(MODEL, horizon=4, dt=0.5,
                                       solver="stagewise", rti=True))
    mpc = AttitudeMPC(MODEL, horizon=4, dt=0.5, solver="condensed")
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    z, p = mpc.initial_guess(x), np.r_[x, QF, np.zeros(3)]
    for u, v in zip(a(z, p), b(z, p)):
        np.testing.assert_array_equal(np.array(u), np.array(v))
