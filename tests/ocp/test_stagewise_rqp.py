"""The stage-wise step with its QP solved by the Riccati active set in C
(``solver="stagewise", qp_solver="rqp"``): the same steps as the
condensed step and the interior point, its multipliers theirs, capped
points certified as feasible descents, a start beyond a box refused."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from adcs.robust_mc import slew_keep_out
from adcs_common.exceptions import InvalidValueError
from allocation import WheelArray
from ocp import quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import AttitudeMPC, simulate_mpc
from ocp.mpc.stagewise import box_layout, stagewise_qp_function

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
MODEL = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS)
QF = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
ZERO = np.zeros(3)


def _rqp(model=MODEL, horizon=20, **kw) -> AttitudeMPC:
    return AttitudeMPC(model, horizon=horizon, dt=0.5, solver="stagewise",
                       qp_solver="rqp", rti=True, **kw)


def _outputs(f, *args) -> dict:
    return dict(zip(f.name_out(), (np.asarray(v) for v in f(*args))))


def _loop_inputs(mpc, x, qf, n):
    """The first n steps' inputs of ``mpc``'s closed loop from x."""
    rk4 = mpc.model.rk4_step(1)
    out = []
    for _ in range(n):
        z_prev = mpc._plan if mpc._plan is not None else \
            mpc.initial_guess(x)
        out.append((x.copy(), qf, ZERO, z_prev.copy(), mpc._lam_x.copy(),
                    np.zeros(mpc.ng)))
        x = np.asarray(rk4(x, mpc.step(x, qf).u, ZERO, mpc.dt)).ravel()
    return out


@pytest.mark.parametrize("kw", [{}])
def test_steps_equal_the_condensed_and_interior_point_steps(kw):
    """Along the condensed loop's first steps (cold, then saturated
    torques with momentum boxes active): the plan equals the condensed
    step's and the interior point's to 1e-10, and its certificate (the
    KKT residual with rqp's own multipliers) ≤ 1e-10. The multipliers
    need not be the others': a wheel's torque and momentum boxes active
    together make them non-unique (the three solvers' differ by 5 % at
    the first step)."""
    cond = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="condensed",
                       rti=True, **kw)
    ipm = AttitudeMPC(MODEL, horizon=20, dt=0.5, solver="stagewise",
                      rti=True, **kw)
    rqp = _rqp(**kw)
    active = 0
    for args in _loop_inputs(cond, MODEL.state([1.0, 0, 0, 0]), QF, 8):
        ref, mid = _outputs(cond.rti_function, *args), \
            _outputs(ipm.rti_function, *args)
        out = _outputs(rqp.rti_function, *args)
        assert out["qp_kkt"] <= 1e-10 and out["qp_capped"] == 0
        assert np.abs(out["z"] - ref["z"]).max() <= 1e-10
        assert np.abs(out["z"] - mid["z"]).max() <= 1e-10
        active += np.count_nonzero(out["lam_x"])
    assert active > 0                        # boxes were active


def test_closed_loop_equals_the_condensed_loop():
    """A 40 s slew from tumbling rates: the same torques as the
    condensed (DAQP) loop to 1e-9 N·m, every bound kept."""
    runs = [simulate_mpc(m, [1, 0, 0, 0], QF, t_final=40.0,
                         w0=[0.01, -0.02, 0.0])
            for m in (AttitudeMPC(MODEL, horizon=20, dt=0.5,
                                  solver="condensed", rti=True), _rqp())]
    a, b = runs
    assert np.abs(a.trajectory.wheel_torque
                  - b.trajectory.wheel_torque).max() <= 1e-9
    assert b.momentum_violation <= 1e-12 and b.torque_violation <= 1e-12
    assert b.settled and b.settle_time == a.settle_time


def test_capped_steps_are_feasible_descents_and_the_loop_settles():
    """Capped at 8 QP iterations from a random attitude and rates: some
    steps are capped (``qp_capped``, status ``":qp_capped"``), each
    certified (feasible descent ≤ 1e-8) within every bound, and the
    loop reaches the target."""
    from benchmarks.mpc_worst_case import random_states

    mpc = _rqp(solver_options={"qp_max_iter": 8})
    rk4 = MODEL.rk4_step(1)
    x = random_states(MODEL, 1, np.random.default_rng(3))[0]
    capped, statuses = 0, set()
    for _ in range(120):
        res = mpc.step(x, np.array([1.0, 0, 0, 0]))
        statuses.add(res.status)
        assert res.qp_kkt <= 1e-8 and res.first_violation <= 1e-9
        capped += res.status.endswith(":qp_capped")
        x = np.asarray(rk4(x, res.u, ZERO, mpc.dt)).ravel()
    assert capped >= 5 and statuses <= {"rti_step", "rti_step:qp_capped"}
    assert 2 * np.arccos(min(1.0, abs(x[0]))) <= 1e-3


def test_a_start_beyond_a_box_fails_its_certificate():
    """The wrapper on a QP whose start breaks a box (a torque box moved
    beyond the start): flagged infeasible, the start returned with zero
    multipliers; in the step such a certificate is +inf and the step
    returns the shifted plan (`ocp.mpc.condensed.sqp_step_functions`)."""
    from ocp.mpc.riccati_qp import qp_external
    from ocp.mpc.stagewise import StageParts

    mpc = _rqp(horizon=6)
    parts = StageParts(mpc, 1e-9, 1, ipm=False)
    x = MODEL.state([1.0, 0, 0, 0])
    data = [np.asarray(v) for v in stagewise_qp_function(mpc)(
        mpc.initial_guess(x), np.r_[x, QF, ZERO])]
    dU0, dX0, A, B, Q, q, g, r, lo, hi = data
    ext = qp_external(6, parts.lay, 4, ~parts.free, parts.patterns, 1000)
    D = dX0 - _rolled(A, B, dU0, dX0, parts)
    ok = [np.asarray(v) for v in ext(dU0, dX0, D, A, B, Q, q, g, r, lo,
                                     hi, np.zeros_like(lo))]
    assert ok[4] == 0 and ok[3] == 0 and ok[5].any()     # the costates
    lo_bad = lo.copy()
    lo_bad[0, 2] = 0.1                     # torque 1 at stage 2 ≥ 0.1 width
    dU, dX, lam, capped, infeasible, mu, moved = (
        np.asarray(v) for v in ext(dU0, dX0, D, A, B, Q, q, g, r, lo_bad,
                                   hi, np.zeros_like(lo)))
    assert infeasible == 1 and capped == 0 and moved == 0   # no phase one
    assert np.array_equal(dU, dU0) and np.array_equal(dX, dX0)
    assert not lam.any() and not mu.any()


def _rolled(A, B, dU, dX, parts):
    """A_k x_k + B_k u_k of the start, x_0 = 0 (A, B as nonzeros)."""
    sp_a, sp_b, _ = parts.patterns
    out = np.zeros_like(dX)
    for k in range(dX.shape[1]):
        Ak = np.asarray(ca.DM(sp_a, A[:, k]).full())
        Bk = np.asarray(ca.DM(sp_b, B[:, k]).full())
        prev = dX[:, k - 1] if k else np.zeros(dX.shape[0])
        out[:, k] = Ak @ prev + Bk @ dU[:, k]
    return out


RATE_MAX = np.deg2rad(1.0)


def test_a_rate_bound_flies_the_condensed_loop():
    """A 1°/s rate bound at horizon 20, uncapped: the same torques as the
    condensed (DAQP) loop to 1e-9 N·m, the rates within their bound."""
    runs = [simulate_mpc(m, [1, 0, 0, 0], QF, t_final=60.0)
            for m in (AttitudeMPC(MODEL, horizon=20, dt=0.5,
                                  solver="condensed", rti=True,
                                  rate_max=RATE_MAX),
                      _rqp(rate_max=RATE_MAX))]
    a, b = (r.trajectory for r in runs)
    assert np.abs(a.wheel_torque - b.wheel_torque).max() <= 1e-9
    assert np.abs(b.w).max() <= RATE_MAX * (1 + 1e-9)
    assert runs[1].momentum_violation <= 1e-12
    assert runs[1].torque_violation <= 1e-12


def test_starts_beyond_a_rate_box_go_through_the_phase_one():
    """The demo craft capped at 8 with a 1°/s rate bound: the capped
    plans' shifted starts break a rate box (by up to 0.66 box widths);
    the wrapper's phase one moves each to a point that keeps every box
    (``moved``), the step is certified there, and the loop reaches the
    target with the rates within their bound. (Without the phase one
    such a start was refused, the shifted plan applied, and the next
    starts broke more: the craft spun up.) The phase one moves only the
    stages from the first broken one (here the plan's tail, the last
    stage): with a cap of 0 the wrapper returns its point, whose earlier
    stages are the start's."""
    import casadi as ca

    from ocp.mpc.condensed import momentum_safe_tail
    from ocp.mpc.riccati_qp import qp_external
    from ocp.mpc.stagewise import StageParts
    from ocp.mpc.stagewise_rqp import warm_sides
    from ocp.spacecraft import load_spacecraft

    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    mpc = _rqp(model, rate_max=RATE_MAX, solver_options={"qp_max_iter": 8})
    parts = StageParts(mpc, 1e-9, 1, ipm=False)
    ext, ext0 = (qp_external(20, parts.lay, model.nu, ~parts.free,
                             parts.patterns, cap, True) for cap in (8, 0))
    zs = ca.MX.sym("z", mpc.nz)
    tail = ca.Function("tail", [zs], [momentum_safe_tail(mpc, zs)])
    sides = ca.Function("sides", [zs], [warm_sides(mpc, parts, zs)])
    data_of = stagewise_qp_function(mpc)
    rk4 = model.rk4_step(1)
    x = model.state([1.0, 0, 0, 0])
    z, lx, lg = mpc.initial_guess(x), np.zeros(mpc.nz), np.zeros(mpc.ng)
    moved, worst, firsts = 0, 0.0, set()
    for step in range(460):
        out = _outputs(mpc.rti_function, x, QF, ZERO, z, lx, lg)
        assert out["qp_kkt"] <= 1e-8, step
        if step < 12:       # the QP of this step, through the external
            z0, lx0, _ = (np.asarray(v).ravel()
                          for v in mpc.shift_function(x, z, lx, lg))
            z0 = np.asarray(tail(z0)).ravel()
            dU0, dX0, A, B, Q, q, g, r, lo, hi = (
                np.asarray(v) for v in data_of(z0, np.r_[x, QF, ZERO]))
            D = dX0 - _rolled(A, B, dU0, dX0, parts)
            res = [np.asarray(v) for v in ext(dU0, dX0, D, A, B, Q, q, g,
                                              r, lo, hi, sides(lx0))]
            V0 = np.asarray(parts.lay.values(dU0, dX0))
            V1 = np.asarray(parts.lay.values(res[0], res[1]))
            assert res[4].item() == 0
            assert np.all(V1 <= hi + 1e-9) and np.all(V1 >= lo - 1e-9)
            moved += int(res[6].item())
            worst = max(worst, float((V0 - hi).max()), float((lo - V0).max()))
            if res[6].item():
                first = int(np.flatnonzero(((V0 > hi + 1e-9) |
                                            (V0 < lo - 1e-9)).any(0))[0])
                p1 = [np.asarray(v) for v in ext0(dU0, dX0, D, A, B, Q, q,
                                                  g, r, lo, hi, sides(lx0))]
                V = np.asarray(parts.lay.values(p1[0], p1[1]))
                assert p1[3].item() == 1 and p1[6].item() == 1
                assert np.all(V <= hi + 1e-9) and np.all(V >= lo - 1e-9)
                assert np.array_equal(p1[0][:, :first], dU0[:, :first])
                assert np.array_equal(p1[1][:, :first], dX0[:, :first])
                firsts.add(first)
        z, lx, lg = out["z"].ravel(), out["lam_x"].ravel(), \
            out["lam_g"].ravel()
        x = np.asarray(rk4(x, out["u"].ravel(), ZERO, mpc.dt)).ravel()
        assert np.abs(x[4:7]).max() <= RATE_MAX * (1 + 1e-6)
    assert moved >= 2 and worst > 0.1, (moved, worst)
    assert firsts == {19}
    assert 2 * np.arccos(min(1.0, abs(float(np.dot(x[:4], QF))))) <= 1e-3


def test_cones_and_move_blocks_are_refused():
    """Keep-out cones (their states' boxes are not tested with the
    phase one) and move blocks are refused, with the way out."""
    with pytest.raises(InvalidValueError, match="keep-out"):
        _rqp(horizon=10, keep_out=slew_keep_out(np.deg2rad(90.0),
                                                np.deg2rad(20.0)))
    with pytest.raises(InvalidValueError, match="move_blocks"):
        _rqp(horizon=10, move_blocks=2)


def test_the_wrapper_answers_the_posed_qp_and_its_multipliers():
    """The external on one posed QP: optimal (not capped, feasible
    start), its boxes' multipliers zero off their bounds and of the
    sign of the side they hold."""
    from ocp.mpc.riccati_qp import external_name

    mpc = _rqp()
    lay = box_layout(mpc)
    assert external_name(20, 11, 4, lay.nb) == "adcs_rqp_20x11x4x8"
    assert external_name(20, 11, 4, lay.nb, 8) == "adcs_rqp_20x11x4x8_cap8"
    x = MODEL.state([1.0, 0, 0, 0])
    dU0, dX0, *_, lo, hi = (np.asarray(v) for v in stagewise_qp_function(
        mpc)(mpc.initial_guess(x), np.r_[x, QF, ZERO]))
    out = _outputs(mpc.rti_function, x, QF, ZERO, mpc.initial_guess(x),
                   np.zeros(mpc.nz), np.zeros(mpc.ng))
    assert out["qp_kkt"] <= 1e-10 and np.all(lo <= 0) and np.all(hi >= 0)


def test_bad_configurations_are_refused():
    with pytest.raises(InvalidValueError, match="qp_solver None"):
        AttitudeMPC(MODEL, horizon=10, solver="stagewise", qp_solver="daqp")
    with pytest.raises(InvalidValueError, match="move_blocks"):
        _rqp(horizon=10, move_blocks=2)
    with pytest.raises(InvalidValueError, match="qp_max_iter"):
        _rqp(horizon=10, solver_options={"ipm_tol": 1e-9})
    with pytest.raises(InvalidValueError, match="ipm_tol"):
        AttitudeMPC(MODEL, horizon=10, solver="stagewise",
                    solver_options={"qp_max_iter": 3})
    for bad in (0, -1, 2.5, True, "8"):
        with pytest.raises(InvalidValueError, match="qp_max_iter"):
            _rqp(horizon=10, solver_options={"qp_max_iter": bad})
    for bad in (0.0, -1e-4, float("nan"), "1e-4"):
        with pytest.raises(InvalidValueError, match="kkt_tol"):
            _rqp(horizon=10, solver_options={"kkt_tol": bad})


def test_threads_build_and_share_the_solver(tmp_path, monkeypatch):
    """Four threads building controllers of a new QP size at once (each
    compiles into files of its own, one rename wins), then stepping one
    controller's step Function (it keeps no state) from eight starts:
    the answers of one thread alone, bit for bit. `AttitudeMPC.step`
    itself follows one trajectory: a second thread is refused."""
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    from adcs_common.exceptions import ThreadOwnershipError
    from benchmarks.mpc_worst_case import random_states

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with ThreadPoolExecutor(4) as pool:
        a, *_ = pool.map(lambda _: _rqp(horizon=3), range(4))
    assert len(list(tmp_path.rglob("libadcs_rqp_3x*.so"))) == 1
    rk4 = MODEL.rk4_step(1)

    def loop(x):
        z, lx, lg, us = a.initial_guess(x), np.zeros(a.nz), \
            np.zeros(a.ng), []
        for _ in range(6):
            out = _outputs(a.rti_function, x, QF, ZERO, z, lx, lg)
            z, lx, lg = out["z"].ravel(), out["lam_x"].ravel(), \
                out["lam_g"].ravel()
            us.append(out["u"].ravel())
            x = np.asarray(rk4(x, us[-1], ZERO, a.dt)).ravel()
        return np.array(us)

    x0s = random_states(MODEL, 8, np.random.default_rng(5))
    alone = [loop(x0) for x0 in x0s]
    with ThreadPoolExecutor(4) as pool:
        shared = list(pool.map(loop, x0s))
    assert all(np.array_equal(u1, u2) for u1, u2 in zip(alone, shared))
    x = MODEL.state([1.0, 0, 0, 0])
    a.step(x, QF)
    with ThreadPoolExecutor(1) as pool:
        err = pool.submit(a.step, x, QF).exception()
    assert isinstance(err, ThreadOwnershipError)


def test_rqp_flies_a_toml_craft(tmp_path):
    """On a craft of the user's own (a TOML file: other inertia, wheel
    angles and limits) the rqp step flies the condensed DAQP loop
    (states to 1e-9) and, capped at 8, reaches the target within every
    bound."""
    from ocp.spacecraft import load_spacecraft
    from test_primal_qp import CRAFT_TOML, check_toml_runs

    path = tmp_path / "craft.toml"
    path.write_text(CRAFT_TOML)
    sc = load_spacecraft(path)
    qf = quat_from_axis_angle([1.0, -1.0, 0.5], np.deg2rad(90.0))
    runs = {}
    for name, solver, qp, opts in (
            ("daqp", "condensed", None, {}), ("rqp", "stagewise", "rqp", {}),
            ("capped", "stagewise", "rqp", {"qp_max_iter": 8})):
        mpc = AttitudeMPC(sc, horizon=10, dt=0.5, solver=solver, rti=True,
                          qp_solver=qp, solver_options=opts)
        runs[name] = simulate_mpc(mpc, [1, 0, 0, 0], qf, t_final=50.0)
    check_toml_runs(runs, "rqp")


def test_the_costate_certificate_is_the_interior_points():
    """The step's certificate of rqp's optimum, with the costates swept
    back in C (`costate_residual`), equals the interior point's KKT
    residual swept over the stage data in the graph
    (`stagewise_ipm.point_residual`) to 1e-13 along a slew, and flags
    multipliers 10 % off (above 1e-3) wherever a box is active."""
    import casadi as ca

    from ocp.mpc.riccati_qp import qp_external
    from ocp.mpc.stagewise import StageParts, qp_data
    from ocp.mpc.stagewise_ipm import Tree, point_residual
    from ocp.mpc.stagewise_kernels import reverse_columns
    from ocp.mpc.stagewise_rqp import costate_residual

    mpc = _rqp(horizon=10)
    N, nu = 10, MODEL.nu
    parts = StageParts(mpc, 1e-9, 1, ipm=False)
    z, p = ca.MX.sym("z", mpc.nz), ca.MX.sym("p", MODEL.nx + 7)
    _, _, _, data, D = qp_data(mpc, parts, z, p)
    dU0, dX0, A, B, Q, q, g, r, lo, hi = data
    ext = qp_external(N, parts.lay, nu, ~parts.free, parts.patterns, 1000)
    dU, dX, lam, _, _, mu, _ = ext(dU0, dX0, D, A, B, Q, q, g, r, lo, hi,
                                ca.MX.zeros(lo.shape))
    qp = [A, B, Q, q, g, r, lo, hi]
    V = parts.lay.values(dU, dX)
    point = [dU, dX, V - lo, hi - V, ca.fmax(-lam, 0), ca.fmax(lam, 0)]
    old = point_residual(parts.kern, parts.lay, Tree(N), (parts.nq, nu),
                         point, qp + [reverse_columns(M) for M in
                                      (A, B, Q, r)], ca.DM.ones(1, N))
    f = ca.Function("certs", [z, p], [
        costate_residual(parts, N, dU, dX, lam, mu, qp), old,
        costate_residual(parts, N, dU, dX, 1.1 * lam, mu, qp),
        ca.mmax(ca.fabs(lam))])
    active = 0
    for x, qf, tau, z_prev, lx, lg in _loop_inputs(
            mpc, MODEL.state([1.0, 0, 0, 0]), QF, 6):
        z0 = np.asarray(mpc.shift_function(x, z_prev, lx, lg)[0]).ravel()
        new, ref, bad, big = (float(v) for v in f(z0, np.r_[x, qf, tau]))
        assert new <= 1e-10 and abs(new - ref) <= 1e-13
        if big > 0:
            active += 1
            assert bad > 1e-3
    assert active >= 3
