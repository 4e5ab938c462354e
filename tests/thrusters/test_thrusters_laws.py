"""[4] closed forms: eq. (2) unloading, eqs. (8)-(10), Table 4."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from thrusters import (
    InvalidValueError,
    ShapeError,
    pair_forces,
    reorientation_law,
    six_thruster_unit,
    unloading_law,
)

R, P = 0.25, 0.5
S3 = np.sqrt(3.0)
UNIT = six_thruster_unit(R=R, L=0.3, thrust=P)


def eq2_by_hand(P_T, mx, mz):
    """Eq. (2) solved symbolically for three equal engines of thrust P."""
    s = P_T / P
    k1 = s / 3 - 2 * mz / (3 * R * P)
    k2 = (s - k1) / 2 + mx / (S3 * R * P)
    k3 = (s - k1) / 2 - mx / (S3 * R * P)
    return np.array([k1, k2, k3])


def test_eq2_zero_momentum_shares_thrust_equally():
    res = unloading_law(UNIT, 0.739, [0, 0, 0], 10.0, 1.0)
    np.testing.assert_allclose(res.duty[:3], 0.739 / 1.5)
    np.testing.assert_array_equal(res.duty[3:], 0.0)
    assert res.status == "ok" and res.mode == "group1"


def test_eq2_matches_hand_solution_and_unloads():
    H = np.array([0.012, 0.004, -0.008])
    T, K = 10.0, 0.7
    res = unloading_law(UNIT, 0.739, H, T, K)
    np.testing.assert_allclose(
        res.duty[:3], eq2_by_hand(0.739, -K * H[0] / T, -K * H[2] / T),
        atol=1e-14)
    # sign convention: after the cycle the wheels hold (1 - K) H
    M = UNIT.torque_matrix() @ res.duty
    np.testing.assert_allclose((H + T * M)[[0, 2]], (1 - K) * H[[0, 2]],
                               atol=1e-15)
    assert UNIT.force_matrix()[1] @ res.duty == pytest.approx(0.739)
    np.testing.assert_allclose(res.error, 0.0, atol=1e-15)


def test_eq2_group2_for_negative_thrust():
    res = unloading_law(UNIT, -0.6, [0.01, 0, 0.0], 10.0)
    assert res.mode == "group2"
    np.testing.assert_array_equal(res.duty[:3], 0.0)
    assert UNIT.force_matrix()[1] @ res.duty == pytest.approx(-0.6)
    assert UNIT.torque_matrix()[0] @ res.duty == pytest.approx(-0.01 / 10)


def test_eq2_clipping_is_reported_not_silent():
    res = unloading_law(UNIT, 0.739, [2.0, 0, 0], 10.0, 1.0)
    assert res.status == "clipped" and res.clipped
    assert np.all((res.duty >= 0) & (res.duty <= 1))
    assert np.any(res.duty_unclipped < 0) or np.any(res.duty_unclipped > 1)
    assert np.linalg.norm(res.error) > 1e-3
    np.testing.assert_allclose(
        res.achieved, [UNIT.force_matrix()[1] @ res.duty,
                       *(UNIT.torque_matrix()[[0, 2]] @ res.duty)])


def test_eq3_on_times():
    res = unloading_law(UNIT, 0.739, [0, 0, 0], 10.0)
    np.testing.assert_allclose(res.on_times(10.0), 10.0 * res.duty)


def test_eq8_pair_forces_sum_and_torques():
    F = pair_forces(UNIT, 0.0, [0.02, -0.01])
    assert F.sum() == pytest.approx(0.0, abs=1e-15)           # eq. (10)
    # arms of D1, D2, D3 per newton (Table 1)
    ax = np.array([0.0, S3 / 2 * R, -S3 / 2 * R])
    az = np.array([-R, R / 2, R / 2])
    assert F @ ax == pytest.approx(0.02)
    assert F @ az == pytest.approx(-0.01)


def test_eq9_sign_selects_group_at_most_three_engines():
    res = reorientation_law(UNIT, 0.0, [0.02, -0.01])
    F = pair_forces(UNIT, 0.0, [0.02, -0.01])
    for f, (i, j) in zip(F, UNIT.pairs):
        on = i if f > 0 else j
        off = j if f > 0 else i
        assert res.duty[on] == pytest.approx(abs(f) / P)
        assert res.duty[off] == 0.0
    assert np.count_nonzero(res.duty) <= 3
    assert res.mode == "reorientation" and res.status == "ok"
    assert UNIT.force_matrix()[1] @ res.duty == pytest.approx(0, abs=1e-15)
    np.testing.assert_allclose(UNIT.torque_matrix()[[0, 2]] @ res.duty,
                               [0.02, -0.01], atol=1e-15)


def test_eq9_uses_each_engines_own_correction():
    unit = six_thruster_unit(correction=[1, 0.9, 0.95, 0.8, 0.85, 0.97])
    res = reorientation_law(unit, 0.0, [0.03, 0.01])
    np.testing.assert_allclose(unit.torque_matrix()[[0, 2]] @ res.duty,
                               [0.03, 0.01], atol=1e-15)


def test_table4_modes_and_eq2_agreement():
    # P_T > 0, small torques: group 1 only, identical to eq. (2)
    H = np.array([0.003, 0.0, -0.002])
    eq2 = unloading_law(UNIT, 0.739, H, 10.0, 1.0)
    eq9 = reorientation_law(UNIT, 0.739, -H[[0, 2]] / 10.0)
    assert eq9.mode == "group1"
    np.testing.assert_allclose(eq9.duty, eq2.duty, atol=1e-14)
    assert reorientation_law(UNIT, -0.3, [0.001, 0]).mode == "group2"
    assert reorientation_law(UNIT, 0.0, [0.001, 0]).mode == "reorientation"
    # a large torque against a small thrust needs both groups
    assert reorientation_law(UNIT, 0.01, [0.05, 0]).mode == "mixed"


def test_eq9_clipping_reported():
    res = reorientation_law(UNIT, 0.0, [0.5, 0.0])      # > arm capacity
    assert res.status == "clipped"
    assert np.all(res.duty <= 1.0)
    assert res.error[1] < 0


@settings(max_examples=60, deadline=None)
@given(st.floats(-0.1, 0.1), st.floats(-0.1, 0.1))
def test_property_reorientation_zero_net_thrust_and_bounds(mx, mz):
    res = reorientation_law(UNIT, 0.0, [mx, mz])
    assert np.all((res.duty >= 0) & (res.duty <= 1))
    assert abs(UNIT.force_matrix()[1] @ res.duty) < 1e-12
    for i, j in UNIT.pairs:
        assert res.duty[i] == 0.0 or res.duty[j] == 0.0
    if res.status == "ok":
        np.testing.assert_allclose(
            UNIT.torque_matrix()[[0, 2]] @ res.duty, [mx, mz], atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.05, 1.4), st.floats(-0.05, 0.05), st.floats(-0.05, 0.05))
def test_property_unloading_within_bounds(P_T, hx, hz):
    res = unloading_law(UNIT, P_T, [hx, 0.0, hz], 10.0, 1.0)
    assert np.all((res.duty >= 0) & (res.duty <= 1))
    assert (res.status == "ok") == np.allclose(res.error, 0, atol=1e-12)


@pytest.mark.parametrize("call, name", [
    (lambda: unloading_law(UNIT, np.nan, [0, 0, 0], 10.0), "P_T"),
    (lambda: unloading_law(UNIT, 0.0, [0, 0, 0], 10.0), "P_T"),
    (lambda: unloading_law(UNIT, 0.7, [0, np.nan, 0], 10.0), "H"),
    (lambda: unloading_law(UNIT, 0.7, [0, 0, 0, 0], 10.0), "H"),
    (lambda: unloading_law(UNIT, 0.7, [0, 0, 0], 0.005), "T_T"),
    (lambda: unloading_law(UNIT, 0.7, [0, 0, 0], 10.0, -1.0), "K_unl"),
    (lambda: reorientation_law(UNIT, 0.0, [0.1]), "M"),
    (lambda: reorientation_law(UNIT, 0.0, [np.inf, 0]), "M"),
])
def test_bad_input_names_the_argument(call, name):
    with pytest.raises((InvalidValueError, ShapeError), match=name):
        call()
