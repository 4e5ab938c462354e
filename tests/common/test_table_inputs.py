"""The table functions answer a wrong argument with the toolbox's own error."""

import pytest

from adcs_common.exceptions import InvalidValueError

BAD = ["rows", [1, 2], [None], 3, None]


def _frames():
    from allocation import envelope_frame, reach_frame
    from ocp.mpc import closed_loop_frame
    from ocp.slews import comparison_frame
    from thrusters import table_frame

    return {"envelope_frame": envelope_frame, "reach_frame": reach_frame,
            "closed_loop_frame": closed_loop_frame,
            "comparison_frame": comparison_frame, "table_frame": table_frame}


@pytest.mark.parametrize("name", ["envelope_frame", "reach_frame",
                                  "closed_loop_frame", "comparison_frame",
                                  "table_frame"])
@pytest.mark.parametrize("bad", BAD, ids=repr)
def test_frame_rejects_what_is_not_its_rows(name, bad):
    with pytest.raises(InvalidValueError):
        _frames()[name](bad)


@pytest.mark.parametrize("name", ["reach_frame", "closed_loop_frame",
                                  "comparison_frame", "table_frame"])
def test_frame_of_no_rows_is_empty(name):
    assert len(_frames()[name]([])) == 0
