"""Exact defaults; a failing iterative backend hands over and says so."""

import numpy as np

from allocation import QPAllocator, WheelArray
from thrusters import DutyCycleAllocator, six_thruster_unit


def test_both_allocators_default_to_the_exact_backend():
    assert QPAllocator(WheelArray.pyramid(h_max=1.0, m_max=0.1)).solver \
        == "daqp"
    assert DutyCycleAllocator(six_thruster_unit(), 2.0, 0.012).solver \
        == "daqp"


def test_a_starved_osqp_hands_wheel_demands_to_daqp():
    arr = WheelArray.from_axes(np.random.default_rng(5).normal(size=(3, 5)),
                               h_max=1.0, m_max=0.1, normalize=True,
                               ).with_failed(2)
    exact = QPAllocator(arr)
    starved = QPAllocator(arr, solver="osqp",
                          solver_options={"max_iter": 1})
    rng = np.random.default_rng(1)
    handed = 0
    for _ in range(50):
        M = 0.1 * rng.normal(size=3)
        r, ref = starved.allocate(M), exact.allocate(M)
        np.testing.assert_allclose(r.torques, ref.torques, atol=1e-9)
        if r.extras.get("fallback"):
            handed += 1
            assert r.extras["fallback"] == "daqp"
            assert r.extras["failed_backend"] == "osqp"
    assert handed > 25


def test_a_starved_osqp_never_returns_zero_duties_on_a_feasible_cycle():
    unit = six_thruster_unit()
    exact = DutyCycleAllocator(unit, 2.0, 0.012, tracking="weighted")
    starved = DutyCycleAllocator(unit, 2.0, 0.012, tracking="weighted",
                                 solver="osqp",
                                 solver_options={"max_iter": 1})
    rng = np.random.default_rng(2)
    handed = 0
    for _ in range(40):
        args = (rng.uniform(0, 0.5), rng.uniform(-0.01, 0.01, 2),
                np.r_[rng.uniform(-0.01, 0.01), 0, rng.uniform(-0.01, 0.01)])
        r, ref = starved.solve(*args), exact.solve(*args)
        assert r.status == ref.status and r.success
        np.testing.assert_allclose(r.duty, ref.duty, atol=1e-9)
        handed += r.extras.get("fallback") == "daqp"
    assert handed > 20
