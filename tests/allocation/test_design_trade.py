"""The trade curve: a monotone, certified front between the two optima."""

import numpy as np
import pytest

from allocation import certify_layout, reference_layouts, trade_curve
from adcs_common.exceptions import InvalidValueError

#: wheels -> (nominal optimum, failure optimum) of the reference table
REFERENCE = {
    4: (4 / np.sqrt(6), 2 / np.sqrt(6)),
    5: (2.182643356, np.sqrt(5) - 1),
    6: (2.752763841, 1.902113033),
}


@pytest.mark.parametrize("n", sorted(REFERENCE))
def test_front_is_monotone_certified_and_ends_at_the_optima(n):
    curve = trade_curve(n, points=5, starts=4)
    nominal, failure = REFERENCE[n]
    r, f = curve.radius, curve.worst_failure_radius
    assert np.all(np.diff(f) > 0) and np.all(np.diff(r) < 0)
    assert r[0] == pytest.approx(nominal, abs=1e-6)
    assert f[-1] == pytest.approx(failure, abs=1e-6)
    assert curve.nominal_optimum == pytest.approx(nominal, abs=1e-6)
    assert curve.failure_optimum == pytest.approx(failure, abs=1e-6)
    for i in range(curve.n_points):
        assert np.allclose(np.linalg.norm(curve.axes[i], axis=0), 1.0)
        assert certify_layout(curve.axes[i], 1.0, 1) == (r[i], f[i])


def test_five_wheels_trade_and_six_do_not():
    assert trade_curve(5, points=4, starts=3).n_points >= 3
    assert trade_curve(6, points=4, starts=3).n_points == 1


@pytest.mark.parametrize("kwargs", [dict(n_wheels=3), dict(n_wheels=5,
                                                           points=1),
                                    dict(n_wheels=4, capacity=-1.0)])
def test_bad_input_refused(kwargs):
    with pytest.raises(InvalidValueError):
        trade_curve(**kwargs)


def test_reference_layouts_certified():
    refs = reference_layouts()
    assert len(refs) == 6
    for axes, nominal, failed in refs.values():
        r_nom, r_fail = certify_layout(axes)
        for ref, ours in ((nominal, r_nom), (failed, r_fail)):
            assert np.isnan(ref) or ours == pytest.approx(ref, abs=1e-6)
