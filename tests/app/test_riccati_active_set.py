"""The Riccati active set's twin (`benchmarks.riccati_active_set`) solves
the condensed step's QPs kept stage by stage: DAQP's optimum, multipliers
that satisfy the KKT conditions, a change at stage k refactoring stages
k…0 alone, dependent boxes held out, capped iterates feasible."""

from dataclasses import replace

import numpy as np
import pytest

from benchmarks.horizon_qps import collect
from benchmarks.riccati_active_set import (Dependent, StageQP, dense_qp,
                                           factor, forward, multipliers,
                                           solve)
from benchmarks.riccati_qps import feasible_start, main, run_daqp


@pytest.fixture(scope="module")
def loop():
    c = collect(horizon=5, draws=1, steps=12, seed=0, stagewise=True)
    c["posed"] = [q["stage"] for q in c["qps"] if feasible_start(q["stage"])]
    return c


def _kkt(qp: StageQP, r: dict) -> float:
    """Stationarity of the dense QP at the twin's answer with its
    multipliers (rows stage-major, as `dense_qp` lays them)."""
    H, f, C, lo, hi = dense_qp(qp)
    nb = qp.dims[3]
    lam = np.zeros(C.shape[0])
    for (k, b), v in r["lam"].items():
        lam[k * nb + b] = v
    u = r["U"].ravel()
    return float(np.max(np.abs(H @ u + f + C.T @ lam)) /
                 (1 + np.max(np.abs(f))))


def test_the_twin_reaches_daqps_optimum_with_kkt_multipliers(loop):
    constrained = 0
    for qp in loop["posed"]:
        r = solve(qp)
        assert r["optimal"]
        m_max = loop["m_max"].reshape(qp.dims[0], -1)
        assert np.max(np.abs(r["U"] - run_daqp(qp)) / m_max) <= 1e-9
        assert _kkt(qp, r) <= 1e-9
        # an upper bound's multiplier is positive, a lower bound's negative
        assert all(v * r["working"][kb] >= -1e-9
                   for kb, v in r["lam"].items())
        constrained += bool(r["working"])
    assert constrained >= 5          # the loop's slew holds boxes


def test_a_change_at_stage_k_refactors_stages_k_to_0(loop):
    qp = max(loop["posed"], key=lambda q: len(solve(q)["working"]))
    W = solve(qp)["working"]
    (k, b), s = max(W.items())        # the latest stage's box
    rest = {kb: v for kb, v in W.items() if kb != (k, b)}
    partial = factor(qp, W, factor(qp, rest), k)
    full = factor(qp, W)
    for a, f in zip(partial, full):
        np.testing.assert_allclose(a.K, f.K, atol=1e-12)
        np.testing.assert_allclose(a.k, f.k, atol=1e-12)
        np.testing.assert_allclose(a.P_out, f.P_out, rtol=1e-12, atol=1e-12)


def test_a_warm_start_at_the_optimums_working_set_takes_one_iteration(loop):
    qp = max(loop["posed"], key=lambda q: len(solve(q)["working"]))
    r = solve(qp)
    assert len(r["working"]) >= 4
    # started at the optimum with its working set: one recursion of
    # every box at once, and the multipliers' check
    at = replace(qp, u0=r["U"], x0=r["X"])
    w = solve(at, dict(r["working"]))
    assert w["iterations"] == 1 and w["factored"] == qp.dims[0]
    np.testing.assert_allclose(w["U"], r["U"], atol=1e-12)


def test_every_capped_iterate_keeps_the_boxes_and_lowers_the_cost(loop):
    def cost(qp, U):
        X = qp.rollout(U)
        return sum(0.5 * X[k] @ qp.Q[k] @ X[k] + qp.q[k] @ X[k]
                   + 0.5 * U[k] @ (qp.R * U[k]) + qp.g[k] @ U[k]
                   for k in range(qp.dims[0]))
    capped = 0
    for qp in loop["posed"]:
        for cap in (1, 2, 3):
            r = solve(qp, max_iter=cap)
            v = qp.values(r["U"], qp.rollout(r["U"]))
            assert np.all(v <= qp.hi + 1e-9) and np.all(v >= qp.lo - 1e-9)
            assert cost(qp, r["U"]) <= cost(qp, qp.u0) + 1e-12
            capped += not r["optimal"]
    assert capped >= 3


def _chain(N: int = 2) -> StageQP:
    """x_{k+1} = x_k + u_k, boxes |u| ≤ 1 and |x| ≤ 1: the smallest QP
    whose boxes can depend on each other."""
    one = np.ones((N, 1, 1))
    return StageQP(A=one, B=one.copy(), d=np.zeros((N, 1)), Q=one.copy(),
                   q=np.full((N, 1), -4.0), R=np.array([1.0]),
                   g=np.zeros((N, 1)), Eu=np.array([[0.5], [0.0]]),
                   Ex=np.array([[0.0], [0.5]]), lo=np.full((N, 2), -0.5),
                   hi=np.full((N, 2), 0.5), fixed=np.array([False]),
                   u0=np.zeros((N, 1)), x0=np.zeros((N, 1)))


def test_a_dependent_box_is_held_out():
    qp = _chain()
    # x_1 = u_0: both at their upper bound fix u_0 twice
    with pytest.raises(Dependent):
        factor(qp, {(0, 0): 1, (0, 1): 1})
    # started where both hold, with both warm: the second is held out
    at = replace(qp, u0=np.array([[1.0], [0.0]]), x0=np.ones((2, 1)))
    r = solve(at, {(0, 0): 1, (0, 1): 1})
    assert r["optimal"] and r["dependent"] == 1
    assert r["working"] == {(0, 0): 1, (1, 1): 1}
    np.testing.assert_allclose(r["U"].ravel(), [1.0, 0.0], atol=1e-12)
    assert _kkt(at, r) <= 1e-12


def test_the_multipliers_need_no_dense_solve(loop):
    qp = max(loop["posed"], key=lambda q: len(solve(q)["working"]))
    W = solve(qp)["working"]
    stages = factor(qp, W)
    U, X = forward(qp, stages)
    lam = multipliers(qp, stages, W, U, X)
    assert set(lam) == set(W)
    assert _kkt(qp, {"U": U, "lam": lam}) <= 1e-9


def test_the_study_prints_its_table(capsys):
    main(["--horizon", "5", "--draws", "1", "--steps", "8", "--caps",
          "2,0"])
    out = capsys.readouterr().out
    assert "| 2 | " in out and "| none | " in out
    assert "A C version's memory" in out
