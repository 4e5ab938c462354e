"""The slews study's settling: one definition, with its band and window.

#26: "settles in 300.38 s" (to 0.1°) stood next to "hold error 0.22°".
A row settles only when the error stays in the band from its settle time
to the end and over the whole hold window (`ClosedLoopResult.settled`).
"""

import numpy as np
import pytest

from adcs.studies.slews import mpc_rows, settle_cell


@pytest.fixture(scope="module")
def feedback():
    """The report's 150° slew under quaternion PD, 60 s, two windows."""
    from adcs_common.quaternion import quat_from_axis_angle
    from allocation import WheelArray
    from ocp.models.rigid import rigid_spacecraft
    from ocp.mpc import compare_slew

    wheels = WheelArray.pyramid(np.deg2rad(55), np.deg2rad(45), h_max=0.2,
                                m_max=0.05)
    model = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), wheels)
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle([1.0, -2.0, 3.0], np.deg2rad(150.0))
    return {hold: compare_slew(model, q0, qf, t_final=60.0, hold=hold,
                               solvers=(), time_optimal=False)[0]
            for hold in (15.0, 5.0)}


def test_entering_the_band_inside_the_hold_window_is_not_settled(feedback):
    r = feedback[15.0]
    # in the band from 51 s, but the last 15 s start at 45 s, at 0.74°
    assert r.settle_time == pytest.approx(51.0)
    assert np.rad2deg(r.hold_error) == pytest.approx(0.7407, abs=1e-3)
    assert np.rad2deg(r.final_error) == pytest.approx(0.0836, abs=1e-3)
    assert r.hold == 15.0 and not r.settled
    assert settle_cell(r) == "not settled (within 0.1° only from 51 s)"
    table, _ = mpc_rows([r], 60.0)
    assert table.columns[1] == "settle to 0.1° [s]"
    assert table.columns[8] == "hold error, last 15 s [deg]"
    assert table.rows[0][1] == "not settled (within 0.1° only from 51 s)"
    assert table.rows[0][7] == pytest.approx(0.0836, abs=1e-3)   # final
    assert table.rows[0][8] == pytest.approx(0.7407, abs=1e-3)   # hold
    assert "over the whole hold window" in table.note


def test_a_window_after_the_settle_time_is_settled(feedback):
    r = feedback[5.0]                     # window 55..60 s, after 51 s
    assert r.settled and r.settle_time == pytest.approx(51.0)
    assert np.rad2deg(r.hold_error) < 0.1
    assert settle_cell(r) == pytest.approx(51.0)


def test_the_summary_says_which_mpc_did_not_settle(feedback):
    from dataclasses import replace

    fb = feedback[15.0]
    held = replace(fb, name="MPC sqpmethod (RTI)", settle_time=32.0,
                   hold_error=np.deg2rad(1e-4))
    dipped = replace(fb, name="MPC ipopt", settle_time=300.38,
                     hold_error=np.deg2rad(0.22))
    never = replace(fb, name="MPC qrqp", settle_time=float("nan"),
                    hold_error=np.deg2rad(3.0))
    table, phrase = mpc_rows([held, dipped, never, fb], 60.0)
    assert [row[1] for row in table.rows] == [
        32.0, "not settled (within 0.1° only from 300.4 s)",
        "not settled (never within 0.1°)",
        "not settled (within 0.1° only from 51 s)"]
    assert phrase == ("MPC settling to 0.1° (held over the last 15 s): "
                      "32 s (sqpmethod (RTI)), not settled in 60 s (ipopt, "
                      "hold error 0.22°), not settled in 60 s (qrqp, hold "
                      "error 3°)")
    _, phrase = mpc_rows([held, fb], 60.0)
    assert phrase == ("MPC settles to 0.1° (held over the last 15 s) in "
                      "32 s (sqpmethod (RTI))")
