"""Duty-cycle QP (theory §2): backends vs an exact KKT reference.

Also the closed forms of eqs. (2), (8)-(9) vs the QP, the momentum bound
and the min on-time carry.
"""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from thrusters import (
    DutyCycleAllocator,
    InfeasibleError,
    InvalidValueError,
    MinOnTimeCarry,
    ShapeError,
    SolverNotFound,
    available_solvers,
    reorientation_law,
    six_thruster_unit,
    unloading_law,
)

UNIT = six_thruster_unit()
H_MAX = 0.012
#: Every backend the package offers; those not installed skip visibly.
OFFERED = ("osqp", "daqp", "casadi:qrqp", "casadi:osqp", "casadi-c:qrqp",
           "qpsolvers:clarabel", "qpsolvers:daqp", "qpsolvers:piqp",
           "qpsolvers:quadprog")
SOLVERS = available_solvers()


def require(solver):
    """Skip (visibly) when ``solver`` is not available here."""
    if solver not in SOLVERS:
        pytest.skip(f"{solver} is not installed (pip install "
                    f"\"adcs-toolbox[solvers]\", or a C compiler)")
#: One tolerance for every backend, on the duties (the issue's 1e-6).
TOL = 1e-6


def reference(qp, theta):
    """Exact optimum of the canonical QP at ``theta``, certified.

    quadprog (Goldfarb–Idnani dual active set, exact, and not a backend
    the fast path uses) solves the QP; the answer is then certified here:
    feasible, stationary with multipliers of the right sign, and
    complementary. P is positive definite, so a KKT point is the unique
    optimum.
    """
    quadprog = pytest.importorskip("quadprog")
    q, l, u = qp.vectors(theta)
    ne = qp.n_eq
    up = qp.upper_rows.copy()
    lo = qp.lower_rows.copy()
    up[:ne] = lo[:ne] = False
    A = qp.A
    ub = np.minimum(qp.ub, 1e3)
    E = np.eye(qp.nx)
    # all inequalities as G x <= h
    G = np.vstack([A[up], -A[lo], E, -E])
    h = np.concatenate([u[up], -l[lo], ub, -qp.lb])
    Aeq, beq = A[:ne], l[:ne]
    C = np.vstack([Aeq, -G])                   # quadprog: C x >= b
    b = np.concatenate([beq, -h])
    x, _, _, _, lam, _ = quadprog.solve_qp(qp.P, -q, C.T, b, meq=ne)
    scale = 1.0 + np.linalg.norm(q) + np.linalg.norm(lam)
    assert np.all(G @ x <= h + 1e-9)
    assert np.allclose(Aeq @ x, beq, atol=1e-9)
    assert np.linalg.norm(qp.P @ x + q - C.T @ lam) < 1e-9 * scale
    assert np.all(lam[ne:] >= -1e-12 * scale)
    assert np.all(np.abs(lam[ne:] * (G @ x - h)) < 1e-9 * scale)
    return x


CASES = {
    # name: (cycle, tracking, bound, P_T, M, H, tau)
    "burn_interior": (10.0, "hard", "box", 0.739, (-0.0008, 0.0005),
                      (0.008, 0.0, -0.005), (0, 0, 0)),
    "hold_interior": (2.0, "hard", "box", 0.0, (0.002, -0.001),
                      (0.001, 0.0, 0.002), (0, 0, 0)),
    "bound_relaxed": (10.0, "hard", "box", 0.0, (0.01, -0.004),
                      (0, 0, 0), (0, 0, 0)),
    "weighted_active_bound": (10.0, "weighted", "box", 0.739,
                              (0.004, 0.0), (0.01, 0.0, 0.0),
                              (0.0012, 0, 0)),
    "weighted_norm_bound": (10.0, "weighted", "norm", 0.5, (0.003, 0.002),
                            (0.009, 0.0, 0.006), (0, 0, 0)),
    "weighted_reorient": (2.0, "weighted", "box", 0.0, (0.2, -0.1),
                          (0.0, 0.0, 0.0), (0, 0, 0)),
}


@pytest.mark.parametrize("solver", OFFERED)
@pytest.mark.parametrize("case", sorted(CASES))
def test_every_backend_matches_exact_reference(solver, case):
    require(solver)
    T, tracking, bound, P_T, M, H, tau = CASES[case]
    alloc = DutyCycleAllocator(UNIT, T, H_MAX, solver=solver,
                               tracking=tracking, bound=bound)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = alloc.solve(P_T, M, H, tau)
    x_ref = reference(alloc.qp, alloc.theta(P_T, M, H, tau))
    assert res.success, res.status
    np.testing.assert_allclose(res.duty, x_ref[:-1], atol=TOL)
    assert res.momentum_excess == pytest.approx(x_ref[-1] * H_MAX,
                                                abs=TOL * H_MAX)
    assert np.all((res.duty >= 0) & (res.duty <= 1))


def test_cases_exercise_the_statuses():
    statuses = {}
    for name, (T, tracking, bound, P_T, M, H, tau) in CASES.items():
        alloc = DutyCycleAllocator(UNIT, T, H_MAX, tracking=tracking,
                                   bound=bound)
        statuses[name] = alloc.solve(P_T, M, H, tau).status
    assert statuses["bound_relaxed"] == "bound_relaxed"
    assert statuses["burn_interior"] == "optimal"
    assert statuses["weighted_active_bound"] == "optimal"


@pytest.mark.parametrize("solver", ["osqp", "casadi:qrqp", "daqp"])
def test_qp_equals_eq2_in_the_interior(solver):
    H = np.array([0.009, 0.0, -0.006])
    law = unloading_law(UNIT, 0.739, H, 10.0, 1.0)
    alloc = DutyCycleAllocator(UNIT, 10.0, H_MAX, solver=solver)
    res = alloc.solve(0.739, law.demand[1:], H)
    assert law.status == "ok" and res.status == "optimal"
    np.testing.assert_allclose(res.duty, law.duty, atol=1e-8)


@pytest.mark.parametrize("solver", ["osqp", "casadi:qrqp", "quadprog"])
def test_qp_equals_eq8_9_in_the_interior(solver):
    alloc = DutyCycleAllocator(UNIT, 2.0, H_MAX, solver=solver)
    for M in [(0.002, -0.001), (-0.003, 0.0), (0.0, 0.004)]:
        law = reorientation_law(UNIT, 0.0, M)
        res = alloc.solve(0.0, M, (0.0, 0.0, 0.0))
        np.testing.assert_allclose(res.duty, law.duty, atol=1e-8)


def test_where_eq2_must_clip_the_qp_keeps_the_momentum_bound():
    P_T, T = 1.40, 10.0
    # H_X chosen so that eq. (2) asks for k3 = 1.004 (clipped to 1)
    k3_0 = unloading_law(UNIT, P_T, [0, 0, 0], T).duty_unclipped[2]
    slope = unloading_law(UNIT, P_T, [1, 0, 0], T).duty_unclipped[2] - k3_0
    hx = (1.004 - k3_0) / slope
    law = unloading_law(UNIT, P_T, [hx, 0, 0], T, 1.0)
    assert law.status == "clipped"
    H = np.array([hx, 0.0, 0.0])
    law_after = H + T * (UNIT.torque_matrix() @ law.duty)
    alloc = DutyCycleAllocator(UNIT, T, H_MAX, tracking="weighted")
    res = alloc.solve(P_T, law.demand[1:], H)
    assert res.status == "optimal"
    assert np.all(np.abs(res.momentum_after[[0, 2]]) <= H_MAX + 1e-9)
    assert res.achieved[0] == pytest.approx(P_T, abs=1e-9)
    # the clipped law misses its thrust; the QP does not
    assert abs(law.error[0]) > 1e-3
    assert np.all(np.isfinite(law_after))


def test_infeasible_thrust_demand_returns_status_not_nan():
    alloc = DutyCycleAllocator(UNIT, 10.0, H_MAX)
    res = alloc.solve(5.0)                     # > 3 x 0.5 N
    assert res.status == "infeasible" and not res.success
    assert np.all(res.duty == 0.0) and np.all(np.isfinite(res.duty))
    with pytest.raises(InfeasibleError):
        alloc.duty(5.0)


def test_infeasible_momentum_bound_is_relaxed_and_reported():
    alloc = DutyCycleAllocator(UNIT, 10.0, H_MAX, tracking="weighted")
    # |M_X| <= 2 x 0.108 N·m at most: 3 N·m·s cannot be unloaded in 10 s
    res = alloc.solve(0.739, (0.0, 0.0), (3.0, 0.0, 0.0))
    assert res.status == "bound_relaxed" and res.success
    assert res.momentum_excess > 0.5
    assert np.all(np.isfinite(res.duty))
    assert res.momentum_after[0] == pytest.approx(H_MAX + res.momentum_excess)


def test_propellant_is_the_cost():
    alloc = DutyCycleAllocator(UNIT, 2.0, H_MAX)
    res = alloc.solve(0.0, (0.002, 0.001))
    assert res.propellant == pytest.approx(
        2.0 * np.sum(res.duty * UNIT.propellant_rate()))
    # an opposed pair never fires together (it would waste propellant)
    for i, j in UNIT.pairs:
        assert min(res.duty[i], res.duty[j]) < 1e-9


FEAS_CACHE = {}


def momentum_feasible(P_T, H, tau, T):
    """Tell (LP) if some k in [0,1]^6 gives P_T and |H+| <= h_max."""
    F = UNIT.force_matrix()[1]
    Mt = UNIT.torque_matrix()[[0, 2]]
    shift = np.array([H[0], H[2]]) + T * np.array([tau[0], tau[2]])
    A_ub = np.vstack([T * Mt, -T * Mt])
    b_ub = np.concatenate([H_MAX - shift, H_MAX + shift])
    r = linprog(np.zeros(6), A_ub=A_ub, b_ub=b_ub, A_eq=F[None],
                b_eq=[P_T], bounds=[(0, 1)] * 6, method="highs")
    return r.status == 0


ALLOC_W = DutyCycleAllocator(UNIT, 10.0, H_MAX, tracking="weighted")
ALLOC_R = DutyCycleAllocator(UNIT, 2.0, H_MAX, tracking="weighted",
                             solver="daqp")


@settings(max_examples=80, deadline=None)
@given(st.floats(-1.4, 1.4), st.floats(-0.05, 0.05), st.floats(-0.05, 0.05),
       st.floats(-0.03, 0.03), st.floats(-0.03, 0.03),
       st.floats(-0.002, 0.002))
def test_property_duty_bounds_and_momentum_bound_when_feasible(
        P_T, mx, mz, hx, hz, tx):
    H, tau = (hx, 0.0, hz), (tx, 0.0, 0.0)
    res = ALLOC_W.solve(P_T, (mx, mz), H, tau)
    assert res.success
    assert np.all((res.duty >= 0) & (res.duty <= 1))
    assert res.achieved[0] == pytest.approx(P_T, abs=1e-7)
    if momentum_feasible(P_T, H, tau, 10.0):
        assert res.status == "optimal"
        assert np.all(np.abs(res.momentum_after[[0, 2]]) <= H_MAX + 1e-8)
    else:
        assert res.status == "bound_relaxed"


@settings(max_examples=60, deadline=None)
@given(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(-0.01, 0.01),
       st.floats(-0.01, 0.01))
def test_property_reorientation_net_thrust_zero(mx, mz, hx, hz):
    res = ALLOC_R.solve(0.0, (mx, mz), (hx, 0.0, hz))
    assert res.success
    assert np.all((res.duty >= 0) & (res.duty <= 1))
    assert abs(UNIT.force_matrix()[1] @ res.duty) < 1e-8


def test_unknown_solver_lists_installed_and_extra():
    with pytest.raises(SolverNotFound) as err:
        DutyCycleAllocator(UNIT, 10.0, H_MAX, solver="gurobi_magic")
    msg = str(err.value)
    assert "osqp" in msg and 'pip install "adcs-toolbox[solvers]"' in msg
    assert err.value.name == "gurobi_magic"
    assert isinstance(err.value, ValueError)


def test_installed_but_not_offered_backend_says_so():
    import qpsolvers
    if "proxqp" not in qpsolvers.available_solvers:
        pytest.skip("proxqp not installed")
    with pytest.raises(SolverNotFound, match="installed but not offered"):
        DutyCycleAllocator(UNIT, 10.0, H_MAX, solver="proxqp")


def test_unknown_kwarg_rejected():
    with pytest.raises(TypeError):
        DutyCycleAllocator(UNIT, 10.0, H_MAX, sovler="osqp")


@pytest.mark.parametrize("kwargs, name", [
    (dict(cycle=0.01), "cycle"),
    (dict(h_max=-0.01), "h_max"),
    (dict(h_max=np.nan), "h_max"),
    (dict(tracking="soft"), "tracking"),
    (dict(bound="ball"), "bound"),
    (dict(bound="norm", n_facets=2), "n_facets"),
    (dict(torque_weight=-1.0), "torque_weight"),
])
def test_bad_allocator_arguments(kwargs, name):
    args = dict(cycle=10.0, h_max=H_MAX)
    args.update(kwargs)
    with pytest.raises(InvalidValueError, match=name):
        DutyCycleAllocator(UNIT, args.pop("cycle"), args.pop("h_max"),
                           **args)


@pytest.mark.parametrize("args, name, exc", [
    ((np.nan,), "P_T", InvalidValueError),
    ((0.0, (0.1, np.inf)), "M", InvalidValueError),
    ((0.0, (0.1, 0.2, 0.3)), "M", ShapeError),
    ((0.0, (0.1, 0.2), (0.0, 0.0)), "H", ShapeError),
    ((0.0, (0.1, 0.2), (0, 0, 0), (0, np.nan, 0)), "tau_dist",
     InvalidValueError),
])
def test_bad_demands_name_the_argument(args, name, exc):
    alloc = DutyCycleAllocator(UNIT, 10.0, H_MAX)
    with pytest.raises(exc, match=name):
        alloc.solve(*args)


def test_min_on_time_carry_conserves_impulse():
    carry = MinOnTimeCarry(UNIT, 2.0)
    rng = np.random.default_rng(0)
    demanded = rng.uniform(0, 0.02, size=(200, 6)) * (rng.random(
        (200, 6)) < 0.5)
    demanded[:, 3:] = 0.0                       # one group: no netting
    cmd = np.array([carry.apply(k) for k in demanded])
    on = cmd * 2.0
    assert np.all((on == 0) | (on >= UNIT.min_on_time - 1e-15))
    np.testing.assert_allclose(cmd.sum(0) + carry.carry, demanded.sum(0),
                               atol=1e-12)
    assert np.all(np.abs(carry.carry) <= 0.5 * carry.min_duty + 1e-15)


def test_min_on_time_carry_nets_opposed_pairs():
    carry = MinOnTimeCarry(UNIT, 2.0)
    kmin = carry.min_duty
    cmd = carry.apply([0.3 * kmin, 0, 0, 0.2 * kmin, 0, 0])   # D1 vs D4
    assert np.all(cmd == 0)
    np.testing.assert_allclose(carry.carry[[0, 3]], [0.1 * kmin, 0.0])


def test_min_on_time_carry_rejects_bad_duty_and_short_cycle():
    with pytest.raises(InvalidValueError, match="cycle"):
        MinOnTimeCarry(UNIT, 0.01)
    with pytest.raises(InvalidValueError, match="duty"):
        MinOnTimeCarry(UNIT, 2.0).apply([np.nan] * 6)


def test_casadi_function_for_codegen_matches_allocator():
    alloc = DutyCycleAllocator(UNIT, 2.0, H_MAX, tracking="weighted",
                               solver="daqp")
    f = alloc.casadi_function()
    th = alloc.theta(0.0, (0.003, -0.001), (0.005, 0.0, 0.002))
    x, viol = f(th, np.ones(6))
    assert float(viol) < 1e-9
    np.testing.assert_allclose(np.array(x).ravel()[:-1],
                               alloc.solve_theta(th).duty, atol=1e-8)
    assert f.name_in() == ["theta", "kmax"]


@pytest.mark.parametrize("solver", OFFERED)
def test_set_pressure_equals_a_unit_built_at_that_pressure(solver):
    require(solver)
    unit = six_thruster_unit(thrust_offset=0.1)
    low = 7.0 * 98066.5
    built = DutyCycleAllocator(unit.with_pressure(low), 10.0, H_MAX,
                               solver="daqp")
    moved = DutyCycleAllocator(unit, 10.0, H_MAX, solver=solver)
    moved.set_pressure(low)
    assert moved.pressure == low
    for P_T, M, H in [(0.6, (-0.0005, 0.0003), (0.005, 0, -0.003)),
                      (0.0, (0.0008, -0.0005), (0.0, 0.0, 0.0))]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            a = built.solve(P_T, M, H)
            b = moved.solve(P_T, M, H)
        assert a.status == b.status == "optimal"
        np.testing.assert_allclose(b.duty, a.duty, atol=TOL)
        np.testing.assert_allclose(b.achieved, a.achieved, atol=1e-9)
    # a demand the lower pressure cannot meet (> 3 x 0.4 N at 7 kgf/cm²)
    assert moved.solve(1.3).status == "infeasible"


def test_set_pressure_rejects_bad_values():
    alloc = DutyCycleAllocator(UNIT, 10.0, H_MAX)
    with pytest.raises(InvalidValueError, match="pressure"):
        alloc.set_pressure(-1.0)
    with pytest.raises(InvalidValueError, match="pressure"):
        alloc.set_pressure(np.nan)


ALLOC_N = DutyCycleAllocator(UNIT, 10.0, H_MAX, tracking="weighted",
                             bound="norm", n_facets=12, solver="daqp")


@settings(max_examples=50, deadline=None)
@given(st.floats(0.1, 1.2), st.floats(-0.05, 0.05), st.floats(-0.05, 0.05),
       st.floats(-0.008, 0.008), st.floats(-0.008, 0.008))
def test_property_norm_bound_keeps_momentum_in_the_circle(P_T, mx, mz, hx,
                                                          hz):
    res = ALLOC_N.solve(P_T, (mx, mz), (hx, 0.0, hz))
    assert res.status == "optimal"      # |H| < h_max cos(pi/12) at start
    # the 12-gon is inscribed: inside it means inside the circle
    assert np.hypot(*res.momentum_after[[0, 2]]) <= H_MAX + 1e-9


def test_offered_list_matches_available_here():
    # every name the package lists is one the tests cover
    assert set(SOLVERS) <= set(OFFERED)


# fast path (duty_fast): one buffer trigger, checked, falls back --------------
FAST_CONFIGS = [(2.0, "weighted", "box"), (2.0, "weighted", "norm"),
                (10.0, "hard", "box"), (2.0, "hard", "norm")]


def random_cycles(rng, n):
    """Random demands: burns and holds, momentum inside the bound."""
    for i in range(n):
        P_T = 0.0 if i % 2 else rng.uniform(0.0, 1.0)
        yield (P_T, rng.uniform(-0.004, 0.004, 2),
               np.array([rng.uniform(-0.01, 0.01), 0.0,
                         rng.uniform(-0.01, 0.01)]),
               rng.uniform(-1e-5, 1e-5, 3))


@pytest.mark.parametrize("T,tracking,bound", FAST_CONFIGS)
def test_duty_fast_matches_exact_reference_on_random_cycles(T, tracking,
                                                            bound):
    alloc = DutyCycleAllocator(UNIT, T, H_MAX, solver="daqp",
                               tracking=tracking, bound=bound, n_facets=12)
    rng = np.random.default_rng(7)
    checked = 0
    for P_T, M, H, tau in random_cycles(rng, 60):
        try:
            slow = alloc.duty(P_T, M, H, tau)
        except InfeasibleError:
            with pytest.raises(InfeasibleError):
                alloc.duty_fast(P_T, M, H, tau)
            continue
        fast = alloc.duty_fast(P_T, M, H, tau)
        x_ref = reference(alloc.qp, alloc.theta(P_T, M, H, tau))
        np.testing.assert_allclose(fast, x_ref[:-1], atol=TOL)
        np.testing.assert_allclose(fast, slow, atol=TOL)
        assert np.all((fast >= 0) & (fast <= 1))
        checked += 1
    assert checked >= 30
    # the buffer answered every feasible cycle, hard tracking included
    # (its equality rows are eliminated before DAQP sees the QP)
    assert alloc.fast_fallbacks == 60 - checked


def test_duty_fast_falls_back_when_the_check_fails():
    from thrusters.qp.casadi_functions import FastDuty

    alloc = DutyCycleAllocator(UNIT, 2.0, H_MAX, solver="daqp",
                               tracking="weighted")
    # DAQP's default primal_tol leaves points off by up to ~3e-5: the
    # check must catch them and solve() answer instead
    alloc._fast = FastDuty(alloc.qp, np.ones(6),
                           options={"daqp": {"primal_tol": 1e-6}})
    rng = np.random.default_rng(3)
    for P_T, M, H, tau in random_cycles(rng, 40):
        try:
            fast = alloc.duty_fast(P_T, M, H, tau)
        except InfeasibleError:
            continue
        x_ref = reference(alloc.qp, alloc.theta(P_T, M, H, tau))
        np.testing.assert_allclose(fast, x_ref[:-1], atol=TOL)
    assert alloc.fast_fallbacks > 0


def test_duty_fast_never_returns_nan_or_a_bad_demand():
    alloc = DutyCycleAllocator(UNIT, 10.0, H_MAX, solver="daqp",
                               tracking="weighted")
    with pytest.raises(InvalidValueError, match="P_T"):
        alloc.duty_fast(np.nan)
    with pytest.raises(InvalidValueError, match="H"):
        alloc.duty_fast(0.0, (0.0, 0.0), (np.inf, 0.0, 0.0))
    with pytest.raises(ShapeError):
        alloc.duty_fast(0.0, (0.0, 0.0, 0.0))
    with pytest.raises(InfeasibleError):
        alloc.duty_fast(5.0)            # beyond the thrusters
    assert alloc.fast_fallbacks == 4
    # the next good cycle goes through the buffer again, exactly
    out = np.full(6, np.nan)
    got = alloc.duty_fast(0.739, (-0.0008, 0.0005), (0.008, 0.0, -0.005),
                          out=out)
    assert got is out
    np.testing.assert_allclose(out, alloc.duty(0.739, (-0.0008, 0.0005),
                                               (0.008, 0.0, -0.005)),
                               atol=TOL)
    assert alloc.fast_fallbacks == 4


def test_duty_fast_follows_set_pressure():
    unit = six_thruster_unit(thrust_offset=0.1)
    alloc = DutyCycleAllocator(unit, 10.0, H_MAX, solver="daqp",
                               tracking="weighted")
    alloc.duty_fast(0.0)                 # Function built before the move
    alloc.set_pressure(7.0 * 98066.5)
    assert alloc._fast.kmax.min() < 1.0  # the buffer got the move
    for P_T, M, H in [(0.6, (-0.0005, 0.0003), (0.005, 0, -0.003)),
                      (0.0, (0.0008, -0.0005), (0.0, 0.0, 0.0))]:
        res = alloc.solve(P_T, M, H)
        assert res.status == "optimal"
        fast = alloc.duty_fast(P_T, M, H)
        np.testing.assert_allclose(fast, res.duty, atol=TOL)
        np.testing.assert_allclose(
            fast, reference(alloc.qp, alloc.theta(P_T, M, H))[:-1]
            / alloc._scale, atol=TOL)
    with pytest.raises(InfeasibleError):
        alloc.duty_fast(1.3)    # > 3 x 0.4 N at 7 kgf/cm²
    assert alloc.fast_fallbacks == 1


def test_duty_function_without_jit_gives_the_same_answer():
    from thrusters.qp.casadi_functions import duty_function

    alloc = DutyCycleAllocator(UNIT, 2.0, H_MAX, solver="daqp",
                               tracking="weighted")
    th = alloc.theta(0.0, (0.003, -0.001), (0.005, 0.0, 0.002))
    duty, _, check = duty_function(alloc.qp, jit=False)(th, np.ones(6))
    assert float(check) <= 1.0
    np.testing.assert_allclose(np.array(duty).ravel(), alloc.duty_fast(
        0.0, (0.003, -0.001), (0.005, 0.0, 0.002)), atol=1e-12)
    # a NaN parameter gives check = inf, never a NaN duty accepted
    th[0] = np.nan
    duty, _, check = duty_function(alloc.qp, jit=False)(th, np.ones(6))
    assert float(check) == np.inf
