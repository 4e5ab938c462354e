"""Monte Carlo draws flown in Basilisk by the nominal and the robust MPC.

Basilisk's craft is the drawn plant (inertia, products, tilted wheel
axes); the MPC steps inside it through AttitudeMPCModule. Each run is
compared with the same draw flown by `simulate_mpc` (CVODES).
"""

import numpy as np
import pytest

pytest.importorskip(
    "Basilisk", reason="Basilisk is optional: pip install -e .[basilisk]")

from adcs.basilisk.robust_mc import (basilisk_mc_case,  # noqa: E402
                                     basilisk_robust_mc, run_basilisk_mc)
from adcs.cli import main  # noqa: E402
from adcs.robust_mc import (draw_plant, robust_mc_case,  # noqa: E402
                            robust_mc_table, summarise)
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


def test_a_monte_carlo_case_in_basilisk_is_the_case_in_ours():
    """Same draw, both MPCs under a rate bound: the same outputs."""
    case = dict(spacecraft="demo", seed=1, draw=0, t_final=10.0,
                rate_max=0.04, spread=0.2, angle_deg=90.0, rate_margin=0.05)
    b, o = basilisk_mc_case(**case), robust_mc_case(**case)
    for k in ("factor_1", "product_xz", "tilt_max"):
        assert b[k] == o[k]
    for c in ("nominal", "robust"):
        assert b[f"{c}_failed"] == o[f"{c}_failed"] == 0.0
        assert b[f"{c}_faults"] == 0.0
        assert abs(b[f"{c}_final_error"] - o[f"{c}_final_error"]) < 1e-6
        assert b[f"{c}_energy"] == pytest.approx(o[f"{c}_energy"], rel=1e-5)
        for v in ("momentum", "torque", "rate"):
            assert b[f"{c}_{v}_violation"] < 1e-9
        assert 0.0 < b[f"{c}_step_time"] < 1.0
    # mid-slew at 10 s: not settled
    assert np.isnan(b["robust_settle_time"])


def test_the_monte_carlo_in_basilisk_reads_as_ours():
    ds = run_basilisk_mc(1, seed=0, t_final=4.0)
    nominal, robust = summarise(ds)
    assert (nominal.draws, nominal.failed, robust.failed) == (1, 0, 0)
    assert "| loops broken | 0 | 0 |" in robust_mc_table(ds)


def test_cli_sweep_robust_in_basilisk(tmp_path, capsys):
    assert main(["sweep", "robust-basilisk", "--quick", "--sync",
                 "--samples", "1", "--no-progress", "--out",
                 str(tmp_path)]) == 0
    assert "1 cases, 0 failed" in capsys.readouterr().out
    assert (tmp_path / "robust-basilisk.nc").exists()
