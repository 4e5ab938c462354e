"""Keep-out cones in the stage-wise and robust MPC (`ocp.mpc.keepout`).

The demo slew (90° about (1, 1, 0) from rest) carries the boresight
(1, −1, 0)/√2 through a 20° cone centred 5° off its path
(`adcs.robust_mc.slew_keep_out`): without the cone the MPC flies 14.7°
into it; with it, nominal and robust MPC pass it on the sampled path
and between the samples, every planned state of every scenario keeps
it, and the loop still ends on target.
"""

import shutil

import numpy as np
import pytest

from adcs.robust_mc import draw_plant, robust_scenarios, slew_keep_out
from adcs_common.exceptions import InfeasibleError, InvalidValueError
from allocation import WheelArray
from ocp import KeepOut, quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import (AttitudeMPC, RobustMPC, Scenario, keep_out_margin,
                     simulate_mpc)
from ocp.mpc.keepout import (KEEP_OUT_BACKOFF, cone_function, cone_values,
                             planning_cones, smallest_cone_margin)

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
MODEL = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS)
QF = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
CONE = slew_keep_out(np.deg2rad(90.0), np.deg2rad(20.0))


def _nominal(**kw):
    return AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                       rti=True, rate_max=0.04, **kw)


def test_the_cone_law_in_numpy_and_casadi_agree():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(50, 4))
    cones = (CONE, KeepOut([0, 0, 1], [1, 0, 0], 0.3))
    f = cone_function(cones, MODEL.nx)
    want = cone_values(cones, q)
    for qk, w in zip(q, want):
        x = np.r_[qk, np.zeros(MODEL.nx - 4)]
        np.testing.assert_allclose(np.array(f(x)).ravel(), w, rtol=0,
                                   atol=1e-12)
    # on unit quaternions: cos of the boresight's angle minus cos α
    unit = q / np.linalg.norm(q, axis=1, keepdims=True)
    c = cone_values((CONE,), unit)[:, 0]
    angle = CONE.margin(unit) + CONE.half_angle
    np.testing.assert_allclose(c, np.cos(angle) - np.cos(CONE.half_angle),
                               atol=1e-12)


def test_the_nominal_mpc_flies_round_the_cone_and_reaches_its_target():
    free = simulate_mpc(_nominal(), [1, 0, 0, 0], QF, t_final=60.0)
    assert np.rad2deg(CONE.margin(free.trajectory.q).min()) < -14.0
    mpc = _nominal(keep_out=CONE)
    r = simulate_mpc(mpc, [1, 0, 0, 0], QF, t_final=60.0)
    # on the path between the samples too (8 points per sample)
    margin = keep_out_margin(r, CONE, MODEL)
    assert 0.0 < margin < np.deg2rad(0.5)       # it passed close by
    assert r.final_error < 1e-5 and r.settle_time < 45.0
    assert np.abs(r.trajectory.w).max() <= 0.04 + 1e-9


def test_the_cone_is_planned_widened_by_its_path_pad():
    """The pad is the bound on the path's dip between samples
    (`ocp.slews.keepout.path_margin`); a robust MPC's is its lightest
    scenario's."""
    nom, = planning_cones(_nominal(keep_out=CONE))
    pad = nom.half_angle - CONE.half_angle
    assert np.deg2rad(0.05) < pad < np.deg2rad(0.5)
    rob, = planning_cones(RobustMPC(
        MODEL, robust_scenarios(MODEL.inertia), horizon=3, rti=True,
        rate_max=0.04, keep_out=CONE))
    assert rob.half_angle - CONE.half_angle > pad


def test_one_nominal_scenario_with_a_cone_is_the_nominal_mpc():
    nom = _nominal(keep_out=CONE)
    rob = RobustMPC(MODEL, [Scenario(MODEL.inertia)], horizon=20, dt=0.5,
                    rti=True, rate_max=0.04, keep_out=CONE)
    rk4 = MODEL.rk4_step(1)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    widened = planning_cones(nom)
    closest = -np.inf
    for k in range(40):
        a, b = nom.step(x, QF), rob.step(x, QF)
        # both stop at a KKT residual of 1e-9: the planned torques far in
        # the horizon agree to its rounding (1.4e-10)
        np.testing.assert_allclose(b.u, a.u, rtol=0, atol=1e-10)
        np.testing.assert_allclose(b.plan, a.plan, rtol=0, atol=1e-9)
        closest = max(closest, cone_values(widened, _states(a.plan)).max())
        x = np.array(rk4(x, a.u, np.zeros(3), 0.5)).ravel()
    # the cone was active in those steps: planned states on the widened
    # cone's edge, KEEP_OUT_BACKOFF inside
    assert closest == pytest.approx(-KEEP_OUT_BACKOFF, abs=1e-6)


def _states(plan: np.ndarray, N: int = 20) -> np.ndarray:
    """The quaternions of x_1..x_N of one scenario's plan (N, 4)."""
    m = MODEL.nx + MODEL.nu
    return np.array([plan[j * m:j * m + 4] for j in range(1, N + 1)])


def test_every_scenario_keeps_the_cone_on_a_drawn_plant():
    d = draw_plant(MODEL.inertia, WHEELS, 1, 0)
    plant = rigid_spacecraft(d.inertia, d.wheels)
    mpc = RobustMPC(MODEL, robust_scenarios(MODEL.inertia), horizon=20,
                    dt=0.5, rti=True, rate_max=0.038, keep_out=CONE)
    F = plant.integrator(0.5)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    closest = -np.inf
    for k in range(60):
        s = mpc.step(x, QF)
        # the plan's tail to the QP's tolerance, the applied step exactly
        assert s.violation <= 1e-8 and s.first_violation <= 1e-12
        assert s.qp_kkt <= 1e-6
        for plan in mpc.scenario_plans(s.plan):
            c = cone_values((CONE,), _states(plan)).max()
            assert c < 0.0
            closest = max(closest, c)
        x = np.asarray(F(x0=x, p=np.r_[s.u, 0, 0, 0])["xf"]).ravel()
    # the plans came to the cone (within its path pad of the edge)
    assert closest > -0.01


def test_the_plan_check_counts_a_state_inside_the_cone():
    mpc = _nominal(keep_out=CONE)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    z = mpc.initial_guess(x)
    p = np.r_[x, QF, np.zeros(3)]
    assert float(mpc.check_function(z, p)[1]) == 0.0
    # the boresight on the cone's axis at stage 3
    q_in = _attitude_on_axis(CONE)
    nx, nu = MODEL.nx, MODEL.nu
    z[3 * (nx + nu):3 * (nx + nu) + 4] = q_in
    viol = float(mpc.check_function(z, p)[1])
    assert viol == pytest.approx(1.0 - np.cos(CONE.half_angle), abs=1e-12)
    assert float(mpc.check_function(z, p)[2]) == 0.0    # not x_1


def _attitude_on_axis(cone: KeepOut) -> np.ndarray:
    """A quaternion turning the boresight onto the cone's direction."""
    b, s = np.array(cone.boresight), np.array(cone.direction)
    axis = np.cross(b, s)
    return quat_from_axis_angle(axis, float(np.arccos(b @ s)))


def test_a_state_inside_a_cone_is_refused_as_infeasible():
    """No plan can take the attitude one step ahead out of a cone: the
    step says so, not a failed certificate."""
    b, s = np.array(CONE.boresight), np.array(CONE.direction)
    q_in = quat_from_axis_angle(np.cross(b, s), float(np.arccos(b @ s))
                                - 0.1)
    with pytest.raises(InfeasibleError, match=r"inside keep_out\[0\]"):
        _nominal(keep_out=CONE).step(MODEL.state(q_in), QF)


def test_bad_keep_out_gets_the_toolbox_error():
    with pytest.raises(InvalidValueError, match="stagewise"):
        AttitudeMPC(MODEL, solver="condensed", keep_out=CONE)
    for bad in ("sun", [CONE, "moon"], 3.0):
        with pytest.raises(InvalidValueError, match="keep_out"):
            _nominal(keep_out=bad)
    r = simulate_mpc(_nominal(), [1, 0, 0, 0], QF, t_final=1.0)
    with pytest.raises(InvalidValueError, match="no cone"):
        keep_out_margin(r, [], MODEL)
    with pytest.raises(InvalidValueError, match="substeps"):
        keep_out_margin(r, CONE, MODEL, substeps=0)
    with pytest.raises(InvalidValueError, match="plant"):
        keep_out_margin(r, CONE, "plant")
    assert KEEP_OUT_BACKOFF > 0


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_the_exported_steps_with_a_cone_equal_python_in_closed_loop(
        tmp_path):
    """``export_c(mpc_keep_out=...)``: the stage-wise and robust RTI
    steps in C return what Python does over 80 steps of the slew past
    the cone, and the driver's own C closed loop keeps every bound."""
    import casadi as ca

    from ocp.codegen.export import export_c, run_driver

    names = ("mpc_sw_rti_step", "mpc_robust_rti_step")
    res = export_c(tmp_path / "c", wheels=WHEELS, mpc_variants=names,
                   mpc_keep_out=CONE, rate_max=0.04, build=True,
                   repeats=5)
    rk4 = res.functions["rk4"]
    for name in names:
        f = res.functions[name]
        ext = ca.external(name, str(res.shared_library))
        x, qf, tau, z, lx, lg = (np.asarray(a, float)
                                 for a in res.samples[name])
        margin = np.inf
        for _ in range(80):
            a, b = f(x, qf, tau, z, lx, lg), ext(x, qf, tau, z, lx, lg)
            for i, (ya, yb) in enumerate(zip(a, b)):
                if i != 2:                  # multipliers: not unique
                    np.testing.assert_allclose(np.asarray(yb),
                                               np.asarray(ya), atol=1e-10,
                                               rtol=0)
            assert float(a[6]) <= 1e-9 and float(a[-1]) <= 1e-6
            z, lx = np.asarray(a[1]).ravel(), np.asarray(a[2]).ravel()
            x = np.asarray(rk4(x, a[0], tau, 0.5)).ravel()
            margin = min(margin, CONE.margin(x[:4]))
        assert 0.0 < margin < np.deg2rad(1.0)   # it passed by the cone
    t = run_driver(res)
    for name in names:
        loop = t[f"closed_loop:{name}"]
        assert loop["loop_ok"] == 1
        assert loop["loop_worst_violation"] < 1e-9


def test_export_refuses_a_cone_without_a_stagewise_step(tmp_path):
    from ocp.codegen.export import export_c

    with pytest.raises(InvalidValueError, match="mpc_keep_out"):
        export_c(tmp_path / "c", wheels=WHEELS,
                 mpc_variants=("mpc_cond_rti_step",), mpc_keep_out=CONE)


def test_a_solve_left_near_its_tolerance_resumes(monkeypatch):
    """`stagewise_ipm.IPM_RESUME`: on a tree QP whose interior point stops
    on its carried residual with the recomputed one at 1.2e-6 (draw 140
    of seed 1 with the cone's box scaled by 0.1, step 7: the rate boxes of
    nine scenarios active over many stages), more iterations to a tighter
    tolerance and the polish again certify it; without the resume the
    step would be refused."""
    import ocp.mpc.stagewise as sw
    import ocp.mpc.stagewise_ipm as ipm
    from adcs.robust_mc import draw_case
    from ocp.mpc.robust_qp import _RobustParts, robust_qp_function

    monkeypatch.setattr(sw, "CONE_WIDTH", 0.1)
    mpc = RobustMPC(MODEL, robust_scenarios(MODEL.inertia), horizon=20,
                    dt=0.5, rti=True, rate_max=0.038, keep_out=CONE)
    _, d, _, _ = draw_case("demo", 1, 140, 0.04, 0.2, 90.0, 20, 0.5, 0.05,
                           0.0, 20.0)
    F = rigid_spacecraft(d.inertia, d.wheels).integrator(0.5)
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    for _ in range(7):
        x = np.asarray(F(x0=x, p=np.r_[mpc.step(x, QF).u, 0, 0, 0])[
            "xf"]).ravel()
    z0 = np.array(mpc.shift_function(x, mpc._plan, mpc._lam_x,
                                     mpc._lam_g)[0]).ravel()
    data = robust_qp_function(mpc)(z0, np.r_[x, QF, np.zeros(3)])
    kkt = float(_RobustParts(mpc, 1e-9, 40).ipm(*data)[4])
    monkeypatch.setattr(ipm, "IPM_RESUME", np.inf)
    stopped = float(_RobustParts(mpc, 1e-9, 40).ipm(*data)[4])
    assert stopped > 1e-6 and kkt < 1e-8


def test_smallest_cone_margin_over_cones_and_attitudes():
    """The smallest margin over every cone and attitude (the loop's and
    Basilisk's keep-out figure): by hand, 10° − 30° at the second
    attitude in the first cone; +inf with no cone."""
    a = KeepOut((1, 0, 0), (0, 1, 0), np.deg2rad(30.0))
    b = KeepOut((1, 0, 0), (0, 0, 1), np.deg2rad(5.0))
    q = np.array([[1.0, 0.0, 0.0, 0.0],
                  quat_from_axis_angle([0, 0, 1], np.deg2rad(80.0))])
    assert smallest_cone_margin([a, b], q) == pytest.approx(
        np.deg2rad(-20.0), abs=1e-12)
    assert smallest_cone_margin([b], q) == pytest.approx(np.deg2rad(85.0))
    assert smallest_cone_margin([], q) == np.inf
