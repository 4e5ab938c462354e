import casadi as ca
import numpy as np

from adcs_common.buffers import BoundCall


def test_bound_call_evaluates_in_place_and_keeps_its_buffer_alive():
    x = ca.SX.sym("x", 2)
    f = ca.Function("f", [x], [2 * x, ca.sum1(x)])
    a, y, s = np.array([1.0, 2.0]), np.zeros(2), np.zeros(1)
    call = BoundCall(f, (a,), (y, s))
    del f                      # the buffer must outlive the caller's names
    call.trigger()
    np.testing.assert_array_equal(y, [2.0, 4.0])
    a[:] = [3.0, -1.0]
    call.trigger()
    np.testing.assert_array_equal(y, [6.0, -2.0])
    assert s[0] == 2.0
    assert call.inputs[0] is a and call.outputs == (y, s)
