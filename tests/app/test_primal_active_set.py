"""The study's primal active set finds DAQP's optimum, keeps every
iterate feasible, and needs independent working sets."""

import daqp
import numpy as np

from benchmarks import primal_active_set as pas


def _qp(seed, n=12, m=30):
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(n, n))
    H = M @ M.T + 0.1 * np.eye(n)
    C = rng.normal(size=(m, n))
    lo, hi = -rng.uniform(0.1, 1, m), rng.uniform(0.1, 1, m)
    return H, rng.normal(size=n) * 5, C, lo, hi


def test_optimum_and_multipliers_are_daqps():
    for seed in range(20):
        H, g, C, lo, hi = _qp(seed)
        r = pas.solve(H, g, C, lo, hi, np.zeros(H.shape[0]), {})
        x, _, flag, info = daqp.solve(H, g, C, hi.copy(), lo.copy(),
                                      np.zeros(len(lo), np.int32))
        assert flag == 1 and r["optimal"]
        np.testing.assert_allclose(r["x"], x, atol=1e-9)
        np.testing.assert_allclose(r["lam"], info["lam"], atol=1e-8)


def test_a_capped_solve_is_feasible_and_lowers_the_cost():
    H, g, C, lo, hi = _qp(3)
    full = pas.solve(H, g, C, lo, hi, np.zeros(12), {})
    assert full["iterations"] > 3
    f = [0.0]
    assert len(full["path"]) == full["iterations"]
    for cap in range(1, full["iterations"]):
        x = pas.solve(H, g, C, lo, hi, np.zeros(12), {}, max_iter=cap)["x"]
        np.testing.assert_array_equal(x, full["path"][cap - 1])
        v = C @ x
        assert np.all(v >= lo - 1e-12) and np.all(v <= hi + 1e-12)
        f.append(0.5 * x @ H @ x + g @ x)
    assert all(b <= a + 1e-12 for a, b in zip(f, f[1:]))


def test_a_warm_working_set_of_the_optimum_takes_one_iteration():
    H, g, C, lo, hi = _qp(5)
    full = pas.solve(H, g, C, lo, hi, np.zeros(12), {})
    W = {int(j): int(np.sign(full["lam"][j]))
         for j in np.flatnonzero(full["lam"])}
    again = pas.solve(H, g, C, lo, hi, full["x"], W)
    assert again["iterations"] == 1
    np.testing.assert_allclose(again["x"], full["x"], atol=1e-12)


def test_independent_drops_a_dependent_row():
    C = np.array([[1.0, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 2]])
    assert pas.independent(C, [0, 1, 2, 3]) == [0, 1, 3]
    assert pas.independent(C, [2, 0, 1]) == [2, 0]
