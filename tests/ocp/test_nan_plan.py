"""A plan that goes NaN reports NaN figures, never a passing check.

The step Functions are what the C export generates, and C cannot raise:
a caller that tests ``violation <= tol`` or ``qp_kkt <= tol`` must see
the test fail. The maxima behind those figures (``fmax``/``mmax``) skip
NaN, so without `ocp.mpc.plan.nan_unless_finite` a NaN plan reported a
violation, defect and certificate of 0.
"""

from __future__ import annotations

import numpy as np
import pytest

from allocation import WheelArray
from ocp import quat_from_axis_angle, rigid_spacecraft
from ocp.mpc import AttitudeMPC, RobustMPC, inertia_corners

WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
MODEL = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), WHEELS)
QF = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
FIGURES = ("violation", "first_violation", "defect", "qp_kkt")


def _controllers():
    kw = {"horizon": 6, "dt": 0.5}
    yield "condensed", AttitudeMPC(MODEL, solver="condensed", rti=True, **kw)
    yield "stagewise", AttitudeMPC(MODEL, solver="stagewise", rti=True, **kw)
    yield "sqpmethod", AttitudeMPC(MODEL, solver="sqpmethod", rti=True, **kw)
    yield "robust", RobustMPC(MODEL, inertia_corners(MODEL.inertia, 0.2)[:3],
                              rti=True, **kw)


@pytest.mark.parametrize("name, mpc", list(_controllers()))
def test_a_nan_state_gives_nan_figures(name, mpc):
    x = MODEL.state([1.0, 0.0, 0.0, 0.0])
    ok = mpc.step_function(x, QF, np.zeros(3), mpc.initial_guess(x),
                           np.zeros(mpc.nz), np.zeros(mpc.ng))
    names = mpc.step_function.name_out()
    for fig in FIGURES:
        assert np.isfinite(float(ok[names.index(fig)])), (name, fig)
    assert float(ok[names.index("violation")]) <= 1e-9
    bad = x.copy()
    bad[4] = np.nan
    if name == "sqpmethod":
        # CasADi's sqpmethod refuses NaN in its own Jacobian: the call
        # fails (nonzero return in C), no figures to read
        with pytest.raises(RuntimeError, match="NaN detected|failed"):
            mpc.step_function(bad, QF, np.zeros(3), mpc.initial_guess(x),
                              np.zeros(mpc.nz), np.zeros(mpc.ng))
        return
    out = mpc.step_function(bad, QF, np.zeros(3), mpc.initial_guess(x),
                            np.zeros(mpc.nz), np.zeros(mpc.ng))
    assert not np.all(np.isfinite(np.asarray(out[names.index("z")])))
    for fig in FIGURES:
        v = float(out[names.index(fig)])
        assert np.isnan(v), (name, fig, v)
        assert not v <= 1e-6          # a caller's check fails
