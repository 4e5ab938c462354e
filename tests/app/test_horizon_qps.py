"""The horizon study's QPs are the step's: every way of solving them
lands on the step's torques (`benchmarks.horizon_qps`)."""

from dataclasses import replace

import numpy as np
import pytest

from benchmarks.horizon_qps import (active_sets, collect, run_daqp,
                                    run_osqp, run_primal)
from ocp.spacecraft import load_spacecraft


@pytest.fixture(scope="module")
def loop():
    return collect(horizon=5, draws=1, steps=12, seed=0)


def test_daqp_on_the_posed_qps_gives_the_steps_torques(loop):
    d = run_daqp(loop)
    assert len(d["cold"]) == 12
    assert d["error"]["cold"] <= 1e-9         # 2e-12 seen at N = 20
    for warm in ("warm_signs", "warm_unshifted", "warm_sides"):           # DAQP's primal tolerance
        assert d["error"][warm] <= 1e-5


def test_working_set_distance_counts_drops_and_adds(loop):
    # N = 5: 20 bounds (4 a stage), then 20 momentum rows
    signs = [np.zeros(40, int) for _ in range(3)]
    signs[1][[4, 24]] = 1       # stage 1's first bound and momentum row
    signs[2][[0, 20, 35]] = [1, -1, -1]
    sides = [np.abs(s) for s in signs]
    sides[2][39] = 1            # active, not in the working set
    # step 2 starts from step 1's set one stage ahead: the bound kept at
    # stage 0, the row moved to its other bound (2), stage 3's row (1)
    act = active_sets(dict(loop, qps=loop["qps"][:3]), sides, signs)
    np.testing.assert_array_equal(act, [[0, 0, 0, -1], [1, 1, 2, 2],
                                        [1, 3, 3, 3]])


def test_osqp_reaches_the_steps_torques_and_a_cap_does_not(loop):
    full = run_osqp(loop, adaptive=True)
    assert full["error"].max() <= 1e-3
    capped = run_osqp(loop, adaptive=False, cap=5)
    assert np.all(capped["iters"] == 5)
    assert capped["error"].max() > full["error"].max()


def test_primal_active_set_from_the_steps_start_reaches_its_torques(loop):
    d = run_daqp(loop)
    r = run_primal(loop, d["signs"], [1])
    assert len(r["kept"]) + r["infeasible_start"] == 11   # 12 less the first
    assert len(r["kept"]) >= 8
    assert r["error"] <= 1e-5                 # the step's: DAQP's tolerance
    distance, missed = (np.array(v) for v in r[1])
    assert np.all((missed >= -1e-12) & (missed <= 1 + 1e-12))


def test_a_users_toml_craft_with_a_rate_bound_reaches_the_study(tmp_path):
    """Six wheels and a rate bound, from a TOML file: the QPs hold their
    torque, momentum and rate rows, and DAQP gives the step's torques."""
    sc = replace(load_spacecraft("chibis-m"), rate_max=0.02)
    path = tmp_path / "craft.toml"
    path.write_text(sc.to_toml())
    c = collect(horizon=4, draws=1, steps=6, seed=0, spacecraft=str(path))
    q = c["qps"][0]
    assert q["Winv"].shape == (24, 24)
    assert q["rows"].shape == (4 * 6 + 4 * 3, 24)        # momenta, rates
    np.testing.assert_array_equal(c["scale"][-12:], 0.02)
    d = run_daqp(c)
    assert d["error"]["cold"] <= 1e-9
    assert run_primal(c, d["signs"], [1])["error"] <= 1e-5
