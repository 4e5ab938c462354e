"""Allocators and controllers shared by 4 threads answer as from one."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from adcs.robust_mc import slew_keep_out
from adcs_common.exceptions import ThreadOwnershipError

from allocation import QPAllocator, WheelArray
from ocp import quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import AttitudeMPC
from thrusters import DutyCycleAllocator, six_thruster_unit

THREADS = 4


def _shared_equals_sequential(call, inputs, rounds=3):
    """Every threaded answer equals the sequential one.

    To 1e-12: warm-started solvers (daqp's active set, the MPC's qrqp)
    start each problem where the previous call left them, and threads
    change which call came before (a last-bit difference); another
    thread's answer, a broken bound or NaN would be far off.
    """
    sequential = [call(x) for x in inputs]
    with ThreadPoolExecutor(THREADS) as pool:
        for _ in range(rounds):
            answers = list(pool.map(call, inputs))
            for a, b in zip(answers, sequential):
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_wheel_allocator_shared_by_four_threads():
    arr = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    qp = QPAllocator(arr)
    rng = np.random.default_rng(0)
    demands = [(0.3 * rng.normal(size=3), 3.0 * rng.uniform(-1, 1, 4))
               for _ in range(1000)]
    _shared_equals_sequential(
        lambda d: qp.allocate(d[0], d[1], 0.5).torques, demands)
    _shared_equals_sequential(
        lambda d: qp.allocate_fast(d[0], d[1], 0.5), demands)


def test_duty_allocator_shared_by_four_threads():
    alloc = DutyCycleAllocator(six_thruster_unit(), 2.0, 0.012,
                               tracking="weighted")
    rng = np.random.default_rng(1)
    cycles = [(rng.uniform(0, 0.5), rng.uniform(-0.01, 0.01, 2),
               np.r_[rng.uniform(-0.01, 0.01), 0, rng.uniform(-0.01, 0.01)])
              for _ in range(1000)]
    _shared_equals_sequential(lambda c: alloc.solve(*c).duty, cycles)
    _shared_equals_sequential(lambda c: alloc.duty_fast(*c), cycles)


def _model():
    return rigid_spacecraft(np.diag([3.0, 2.5, 3.5]),
                            WheelArray.pyramid(h_max=0.2, m_max=0.05))


def _run(mpc, model, n=15):
    """Run a short closed loop (RK4 plant) from rest; return the commands."""
    qf = quat_from_axis_angle([1, 1, 0], 0.5)
    x = model.state([1.0, 0.0, 0.0, 0.0])
    rk4 = model.rk4_step(1)
    mpc.reset()
    us = []
    for _ in range(n):
        u = np.asarray(mpc.step(x, qf).u).ravel()
        x = np.asarray(rk4(x, u, np.zeros(3), mpc.dt)).ravel()
        us.append(u)
    return np.array(us)


#: the stage-wise MPC with a keep-out cone across the slew (the cones
#: add kernels, no state the threads could share)
MPC_KINDS = [{"rti": True}, {"solver": "condensed"},
             {"solver": "stagewise",
              "keep_out": (slew_keep_out(0.5, np.deg2rad(10.0)),)}]


@pytest.mark.parametrize("kw", MPC_KINDS)
def test_one_mpc_per_thread_follows_its_trajectory_exactly(kw):
    model = _model()
    ref = _run(AttitudeMPC(model, horizon=8, **kw), model)
    mpcs = [AttitudeMPC(model, horizon=8, **kw) for _ in range(THREADS)]
    with ThreadPoolExecutor(THREADS) as pool:
        runs = list(pool.map(lambda m: _run(m, model), mpcs))
    for us in runs:
        np.testing.assert_allclose(us, ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("kw", MPC_KINDS)
def test_a_shared_mpc_refuses_a_second_thread_until_reset(kw):
    model = _model()
    mpc = AttitudeMPC(model, horizon=8, **kw)
    x = model.state([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle([1, 1, 0], 0.5)
    mpc.step(x, qf)
    with ThreadPoolExecutor(1) as pool:
        with pytest.raises(ThreadOwnershipError, match="reset"):
            pool.submit(mpc.step, x, qf).result()
        pool.submit(mpc.reset).result()        # hand it over
        assert pool.submit(mpc.step, x, qf).result().u.shape == (4,)
    with pytest.raises(ThreadOwnershipError):
        mpc.step(x, qf)
