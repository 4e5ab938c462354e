"""Result objects: a short repr, saved and loaded back."""

import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from allocation import QPAllocator, WheelArray, min_norm_law, torque_reach
from ocp import quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import AttitudeMPC, simulate_mpc


@pytest.fixture(scope="module")
def reach():
    arr = WheelArray.pyramid(h_max=1.0, m_max=1.0)
    return torque_reach(arr, min_norm_law(arr), n_directions=400)


def test_reprs_show_arrays_by_shape(reach):
    text = repr(reach)
    assert text.startswith("ReachResult(law=")
    assert "directions=<array (3, 400)>" in text and len(text) < 700
    res = QPAllocator(WheelArray.pyramid(m_max=0.2)).allocate([0.1, 0, 0])
    assert "status='optimal'" in repr(res) and len(repr(res)) < 600


def test_results_save_and_load(tmp_path, reach):
    back = type(reach).load(reach.save(tmp_path / "reach"))
    np.testing.assert_array_equal(back.directions, reach.directions)
    assert back.mean_direction_fraction == reach.mean_direction_fraction
    assert back.failed == reach.failed and isinstance(back.failed, tuple)
    model = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]),
                             WheelArray.pyramid(h_max=0.2, m_max=0.05))
    loop = simulate_mpc(AttitudeMPC(model, rti=True), [1, 0, 0, 0],
                        quat_from_axis_angle([0, 0, 1], 0.3), t_final=5.0)
    slew = loop.trajectory
    path = slew.save(tmp_path / "out" / "slew.npz")
    again = type(slew).load(path)
    np.testing.assert_array_equal(again.q, slew.q)
    np.testing.assert_array_equal(again.wheel_torque, slew.wheel_torque)
    assert again.method == slew.method and again.status == slew.status
    assert len(repr(loop)) < 800
    # a field holding an object (here the trajectory) is named
    with pytest.raises(InvalidValueError,
                       match="ClosedLoopResult.trajectory"):
        loop.save(tmp_path / "loop")
