"""The condensed step with its QP solved by the primal active set in C
(``qp_solver="pqp"``, `ocp.mpc.primal_qp`).

The QP is strictly convex, so the primal active set and DAQP reach the
same optimum: the two steps fly the same closed loop, each QP point
certified by the step's own KKT residual; the primal solver enters the
step as an external call that generated C keeps.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from benchmarks.mpc_worst_case import random_states
from ocp.models.rigid import rigid_spacecraft
from ocp.mpc import AttitudeMPC
from ocp.mpc.condensed import STEP_NAMES
from ocp.mpc.primal_qp import external_name, wrapper_source
from ocp.spacecraft import load_spacecraft
from adcs_common.exceptions import SolverNotFound


def _loop(mpc: AttitudeMPC, x0: np.ndarray, steps: int) -> dict:
    rk4 = mpc.model.rk4_step(1)
    qf, tau = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3)
    x, z = x0.copy(), mpc.initial_guess(x0)
    lx, lg = np.zeros(mpc.nz), np.zeros(mpc.ng)
    us, kkt = [], []
    kkt_at = STEP_NAMES[1].index("qp_kkt")
    for _ in range(steps):
        out = mpc.rti_function(x, qf, tau, z, lx, lg)
        u = np.array(out[0]).ravel()
        z, lx, lg = (np.array(v).ravel() for v in out[1:4])
        us.append(u)
        kkt.append(float(out[kkt_at]))
        x = np.asarray(rk4(x, u, tau, mpc.dt)).ravel()
    return {"u": np.array(us), "x": x, "kkt": kkt}


@pytest.mark.parametrize("craft", ["demo", "rate_bound"])
def test_pqp_step_flies_daqps_loop(craft, tmp_path):
    """From a random start, 60 RTI steps at horizon 8: the same torques
    as with DAQP (1e-9 of m_max), every QP point certified (KKT ≤ 1e-8);
    with a rate bound the rate rows go through the wrapper too."""
    sc = load_spacecraft("demo")
    rate_max = None if craft == "demo" else 0.02
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    x0 = random_states(model, 1, np.random.default_rng(3))[0]
    runs = {q: _loop(AttitudeMPC(model, horizon=8, dt=0.5,
                                 solver="condensed", rti=True,
                                 rate_max=rate_max, qp_solver=q), x0, 60)
            for q in ("daqp", "pqp")}
    m_max = float(np.max(sc.wheels.m_max))
    assert np.max(np.abs(runs["pqp"]["u"] - runs["daqp"]["u"])) <= 1e-9 * m_max
    assert max(runs["pqp"]["kkt"]) <= 1e-8
    # the loop was constrained: some torque at its bound
    assert np.max(np.abs(runs["pqp"]["u"])) >= 0.999 * m_max


def test_pqp_step_from_a_rate_beyond_its_bound():
    """Measured rates beyond the rate bound (0.022 > 0.02 rad/s): the
    shifted plan breaks rate rows, so each QP of the first steps starts
    with phase one. Uncapped, the step flies DAQP's loop (1e-9 of
    m_max); capped at 8, every step is certified and the rates come back
    within the bound."""
    from ocp.mpc.condensed import qp_factor_function

    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    axis = np.array([0.6, 0.0, 0.8])
    x0 = np.r_[np.cos(0.5), np.sin(0.5) * axis, 0.022, -0.008, 0.004,
               np.zeros(4)]
    runs = {}
    for name, qp, opts in (("daqp", "daqp", {}), ("pqp", "pqp", {}),
                           ("capped", "pqp", {"qp_max_iter": 8})):
        mpc = AttitudeMPC(model, horizon=8, dt=0.5, solver="condensed",
                          rti=True, rate_max=0.02, qp_solver=qp,
                          solver_options=opts)
        runs[name] = _loop(mpc, x0, 40)
    out = qp_factor_function(mpc)(mpc.initial_guess(x0),
                                  np.r_[x0, 1.0, 0.0, 0.0, 0.0, np.zeros(3)])
    assert np.any(np.array(out[6]) < 0)         # y = 0 breaks a rate row
    m_max = float(np.max(sc.wheels.m_max))
    assert np.max(np.abs(runs["pqp"]["u"] - runs["daqp"]["u"])) <= 1e-9 * m_max
    for r in runs.values():
        assert max(r["kkt"]) <= 1e-8
        assert np.max(np.abs(r["x"][4:7])) <= 0.02 + 1e-8


def test_generated_step_calls_the_external(tmp_path):
    """The step's generated C declares and calls the pqp external."""
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    mpc = AttitudeMPC(model, horizon=5, dt=0.5, solver="condensed",
                      rti=True, qp_solver="pqp")
    name = external_name(5 * sc.wheels.n_wheels, 5 * 2 * sc.wheels.n_wheels)
    cg = ca.CodeGenerator("step.c")
    cg.add(mpc.rti_function)
    text = cg.dump()
    assert f"int {name}(const casadi_real** arg" in text
    assert f"{name}(arg" in text


def test_wrapper_text_is_the_rows_layout():
    """The wrapper's sparsity of G is the step's, and its sizes are the
    QP's: n = N·n_u variables, m = N·h rows."""
    text = wrapper_source(2, 2, 2, ca.Sparsity.dense(12, 4), 50)
    assert "#define N_VAR 4" in text and "#define M_ROWS 12" in text
    assert "#define H_ROWS 6" in text and ", 50," in text


def test_pqp_is_for_the_condensed_step_only():
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    with pytest.raises(SolverNotFound):
        AttitudeMPC(model, horizon=5, dt=0.5, solver="sqpmethod",
                    qp_solver="pqp")


def _posed_qp() -> dict:
    """A QP the step poses (`qp_factor_function`, a saturating slew's
    first plan, horizon 5), its rows G stage by stage as the external
    takes them."""
    from ocp.mpc.condensed import qp_factor_function

    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    mpc = AttitudeMPC(model, horizon=5, dt=0.5, solver="condensed",
                      rti=True)
    x = random_states(model, 1, np.random.default_rng(0))[0]
    z = mpc.initial_guess(x)
    winv, rows, g, lbu, ubu, lba, uba = (
        np.array(v) for v in qp_factor_function(mpc)(
            z, np.r_[x, 1.0, 0.0, 0.0, 0.0, np.zeros(3)]))
    n, na = winv.shape[0], rows.shape[0]
    N, nu = 5, sc.wheels.n_wheels
    h = (n + na) // N
    G = np.zeros((n + na, n))
    for k in range(N):
        G[k * h:k * h + nu] = winv[k * nu:(k + 1) * nu]
        G[k * h + nu:(k + 1) * h] = rows[k * (h - nu):(k + 1) * (h - nu)]
    return {"N": N, "nu": nu, "G": G, "A": np.vstack([winv, rows]),
            "args": [winv.T @ g.ravel(), ca.DM(G), lbu.ravel(), ubu.ravel(),
                     lba.ravel(), uba.ravel(), np.zeros(n), np.zeros(na)]}


def _daqp(q: dict, args: list) -> np.ndarray:
    import daqp

    n = q["A"].shape[1]
    lo, hi = np.r_[args[2], args[4]], np.r_[args[3], args[5]]
    ref, _, flag, _ = daqp.solve(np.eye(n), np.ravel(args[0]), q["A"], hi,
                                 lo, np.zeros(len(lo), dtype=np.int32))
    assert flag == 1
    return ref


def test_external_solves_the_posed_qp():
    """The external's y is DAQP's optimum; capped at one iteration, a
    feasible point of lower cost than y = 0, flagged."""
    from ocp.mpc.primal_qp import qp_external

    q = _posed_qp()
    N, nu, args, A = q["N"], q["nu"], q["args"], q["A"]
    lo, hi = np.r_[args[2], args[4]], np.r_[args[3], args[5]]
    ref = _daqp(q, args)
    ext = qp_external(N, nu, nu, ca.DM(q["G"]).sparsity(), 1000)
    y, lam_u, lam_a, lam, infeasible, capped, moved = (
        np.array(v).ravel() for v in ext(*args))
    assert (infeasible[0], capped[0], moved[0]) == (0, 0, 0)
    assert np.max(np.abs(y - ref)) <= 1e-9
    assert np.count_nonzero(lam) > 0            # a bound was active
    one = qp_external(N, nu, nu, ca.DM(q["G"]).sparsity(), 1)
    y1, *_, infeasible, capped, moved = (np.array(v).ravel()
                                         for v in one(*args))
    assert (infeasible[0], capped[0], moved[0]) == (0, 1, 0)
    assert np.all(A @ y1 <= hi + 1e-12) and np.all(A @ y1 >= lo - 1e-12)
    assert 0.5 * y1 @ y1 + args[0] @ y1 < 0.0      # below the start's


def test_external_phase_one_from_a_start_that_breaks_bounds():
    """Bounds that y = 0 breaks (δu ≥ 1e-3 at the first stage, as a
    defect would): phase one moves the start onto them and the primal
    phase reaches DAQP's optimum of that QP, flagged ``moved``; capped
    at 8 iterations it ends feasible. Bounds that no point keeps: flagged
    infeasible, y = 0 and no multipliers."""
    from ocp.mpc.primal_qp import qp_external

    q = _posed_qp()
    N, nu, A = q["N"], q["nu"], q["A"]
    bad = list(q["args"])
    bad[2] = bad[2].copy()
    bad[2][:nu] = 1e-3
    ref = _daqp(q, bad)
    sp = ca.DM(q["G"]).sparsity()
    y, *_, infeasible, capped, moved = (np.array(v).ravel() for v in
                                        qp_external(N, nu, nu, sp,
                                                    1000)(*bad))
    assert (infeasible[0], capped[0], moved[0]) == (0, 0, 1)
    assert np.max(np.abs(y - ref)) <= 1e-9
    y2, *_, infeasible, capped, moved = (np.array(v).ravel() for v in
                                         qp_external(N, nu, nu, sp,
                                                     8)(*bad))
    assert (infeasible[0], moved[0]) == (0, 1)
    lo, hi = np.r_[bad[2], bad[4]], np.r_[bad[3], bad[5]]
    assert np.all(A @ y2 <= hi + 1e-12) and np.all(A @ y2 >= lo - 1e-12)
    bad[3] = bad[3].copy()
    bad[3][0] = 5e-4                            # 1e-3 ≤ δu_0 ≤ 5e-4
    y, *_, lam, infeasible, capped, moved = (
        np.array(v).ravel() for v in qp_external(N, nu, nu, sp,
                                                 1000)(*bad))
    assert (infeasible[0], capped[0], moved[0]) == (1, 0, 1)
    assert not np.any(y) and not np.any(lam)


def test_threads_build_and_share_the_solver(tmp_path, monkeypatch):
    """Four threads building controllers of a new QP size at once (each
    compiles into its own file, one rename wins) and then stepping the
    same controller: same answers as one thread alone."""
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)

    def build(_):
        return AttitudeMPC(model, horizon=3, dt=0.5, solver="condensed",
                           rti=True, qp_solver="pqp")

    with ThreadPoolExecutor(4) as pool:
        a, *_ = pool.map(build, range(4))
    assert len(list(tmp_path.rglob("libadcs_pqp_12x24.so"))) == 1
    x0s = random_states(model, 8, np.random.default_rng(5))
    alone = [_loop(a, x0, 10)["u"] for x0 in x0s]
    with ThreadPoolExecutor(4) as pool:
        shared = list(pool.map(lambda x0: _loop(a, x0, 10)["u"], x0s))
    for u1, u2 in zip(alone, shared):
        assert np.array_equal(u1, u2)


def test_no_compiler_is_the_toolboxs_error(tmp_path, monkeypatch):
    """Without a C compiler, qp_solver='pqp' says so (CompilerNotFound,
    a toolbox error), not a traceback from inside CasADi."""
    import tempfile

    from adcs_common.codegen import CompilerNotFound

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.delenv("CC", raising=False)
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    with pytest.raises(CompilerNotFound):
        AttitudeMPC(model, horizon=4, dt=0.5, solver="condensed", rti=True,
                    qp_solver="pqp")


def test_capped_step_applies_feasible_descent_points():
    """Capped at five QP iterations (``qp_max_iter``), the RTI loop
    applies the capped points: each flagged (``qp_capped``), certified as
    a feasible descent (≤ 1e-8), within every bound, and the loop still
    reaches the target; `AttitudeMPC.step` says ``":qp_capped"``."""
    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    x0 = random_states(model, 1, np.random.default_rng(3))[0]
    mpc = AttitudeMPC(model, horizon=8, dt=0.5, solver="condensed",
                      rti=True, qp_solver="pqp",
                      solver_options={"qp_max_iter": 5})
    f = mpc.rti_function
    names = [f.name_out(i) for i in range(f.n_out())]
    assert names[-2:] == ["qp_kkt", "qp_capped"]
    rk4 = model.rk4_step(1)
    qf, tau = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3)
    x, capped, statuses = x0.copy(), 0, set()
    for _ in range(80):
        res = mpc.step(x, qf)
        statuses.add(res.status)
        assert res.qp_kkt <= 1e-8 and res.first_violation <= 1e-9
        x = np.asarray(rk4(x, res.u, tau, mpc.dt)).ravel()
        capped += res.status.endswith(":qp_capped")
    assert capped >= 5 and statuses <= {"rti_step", "rti_step:qp_capped"}
    assert 2 * np.arccos(min(1.0, abs(x[0]))) <= 1e-3


def test_capped_certificate_checks_feasibility_and_descent():
    """`capped_residual`: 0 at a feasible point below the start's cost;
    a bound broken by 0.3 (scale 1 + 2) gives 0.1; a cost rise of 1.5
    (relative to 1 + |g|² = 2) gives 0.75."""
    from ocp.mpc.condensed_qp import capped_residual

    g = np.array([-1.0, 0.0])
    lo, hi = -2 * np.ones(2), 2 * np.ones(2)
    none = np.zeros(0)

    def cert(y, v):
        return float(capped_residual(y, g, v, none, lo, hi, none, none))

    assert cert(np.array([1.0, 0.0]), np.array([1.0, 0.0])) == 0.0
    assert abs(cert(np.array([1.0, 0.0]), np.array([2.3, 0.0])) - 0.1) \
        <= 1e-15
    assert abs(cert(np.array([-1.0, 0.0]), np.zeros(2)) - 0.75) <= 1e-15


@pytest.mark.parametrize("qp, cap", [("daqp", 5), ("pqp", 0),
                                     ("pqp", 2.5), ("pqp", True)])
def test_qp_max_iter_is_checked(qp, cap):
    """A cap for DAQP (a capped dual point breaks bounds) or one that is
    not a positive int is refused, naming the option."""
    from adcs_common.exceptions import InvalidValueError

    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    with pytest.raises(InvalidValueError, match="qp_max_iter"):
        AttitudeMPC(model, horizon=4, dt=0.5, solver="condensed", rti=True,
                    qp_solver=qp, solver_options={"qp_max_iter": cap})


CRAFT_TOML = """
name = "toml-craft"
inertia = [[4.0, 0.1, 0.0], [0.1, 3.0, -0.05], [0.0, -0.05, 5.0]]

[wheels]
pyramid = { delta_deg = 50.0, gamma_deg = 30.0 }
h_max = 0.15   # N·m·s
m_max = 0.03   # N·m
"""


def test_pqp_flies_a_toml_craft(tmp_path):
    """On a craft of the user's own (a TOML file, other inertia, wheel
    angles and limits), the pqp step flies DAQP's closed loop (states to
    1e-9) and, capped at 8, reaches the target within every bound."""
    from ocp import quat_from_axis_angle
    from ocp.mpc import simulate_mpc

    path = tmp_path / "craft.toml"
    path.write_text(CRAFT_TOML)
    sc = load_spacecraft(path)
    qf = quat_from_axis_angle([1.0, -1.0, 0.5], np.deg2rad(90.0))
    runs = {}
    for name, qp, opts in (("daqp", "daqp", {}), ("pqp", "pqp", {}),
                           ("capped", "pqp", {"qp_max_iter": 8})):
        mpc = AttitudeMPC(sc, horizon=10, dt=0.5, solver="condensed",
                          rti=True, qp_solver=qp, solver_options=opts)
        runs[name] = simulate_mpc(mpc, [1, 0, 0, 0], qf, t_final=50.0)
    check_toml_runs(runs, "pqp")


def check_toml_runs(runs: dict, name: str) -> None:
    """``runs[name]`` flies ``runs["daqp"]``'s states to 1e-9, and every
    run reaches the target within every bound."""
    a, b = runs[name].trajectory, runs["daqp"].trajectory
    assert np.max(np.abs(np.c_[a.q, a.w] - np.c_[b.q, b.w])) <= 1e-9
    for r in runs.values():
        assert r.final_error < np.deg2rad(0.01)
        assert r.momentum_violation <= 1e-9 and r.torque_violation <= 1e-9


@pytest.mark.parametrize("kw", [
    {"condensed_qp_plugin": "pqpx"}, {"condensed_qp_plugin": "PQP"},
    {"condensed_qp_plugin": "pqp", "condensed_qp_max_iter": 0},
    {"condensed_qp_plugin": "daqp", "condensed_qp_max_iter": 8},
    {"condensed_qp_plugin": "pqp", "condensed_qp_max_iter": 8,
     "mpc_variants": ("mpc_step",)}])
def test_export_refuses_a_bad_condensed_qp(tmp_path, kw):
    """`export_c` answers an unknown condensed QP, a cap below 1, a cap
    for DAQP or one no exported step takes with the toolbox's error,
    before generating anything."""
    from adcs_common.exceptions import InvalidValueError
    from ocp.codegen.export import export_c

    kw = {"mpc_variants": ("mpc_cond_rti_step",), **kw}
    with pytest.raises(InvalidValueError):
        export_c(tmp_path / "out", spacecraft="demo", horizon=4, **kw)
    assert not (tmp_path / "out" / "adcs_codegen.c").exists()


def test_shift_tail_keeps_the_momentum_bound():
    """`momentum_safe_tail`: the shifted plan's repeated last torque is
    clipped so that H_N + dt·s·u stays within ±h_max, s the wheels'
    scale factors (a failed wheel's torque stays 0); torques that keep
    it are left alone (on an array with scale errors and a failure)."""
    from allocation import WheelArray
    from ocp.mpc.condensed import momentum_safe_tail

    sc = load_spacecraft("demo")
    wheels = WheelArray(sc.wheels.axes, sc.wheels.h_max, sc.wheels.m_max,
                        failed=(3,), scale=[1.1, 0.9, 1.0, 1.0])
    model = rigid_spacecraft(sc.inertia, wheels)
    mpc = AttitudeMPC(model, horizon=4, dt=0.5, solver="condensed",
                      rti=True, qp_solver="pqp")
    zs = ca.MX.sym("z", mpc.nz)
    tail = ca.Function("tail", [zs], [momentum_safe_tail(mpc, zs)])
    z = np.zeros(mpc.nz)
    h0 = mpc._xs[-2].start + 7
    u0 = mpc._us[-1].start
    z[h0:h0 + 4] = [0.19, -0.195, 0.0, 0.0]
    z[u0:u0 + 4] = [0.04, -0.04, 0.03, 0.0]
    out = np.array(tail(z)).ravel()
    s, dt = np.array([1.1, 0.9, 1.0, 0.0]), 0.5
    u = out[u0:u0 + 4]
    assert np.allclose(u, [(0.2 - 0.19) / (dt * 1.1),
                           (-0.2 + 0.195) / (dt * 0.9), 0.03, 0.0],
                       rtol=0, atol=1e-15)
    assert np.all(np.abs(z[h0:h0 + 4] + dt * s * u) <= 0.2 + 1e-15)
    assert np.array_equal(np.delete(out, np.s_[u0:u0 + 4]),
                          np.delete(z, np.s_[u0:u0 + 4]))


def test_wrapper_rows_end_one_after_another():
    """The wrapper reverses G's columns within each stage and orders its
    rows by where they end (`primal_qp._row_order`): on a step's QP,
    W⁻¹'s diagonal blocks are upper triangular, so a stage's bound row i
    and its wheel i's momentum row end n_u − i columns into the stage;
    the rows' ends never decrease, which keeps the warm start's
    reflections short (pqp.c, warm_factor)."""
    from ocp.mpc.condensed import qp_factor_function
    from ocp.mpc.primal_qp import _row_order

    sc = load_spacecraft("demo")
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    N, nu = 5, model.nu
    nw = sc.wheels.n_wheels
    mpc = AttitudeMPC(model, horizon=N, dt=0.5, solver="condensed",
                      rti=True)
    x0 = random_states(model, 1, np.random.default_rng(4))[0]
    z = np.random.default_rng(5).normal(size=mpc.nz) * 0.1
    winv, rows = (np.array(v) for v in qp_factor_function(mpc)(
        z, np.r_[x0, 1.0, 0, 0, 0, 0, 0, 0])[:2])
    h = nu + nw
    G = np.vstack([np.vstack([winv[s * nu:(s + 1) * nu],
                              rows[s * nw:(s + 1) * nw]]) for s in range(N)])
    sp = ca.kron(ca.DM(ca.Sparsity.lower(N), 1.0),
                 ca.DM.ones(h, nu)).sparsity()
    order, at, length = _row_order(N, nu, nw, h, sp)
    assert [order[at[r]] for r in range(N * h)] == list(range(N * h))
    col = [c // nu * nu + nu - 1 - c % nu for c in range(N * nu)]
    C = G[order][:, col]
    ends = [int(np.flatnonzero(c)[-1]) + 1 for c in C]
    assert all(e <= n for e, n in zip(ends, length))
    assert ends == sorted(ends)
    for s in range(N):
        for i in range(nu):
            assert ends[at[s * h + i]] == s * nu + nu - i
        for w in range(nw):
            assert ends[at[s * h + nu + w]] == s * nu + nu - w
