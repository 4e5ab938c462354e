"""Monte Carlo draws flown in Basilisk by the nominal and the robust MPC.

Basilisk's craft is the drawn plant (inertia, products, tilted wheel
axes); the MPC steps inside it through AttitudeMPCModule. Each run is
compared with the same draw flown by `simulate_mpc` (CVODES).
"""

import numpy as np
import pytest

pytest.importorskip(
    "Basilisk", reason="Basilisk is optional: pip install -e .[basilisk]")

from adcs.basilisk.robust_mc import basilisk_robust_mc  # noqa: E402
from adcs.robust_mc import draw_plant  # noqa: E402
from allocation import WheelArray  # noqa: E402


def test_a_draw_in_basilisk_is_the_draw_in_ours():
    runs = basilisk_robust_mc(1, seed=0, t_final=10.0)
    assert [r.controller for r in runs] == ["nominal", "robust"]
    for r in runs:
        assert r.faults == 0
        # the same loop: RK4 at 0.1 s against CVODES, the controller's
        # wheel momenta formed with the nominal axes (it knows no tilt)
        assert r.max_error_difference < 1e-5
        assert r.max_torque_difference < 1e-4
        assert r.momentum_excess <= 1e-9 and r.torque_excess <= 1e-12
        assert 0.1 < r.final_error_basilisk < np.pi    # 10 s: mid-slew
    # the two controllers flew the same plant differently
    assert abs(runs[0].energy_basilisk - runs[1].energy_basilisk) > 1e-3
    d = draw_plant(np.diag([3.0, 2.5, 3.5]),
                   WheelArray.pyramid(h_max=0.2, m_max=0.05), 0, 0)
    assert np.abs(d.tilt_a).max() > 0            # the axes were tilted
