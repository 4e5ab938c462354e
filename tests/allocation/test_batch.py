"""The batch allocator: K demands at once, equal to one at a time."""

import threading

import numpy as np
import pytest

from allocation import (
    InvalidValueError,
    LinearLaw,
    ShapeError,
    WheelArray,
    law_extent,
    min_norm_gains,
    torque_reach,
)
from allocation.qp import BatchAllocation, QPAllocator, available_solvers
from conftest import DELTA, GAMMA

#: "equal to the one-at-a-time answers" (the issue's bar)
EQUAL = 1e-10


def small_pyramid(**kw) -> WheelArray:
    return WheelArray.pyramid(DELTA, GAMMA, h_max=4.0, m_max=0.2, **kw)


def demands(k: int, m_max: float, seed: int = 0) -> np.ndarray:
    """Random directions, half inside the set and half far outside."""
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(k, 3))
    M /= np.linalg.norm(M, axis=1)[:, None]
    return M * m_max * rng.uniform(0.05, 4.0, size=(k, 1))


def one_at_a_time(q: QPAllocator, M, h=None, dt=None) -> np.ndarray:
    return np.array([q.allocate(M[k], None if h is None else h[k],
                                dt).torques for k in range(len(M))])


@pytest.mark.parametrize("failed", [(), (0,), (1,), (2,), (3,)])
@pytest.mark.parametrize("weights", [None, [1.0, 2.0, 3.0, 4.0]])
def test_batch_equals_allocate_on_random_and_saturated_demands(
        failed, weights):
    arr = small_pyramid().with_failed(*failed)
    q = QPAllocator(arr, weights)
    M = demands(300, 0.2)
    res = q.allocate_batch(M)
    np.testing.assert_allclose(res.torques, one_at_a_time(q, M), rtol=0,
                               atol=EQUAL)
    assert res.extras == {"vectorised": 300, "one_at_a_time": 0}
    assert 50 < res.saturated.sum() < 300            # both kinds present
    assert set(res.status) == {"optimal", "saturated"}
    alphas = [q.allocate(Mk).alpha for Mk in M[:20]]
    np.testing.assert_allclose(res.alpha[:20], alphas, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.achieved, res.torques @ arr.axes.T,
                               atol=1e-15)
    for i in failed:
        assert np.all(res.torques[:, i] == 0.0)


def test_saturated_rows_keep_the_demand_direction():
    q = QPAllocator(small_pyramid())
    M = demands(200, 0.2, seed=3)
    res = q.allocate_batch(M)
    sat = res.saturated
    np.testing.assert_allclose(res.achieved[sat],
                               res.alpha[sat, None] * M[sat], atol=1e-13)
    assert np.all(np.abs(res.torques) <= 0.2 + 1e-15)


def test_momentum_bounds_with_wheels_past_their_limit_go_one_at_a_time():
    arr = small_pyramid()
    q = QPAllocator(arr)
    M = demands(200, 0.2, seed=1)
    rng = np.random.default_rng(2)
    h = rng.uniform(-1.05, 1.05, size=(200, 4)) * arr.h_max
    res = q.allocate_batch(M, h, dt=5.0)
    np.testing.assert_allclose(res.torques, one_at_a_time(q, M, h, 5.0),
                               rtol=0, atol=EQUAL)
    past = (np.abs(h) > arr.h_max).any(axis=1)
    assert res.extras["one_at_a_time"] == past.sum() > 0
    after = h + res.torques * 5.0
    inside = ~past
    assert np.all(np.abs(after[inside]) <= arr.h_max * (1 + 1e-12))


@pytest.mark.parametrize("build", [
    lambda: QPAllocator(WheelArray.orthogonal_pairs(m_max=0.2)),
    lambda: QPAllocator(small_pyramid(), momentum_target=np.zeros(4)),
    lambda: QPAllocator(small_pyramid(), saturation="least_squares"),
], ids=["six wheels", "null-space term", "least squares"])
def test_allocators_without_a_closed_form_answer_one_at_a_time(build):
    q = build()
    n = q.array.n_wheels
    M = demands(40, 0.2, seed=4)
    h = np.random.default_rng(5).uniform(-0.5, 0.5, size=(40, n))
    res = q.allocate_batch(M, h)
    np.testing.assert_allclose(res.torques, one_at_a_time(q, M, h),
                               rtol=0, atol=EQUAL)
    assert res.extras == {"vectorised": 0, "one_at_a_time": 40}


@pytest.mark.skipif("osqp" not in available_solvers(), reason="no osqp")
def test_a_backend_chosen_by_name_answers_every_row_itself():
    q = QPAllocator(small_pyramid(), solver="osqp")
    res = q.allocate_batch(demands(10, 0.2))
    assert res.extras["one_at_a_time"] == 10


@pytest.mark.parametrize("bad, args, exc", [
    (np.full((2, 3), np.nan), {}, InvalidValueError),
    (np.ones(3), {}, ShapeError),
    (np.ones((2, 4)), {}, ShapeError),
    (None, {}, ShapeError),
    (np.ones((2, 3)), {"wheel_momentum": np.ones((3, 4))}, ShapeError),
    (np.ones((2, 3)), {"wheel_momentum": np.ones(4)}, ShapeError),
    (np.ones((2, 3)), {"dt": 0.5}, InvalidValueError),
    (np.ones((2, 3)), {"wheel_momentum": np.ones((2, 4)), "dt": -1.0},
     InvalidValueError),
], ids=["nan", "one demand", "four columns", "none", "momentum rows",
        "momentum 1-D", "dt without momentum", "negative dt"])
def test_bad_batches_raise_the_toolbox_errors(bad, args, exc):
    with pytest.raises(exc):
        QPAllocator(small_pyramid()).allocate_batch(bad, **args)


def test_an_empty_batch_is_empty_and_the_result_is_concise():
    q = QPAllocator(small_pyramid())
    empty = q.allocate_batch(np.zeros((0, 3)))
    assert empty.torques.shape == (0, 4) and len(empty) == 0
    res = q.allocate_batch(demands(1000, 0.2))
    assert isinstance(res, BatchAllocation) and res.success
    text = repr(res)
    assert text.startswith("BatchAllocation(1000 demands × 4 wheels")
    assert len(text) < 120


def test_a_shared_allocator_answers_each_thread_as_alone():
    q = QPAllocator(small_pyramid())
    batches = [demands(500, 0.2, seed=s) for s in range(4)]
    alone = [q.allocate_batch(M).torques for M in batches]
    got: dict[int, np.ndarray] = {}

    def work(i):
        for _ in range(20):
            got[i] = q.allocate_batch(batches[i]).torques

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in range(4):
        np.testing.assert_array_equal(got[i], alone[i])


class ClippedMinNorm:
    """Minimum-norm law clipped per wheel (Basilisk's effector does this).

    Not exact beyond the first saturated wheel, so the reach bisection
    has work to do; offers both call styles.
    """

    def __init__(self, arr):
        self.gains = min_norm_gains(arr)
        self.m_max = arr.m_max

    def allocate(self, M):
        return np.clip(self.gains @ M, -self.m_max, self.m_max)

    def allocate_batch(self, M):
        return BatchLike(np.clip(M @ self.gains.T, -self.m_max, self.m_max))


class BatchLike:
    def __init__(self, torques):
        self.torques = torques


class OneAtATime:
    def __init__(self, law):
        self.allocate = law.allocate


@pytest.mark.parametrize("failed", [(), (2,)])
def test_reach_bisects_all_directions_at_once_with_the_same_answer(failed):
    arr = small_pyramid().with_failed(*failed)
    law = ClippedMinNorm(arr)
    u = np.random.default_rng(6).normal(size=(3, 60))
    batch = law_extent(arr, law, u)
    single = law_extent(arr, OneAtATime(law), u)
    np.testing.assert_array_equal(batch, single)
    exact = law_extent(arr, LinearLaw(law.gains, "min-norm"), u)
    np.testing.assert_allclose(batch, exact, rtol=2e-4)


def test_qp_reach_uses_the_batch_and_reaches_the_whole_set():
    arr = small_pyramid()
    q = QPAllocator(arr)
    fast = torque_reach(arr, q, n_directions=200)
    slow = torque_reach(arr, OneAtATime(q), n_directions=200, name="QP")
    np.testing.assert_array_equal(fast.law_extent, slow.law_extent)
    assert fast.min_direction_fraction == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("failed", [(), (1,)])
@pytest.mark.parametrize("reference", ["casadi:daqp", "casadi:qrqp"])
def test_closed_form_equals_the_active_set_qp(failed, reference):
    """Closed form (one and batch) equals an active-set QP solver.

    The default answers 3-4 working wheels in closed form.
    """
    arr = small_pyramid().with_failed(*failed)
    q, ref = QPAllocator(arr), QPAllocator(arr, solver=reference)
    M = demands(200, 0.2, seed=9)
    h = np.random.default_rng(2).uniform(-1, 1, size=(200, 4)) * arr.h_max
    for args in [(), (h, 5.0)]:
        want = one_at_a_time(ref, M, *args)
        np.testing.assert_allclose(one_at_a_time(q, M, *args), want,
                                   rtol=0, atol=EQUAL)
        np.testing.assert_allclose(q.allocate_batch(M, *args).torques,
                                   want, rtol=0, atol=EQUAL)
    assert q.allocate(M[0]).solver == "closed form"
    assert ref.allocate(M[0]).solver == reference


def test_more_than_four_wheels_go_to_daqp():
    q = QPAllocator(WheelArray.orthogonal_pairs(m_max=0.2))
    res = q.allocate(np.array([0.3, -0.1, 0.2]))
    assert res.solver == "daqp" and res.status == "optimal"
