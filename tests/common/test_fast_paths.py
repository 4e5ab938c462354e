"""A fast path accepts exactly what its full path accepts, answers alike."""

import numpy as np
import pytest

from adcs_common.exceptions import AdcsError
from allocation import QPAllocator, WheelArray, conic_allocator_function
from thrusters import DutyCycleAllocator, six_thruster_unit

SIX = WheelArray.from_axes(np.random.default_rng(4).normal(size=(3, 6)),
                           h_max=1.0, m_max=0.1, normalize=True)


def test_wheels_past_h_max_get_the_full_paths_answer():
    qp = QPAllocator(WheelArray.pyramid(h_max=4.0, m_max=0.2))
    h = [4.5, -4.5, 0.0, 0.0]
    ref = qp.allocate([1e-3, 0.0, 0.0], h, 0.5)
    np.testing.assert_array_equal(qp.allocate_fast([1e-3, 0, 0], h, 0.5),
                                  ref.torques)
    rng = np.random.default_rng(0)
    for _ in range(300):
        M = 0.2 * rng.normal(size=3)
        h = 4.0 * rng.uniform(-1.2, 1.2, 4)
        np.testing.assert_allclose(qp.allocate_fast(M, h, 0.5),
                                   qp.allocate(M, h, 0.5).torques,
                                   atol=1e-12)


@pytest.mark.parametrize("array", [WheelArray.pyramid(h_max=1.0, m_max=0.1),
                                   SIX], ids=["pyramid", "six"])
@pytest.mark.parametrize("torque, momentum", [
    ([np.nan, 0.0, 0.0], None), ([np.inf, 0.0, 0.0], None), (0.1, None),
    ([0.1], None), ([0.1, 0.2], None), ("abc", None),
    ([0.1, 0.0, 0.0], "nan"), ([0.1, 0.0, 0.0], "short"),
])
def test_allocate_fast_refuses_what_allocate_refuses(array, torque,
                                                     momentum):
    qp = QPAllocator(array)
    n = array.n_wheels
    h = {None: None, "nan": [np.nan] + [0.0] * (n - 1),
         "short": [0.0] * (n - 1)}[momentum]
    dt = None if h is None else 0.5
    with pytest.raises(AdcsError):
        qp.allocate(torque, h, dt)
    with pytest.raises(AdcsError):
        qp.allocate_fast(torque, h, dt)


def test_the_conic_function_flags_nan_instead_of_passing_it():
    """Where the Function cannot raise (``call``, buffers, C) NaN gives a
    NaN violation; a numeric Python call refuses NaN outright."""
    f = conic_allocator_function(SIX, dt=0.5)
    m, alpha, viol = f.call([[np.nan, 0.0, 0.0], np.zeros(6)])
    assert np.isnan(float(viol))
    m, alpha, viol = f.call([[0.01, 0.0, 0.0], [np.nan] + [0.0] * 5])
    assert np.isnan(float(viol))
    with pytest.raises(AdcsError, match="finite"):
        f([np.nan, 0.0, 0.0], np.zeros(6))
    with pytest.raises(AdcsError, match="finite"):
        f([0.01, 0.0, 0.0], [np.nan] + [0.0] * 5)
    m, alpha, viol = f([0.01, 0.0, 0.0], np.zeros(6))
    assert 0.0 <= float(viol) < 1e-12


@pytest.mark.parametrize("args", [(0.0, 0.001), (0.0, (0.001, 0.0), 0.002),
                                  (0.0, (0.001, 0.0), (0, 0, 0), 1e-4),
                                  (0.0, (np.nan, 0.0)), ("x", (0.0, 0.0))])
def test_duty_paths_never_broadcast_a_scalar(args):
    alloc = DutyCycleAllocator(six_thruster_unit(), 2.0, 0.012)
    with pytest.raises(AdcsError):
        alloc.solve(*args)
    with pytest.raises(AdcsError):
        alloc.duty_fast(*args)
