"""The array design optimiser: reference radii reproduced and certified."""

import itertools
import json

import numpy as np
import pytest

from allocation import WheelArray, certify_layout, design_array, envelope
from allocation.design_nlp import family_axes
from adcs_common.exceptions import InvalidValueError

TOL = 1e-6


def _worst_one_failure(axes):
    arr = WheelArray.from_axes(axes)
    return min(envelope(arr.with_failed(i)).inscribed_radius
               for i in range(arr.n_wheels))


def _icosahedral_axes():
    phi = (1 + np.sqrt(5)) / 2
    v = np.array([[0, 1, phi], [0, -1, phi], [1, phi, 0], [-1, phi, 0],
                  [phi, 0, 1], [phi, 0, -1]], dtype=float).T
    return v / np.linalg.norm(v, axis=0)


# ------------------------------------------------- the reference layouts
@pytest.mark.parametrize("axes, nominal, failed", [
    (family_axes("cone", 4, [np.arccos(1 / np.sqrt(3))]),
     4 / np.sqrt(6), 0.816497),
    (WheelArray.orthogonal_plus_skew(skew="equal_angle").axes,
     np.sqrt(2), 0.577350),
    # the table rounds the angles to 1e-3 deg; these are to 1e-7 deg
    (family_axes("cone", 5, [np.deg2rad(54.2322925)]), 2.182643, None),
    (family_axes("cone", 5, [np.deg2rad(48.0300847)]), None, np.sqrt(5) - 1),
    (_icosahedral_axes(), 2.752764, 1.902113),
    (WheelArray.pyramid().axes, 1.630253, None),
])
def test_reference_layouts_certified_by_the_envelope_code(axes, nominal,
                                                          failed):
    r_nom, r_fail = certify_layout(axes)
    if nominal is not None:
        assert r_nom == pytest.approx(nominal, abs=1e-6)
        assert envelope(WheelArray.from_axes(axes)).inscribed_radius == \
            pytest.approx(r_nom, abs=1e-12)
    if failed is not None:
        assert r_fail == pytest.approx(failed, abs=1e-6)
        assert _worst_one_failure(axes) == pytest.approx(r_fail, abs=1e-12)


# ------------------------------------------------ the optimiser finds them
@pytest.mark.parametrize("kwargs, nominal, failed", [
    (dict(n_wheels=4), 4 / np.sqrt(6), None),
    (dict(n_wheels=4, failures=1), None, 2 / np.sqrt(6)),
    (dict(n_wheels=4, family="pyramid"), 4 / np.sqrt(6), None),
    (dict(n_wheels=4, family="3+1"), np.sqrt(2), None),
    (dict(n_wheels=5, family="cone"), 2.182643356, None),
    (dict(n_wheels=5, family="cone", failures=1), None, np.sqrt(5) - 1),
    (dict(n_wheels=5, failures=1), None, np.sqrt(5) - 1),
    (dict(n_wheels=6, family="pairs"), 2.752763841, None),
])
def test_optimiser_reproduces_reference(kwargs, nominal, failed):
    d = design_array(**kwargs, starts=4, seed=1)
    r_nom, r_fail = certify_layout(d.axes, d.capacity, d.failures)
    assert (d.radius, d.worst_failure_radius) == (r_nom, r_fail)
    if nominal is not None:
        assert d.radius >= nominal - TOL
        assert d.radius == pytest.approx(nominal, abs=TOL)
    if failed is not None:
        assert d.worst_failure_radius >= failed - TOL
        assert d.worst_failure_radius == pytest.approx(failed, abs=TOL)
    assert np.allclose(np.linalg.norm(d.axes, axis=0), 1.0)
    assert d.start_objectives.shape == (4,) == d.start_times.shape


def test_cone_angles_of_the_table():
    best = design_array(5, family="cone", starts=2)
    assert np.rad2deg(best.params[0]) == pytest.approx(54.232, abs=1e-3)
    fail = design_array(5, family="cone", failures=1, starts=2)
    assert np.rad2deg(fail.params[0]) == pytest.approx(48.030, abs=1e-3)


def test_budget_and_scaling():
    d = design_array(4, budget=8.0, starts=3, quantity="torque")
    assert d.capacity.sum() == pytest.approx(8.0)
    assert d.radius == pytest.approx(2 * 4 / np.sqrt(6), abs=1e-5)
    arr = d.wheel_array(h_max=3.0)
    assert np.allclose(arr.m_max, d.capacity) and np.allclose(arr.h_max, 3)
    scaled = design_array(4, capacity=2.0, starts=2)
    assert scaled.radius == pytest.approx(2 * 4 / np.sqrt(6), abs=1e-5)


def test_weighted_trade_lies_between():
    d = design_array(6, failures=1, nominal_weight=0.5, starts=3)
    assert d.objective == pytest.approx(
        0.5 * d.radius + 0.5 * d.worst_failure_radius)


@pytest.mark.parametrize("kwargs", [
    dict(n_wheels=2), dict(n_wheels=4, failures=2),
    dict(n_wheels=5, family="pyramid"), dict(n_wheels=4, family="x"),
    dict(n_wheels=4, quantity="power"), dict(n_wheels=4, budget=-1.0),
    dict(n_wheels=5, failures=1, nominal_weight=2.0),
    dict(n_wheels=13), dict(n_wheels=4, starts=0),
])
def test_bad_input_refused(kwargs):
    with pytest.raises(InvalidValueError):
        design_array(**kwargs)
