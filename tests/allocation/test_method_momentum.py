"""Momentum-bound handling of the allocation methods, checked by hand."""

import numpy as np
import pytest

from allocation import (
    InvalidValueError,
    WheelArray,
    format_momentum,
    momentum_cases,
    momentum_handling,
)
from allocation.methods import (
    direct_allocation,
    pseudo_inverse,
    wls_alloc,
)
from allocation.qp.problem import torque_bounds
from allocation.zonotope import zonotope_facets

DT = 0.5
PYRAMID = WheelArray.pyramid(h_max=4.0, m_max=0.2)


def inside_momentum_set(array, h, M):
    """Test M in {A m : lo <= m <= hi} by the zonotope's facets.

    Independent of the QP.
    """
    lo, hi, _ = torque_bounds(array, h, DT)
    A = array.working_axes
    normals, offsets = zonotope_facets(A * (hi - lo) / 2, A @ (lo + hi) / 2)
    return bool(np.all(normals @ M <= offsets + 1e-9 * np.abs(offsets)))


def test_cases_near_the_bound():
    array = WheelArray.pyramid(h_max=4.0, m_max=0.2, failed=[1])
    h, D = momentum_cases(array, 400, DT, seed=2)
    assert h.shape == (400, 4) and D.shape == (400, 3)
    assert np.all(h[:, 1] == 0.0)
    assert np.all(np.abs(h) <= array.h_max)
    near = np.abs(h[:, [0, 2, 3]]) >= 4.0 - 1.5 * 0.2 * DT
    assert 0.45 < near.mean() < 0.65   # half near, plus uniform ones there
    with pytest.raises(InvalidValueError):
        momentum_cases(array, 10, 0.0)


def test_pyramid_rows_against_hand_computation():
    rows = momentum_handling(PYRAMID, {"pseudo-inverse": pseudo_inverse,
                                       "WLS active set": wls_alloc,
                                       "direct allocation":
                                           direct_allocation},
                             dt=DT, n_cases=300, seed=4)
    by = {r.method: r for r in rows}
    h, D = momentum_cases(PYRAMID, 300, DT, seed=4)
    A = PYRAMID.working_axes
    P = np.linalg.pinv(A)
    # the exact QP meets exactly the demands inside the momentum-limited set
    inside = np.array([inside_momentum_set(PYRAMID, hk, M)
                       for hk, M in zip(h, D)])
    qp = by["exact QP (scale)"]
    assert qp.n_exact == int(inside.sum())
    assert 0.5 < inside.mean() < 0.95           # the bound bites
    assert qp.violation_share == 0.0 and qp.worst_excess <= 1e-12
    # torque limits only: the clipped pseudo-inverse, vectorised
    m = np.clip(D @ P.T, -0.2, 0.2)
    after = np.abs(h + m * DT)
    share = float(np.mean(np.any(after > 4.0 * (1 + 1e-9), axis=1)))
    pi = by["pseudo-inverse"]
    assert pi.violation_share == pytest.approx(share, abs=1e-15)
    assert 0.1 < share < 0.6
    # at most one step of full torque beyond h_max: 0.2 * 0.5 / 4
    assert pi.worst_excess == pytest.approx(
        float(np.max((after - 4.0) / 4.0)), abs=1e-15)
    assert 0.0 < pi.worst_excess <= 0.2 * DT / 4.0 + 1e-15
    # boxed: the clipped pseudo-inverse meets the exact cases it meets
    met = []
    for hk, M in zip(h[inside], D[inside]):
        lo, hi, _ = torque_bounds(PYRAMID, hk, DT)
        mb = np.clip(P @ M, lo, hi)
        met.append(np.linalg.norm(A @ mb - M) <= 1e-3 * np.linalg.norm(M))
    assert pi.reach_share == pytest.approx(np.mean(met), abs=1e-15)
    assert pi.reach_share < 0.9
    for r in rows:
        assert r.bounded_violation_share == 0.0
    # direct allocation and WLS reach the whole momentum-limited set
    assert by["direct allocation"].reach_share == 1.0
    assert by["WLS active set"].reach_share == 1.0
    assert "worst excess" in format_momentum(rows)


def test_three_working_wheels_every_method_reaches():
    """One solution per demand: every method finds it inside the box."""
    array = WheelArray.pyramid(h_max=4.0, m_max=0.2, failed=[2])
    rows = momentum_handling(array, dt=DT, n_cases=120, seed=1)
    assert len(rows) == 8
    for r in rows:
        assert r.reach_share == 1.0, r.method
        assert r.bounded_violation_share == 0.0
    # with the limits only, every method gives the same torques, so the
    # same momentum violations
    assert len({r.violation_share for r in rows[1:]}) == 1
