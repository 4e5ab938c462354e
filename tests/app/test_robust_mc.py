"""Monte Carlo of nominal against robust MPC: draws, Dask = serial, CLI.

The draws stay inside the uncertainty set and are reproducible draw by
draw; the Monte Carlo on a 2-worker `distributed.LocalCluster` equals the
serial loop exactly (every output but the step times); a draw's nominal
loop is `simulate_mpc` on the drawn plant, flown here directly.
"""

import numpy as np
import pytest

distributed = pytest.importorskip(
    "distributed", reason="the Monte Carlo runs on the [sweep] extra")

from adcs.cli import main  # noqa: E402
from adcs.robust_mc import (CONTROLLERS, MISALIGNMENT, draw_plant,  # noqa
                            robust_mc_case, robust_mc_params, robust_mc_table,
                            run_robust_mc, slew_keep_out, summarise)
from adcs.sweep import SWEEPS  # noqa: E402
from adcs_common.exceptions import InvalidValueError  # noqa: E402
from allocation import WheelArray  # noqa: E402
from ocp import quat_from_axis_angle, rigid_spacecraft  # noqa: E402
from ocp.mpc import AttitudeMPC, simulate_mpc  # noqa: E402

J = np.diag([3.0, 2.5, 3.5])
WHEELS = WheelArray.pyramid(h_max=0.2, m_max=0.05)
OPTIONS = {"seed": 7, "t_final": 6.0}


def test_draws_stay_in_the_uncertainty_set_and_repeat():
    from adcs.studies.accuracy import MOUNT_TOL

    assert MISALIGNMENT == MOUNT_TOL          # the accuracy study's model
    draws = [draw_plant(J, WHEELS, 3, k) for k in range(40)]
    f = np.array([d.factors for d in draws])
    p = np.array([d.products for d in draws])
    t = np.array([np.r_[d.tilt_a, d.tilt_b] for d in draws])
    assert np.all(np.abs(f - 1.0) <= 0.2) and np.ptp(f) > 0.3
    assert np.all(np.abs(p) <= 0.05) and np.ptp(p) > 0.05
    assert np.all(np.abs(t) <= np.deg2rad(0.5))
    d = draws[5]
    # factors scale the principal moments in ascending order
    np.testing.assert_allclose(np.sort(np.diag(d.inertia)),
                               np.sort([2.5, 3.0, 3.5] * f[5]), rtol=1e-14)
    assert d.inertia[0, 1] == pytest.approx(3.5 * p[5, 0], rel=1e-14)
    # the axes are the accuracy model's tilts (with_mounting_errors)
    np.testing.assert_allclose(
        d.wheels.axes, WHEELS.with_mounting_errors(d.tilt_a, d.tilt_b).axes,
        rtol=0, atol=1e-15)
    ang = np.arccos(np.clip(np.sum(d.wheels.axes * WHEELS.axes, 0), -1, 1))
    assert 0 < ang.max() <= np.sqrt(2) * np.deg2rad(0.5)
    again = draw_plant(J, WHEELS, 3, 5)       # draw 5 alone: the same
    np.testing.assert_array_equal(again.inertia, d.inertia)
    assert not np.array_equal(draw_plant(J, WHEELS, 4, 5).inertia,
                              d.inertia)
    with pytest.raises(InvalidValueError, match="draw"):
        draw_plant(J, WHEELS, 0, -1)
    with pytest.raises(InvalidValueError, match="positive definite"):
        draw_plant(np.diag([1.0, 1.0, 100.0]), WHEELS, 0, 0, products=0.9)


@pytest.fixture(scope="module")
def serial():
    return run_robust_mc(4, **OPTIONS)


def test_the_monte_carlo_on_two_workers_equals_the_serial_loop(serial):
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True,
        host="127.0.0.1", dashboard_address=None, silence_logs=50)
    try:
        with distributed.Client(cluster) as client:
            there = run_robust_mc(4, client=client, **OPTIONS)
    finally:
        cluster.close()
    assert serial.sizes["case"] == 4 and there.attrs["chunks"] == 4
    assert list(serial["error"].values) == [""] * 4
    names = [k for k in serial.data_vars if not k.endswith("step_time")]
    assert len(names) > 20
    for k in names:
        np.testing.assert_array_equal(there[k].values, serial[k].values,
                                      err_msg=k)


def test_a_draw_is_the_closed_loop_of_its_plant(serial):
    d = draw_plant(J, WHEELS, 7, 2)
    plant = rigid_spacecraft(d.inertia, d.wheels)
    mpc = AttitudeMPC(rigid_spacecraft(J, WHEELS), solver="stagewise",
                      rti=True)
    r = simulate_mpc(mpc, [1, 0, 0, 0], quat_from_axis_angle(
        [1.0, 1.0, 0.0], np.deg2rad(90.0)), t_final=6.0, plant=plant)
    assert serial["nominal_energy"].values[2] == r.energy
    assert serial["nominal_final_error"].values[2] == r.final_error
    assert serial["factor_1"].values[2] == d.factors[0]
    # the robust loop flew the same plant to a different end
    assert serial["robust_energy"].values[2] != r.energy
    assert r.energy > 1e-3


def test_the_summary_counts_the_draws(serial):
    nom, rob = summarise(serial)
    for s, c in zip((nom, rob), CONTROLLERS):
        assert s.controller == c and s.draws == 4 and s.failed == 0
        # dH/dt = m exactly: no plant leaves the bounds of the plans
        assert s.momentum == 0 and s.torque == 0 and s.rate == 0
        assert s.energy_median == pytest.approx(
            np.median(serial[f"{c}_energy"].values), rel=1e-15)
        assert s.settled == 0              # 6 s: the slew is under way
    table = robust_mc_table(serial)
    assert "| loops broken | 0 | 0 |" in table
    assert f"{rob.energy_median / nom.energy_median:.2f}" in table


def test_the_summary_scales_the_rate_overshoot_by_the_bound(serial):
    """With a rate bound the summary counts the loops over it by more than
    1e-6 of the bound, and gives the overshoot's median and largest as a
    fraction of it (percent in the table); a broken loop is not counted."""
    ds = serial.copy(deep=True)
    ds["rate_max"][:] = 0.04
    ds["nominal_rate_violation"][:] = [0.0, 4e-9, 1e-4, 2e-3]
    ds["robust_rate_violation"][:] = [0.0, 0.0, 2e-5, float("nan")]
    ds["robust_failed"][:] = [0.0, 0.0, 0.0, 1.0]
    nom, rob = summarise(ds)
    assert nom.rate == 2 and rob.rate == 1 and rob.failed == 1
    assert nom.rate_over_max == pytest.approx(0.05, rel=1e-12)
    assert nom.rate_over_median == pytest.approx(1.25e-3 + 0.5e-7,
                                                 rel=1e-12)
    assert rob.rate_over_max == pytest.approx(5e-4, rel=1e-12)
    table = robust_mc_table(ds)
    assert "| rate overshoot, largest [% of bound] | 5.000 | 0.050 | 0.01 |" \
        in table


def test_a_keep_out_cone_across_the_slew_is_held_and_counted(serial):
    """With ``keep_out_deg`` both MPCs hold a cone that the slew would
    cross (`slew_keep_out`): neither loop's path, sampled 8 times per
    sample, enters it, and both still end on target. The summary counts
    a loop that entered by more than 1e-6 of the half-angle."""
    rows = robust_mc_params(1, seed=1, t_final=45.0, rate_max=0.04,
                            rate_margin=0.05, keep_out_deg=20.0)
    assert rows[0]["keep_out_deg"] == 20.0
    out = robust_mc_case(**rows[0])
    for c in CONTROLLERS:
        assert out[f"{c}_failed"] == 0.0
        assert out[f"{c}_keep_out_violation"] == 0.0
        assert out[f"{c}_final_error"] < 1e-3       # settling at 45 s
    cone = slew_keep_out(np.pi / 2, np.deg2rad(20.0))
    free = simulate_mpc(AttitudeMPC(rigid_spacecraft(J, WHEELS),
                                    solver="stagewise", rti=True,
                                    rate_max=0.038),
                        [1, 0, 0, 0], quat_from_axis_angle(
                            [1, 1, 0], np.pi / 2), t_final=30.0)
    assert cone.margin(free.trajectory.q).min() < -np.deg2rad(10.0)
    ds = serial.copy(deep=True)
    ds["keep_out_deg"] = ("case", np.full(4, 20.0))
    ds["nominal_keep_out_violation"][:] = [0.0, 1e-9, 1e-3, 0.02]
    nom, rob = summarise(ds)
    assert (nom.keep_out, rob.keep_out) == (2, 0)
    assert "| keep-out violations | 2 | 0 | – |" in robust_mc_table(ds)
    for bad in (-1.0, 50.0, float("nan")):
        with pytest.raises(InvalidValueError, match="keep_out_deg|keep-out"):
            robust_mc_params(1, keep_out_deg=bad)


def test_cli_refuses_a_nan_keep_out_in_one_line(tmp_path, capsys):
    """``adcs sweep robust --keep-out-deg nan``: one line naming the
    value as the user typed it, exit status 2, nothing written."""
    from adcs.cli import main

    out = tmp_path / "o"
    assert main(["sweep", "robust", "--keep-out-deg", "nan", "--samples",
                 "1", "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "adcs: error: keep_out_deg must be finite, got nan"]
    assert not out.exists()


def test_a_rate_margin_plans_below_the_bound_and_counts_against_it():
    """With ``rate_margin`` both MPCs plan the rate bound that fraction
    below it, and the violations are counted against the bound itself:
    planned at half of 0.04 rad/s, no plant gets near 0.04 (without the
    margin the nominal MPC passes it on this draw)."""
    rows = robust_mc_params(1, t_final=12.0, rate_max=0.04, rate_margin=0.5)
    assert rows[0]["rate_margin"] == 0.5
    half = robust_mc_case(**rows[0])
    full = robust_mc_case(**{**rows[0], "rate_margin": 0.0})
    assert half["nominal_rate_violation"] == 0.0
    assert half["robust_rate_violation"] == 0.0
    assert full["nominal_rate_violation"] > 1e-4
    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(InvalidValueError, match="rate_margin"):
            robust_mc_params(1, rate_max=0.04, rate_margin=bad)


def test_params_and_the_registered_sweep():
    rows = SWEEPS["robust"][1](True)
    assert len(rows) == 8 and rows[3]["draw"] == 3
    assert rows[0]["t_final"] == 30.0 and rows[0]["rate_max"] == 0.0
    assert len(SWEEPS["robust"][1](False)) == 200
    with pytest.raises(InvalidValueError, match="draws"):
        robust_mc_params(0)
    # `adcs sweep robust --rate-max 0.04 --rate-margin 0.05`: 60 s loops
    bound = SWEEPS["robust"][1](False, rate_max=0.04, rate_margin=0.05)
    assert (bound[0]["rate_max"], bound[0]["rate_margin"],
            bound[0]["t_final"]) == (0.04, 0.05, 60.0)
    assert SWEEPS["robust-basilisk"][1] is SWEEPS["robust"][1]
    wide = SWEEPS["robust"][1](True, tree_products=0.05)
    assert wide[0]["tree_products"] == 0.05
    for bad in (-0.01, 1.0, float("nan")):
        with pytest.raises(InvalidValueError, match="tree_products"):
            robust_mc_params(1, tree_products=bad)


def test_the_robust_tree_spans_the_products_when_asked():
    from adcs.robust_mc import robust_scenarios

    assert len(robust_scenarios(J)) == 9
    wide = robust_scenarios(J, 0.2, 0.05)
    assert len(wide) == 17
    np.testing.assert_array_equal(wide[0].inertia, J)
    # each product ±5 % of the scenario's largest moment
    off = sorted({round(float(s.inertia[0, 1] / np.diag(s.inertia).max()),
                        12) for s in wide[1:]})
    assert off == [-0.05, 0.05]
    diag = {tuple(np.round(np.diag(s.inertia) / np.diag(J), 12))
            for s in wide[1:]}
    assert diag == {(a, b, c) for a in (0.8, 1.2) for b in (0.8, 1.2)
                    for c in (0.8, 1.2)}
    for bad in (-0.05, 1.0, float("nan"), "wide", None):
        with pytest.raises(InvalidValueError, match="tree_products"):
            robust_scenarios(J, 0.2, bad)
    with pytest.raises(InvalidValueError, match="spread"):
        draw_plant(J, WHEELS, 0, 0, spread="wide")


def test_cli_sweep_robust_refuses_a_bad_margin(tmp_path, capsys):
    assert main(["sweep", "robust", "--quick", "--sync", "--rate-max",
                 "0.04", "--rate-margin", "1.5", "--out",
                 str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rate_margin" in err[0]


def test_cli_sweep_robust(tmp_path, capsys):
    assert main(["sweep", "robust", "--quick", "--sync", "--samples", "1",
                 "--no-progress", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "1 cases, 0 failed" in out
    assert (tmp_path / "robust.nc").exists()
    assert (tmp_path / "robust.png").exists()


def test_cli_sweep_robust_in_basilisk_without_basilisk(tmp_path, capsys,
                                                       monkeypatch):
    import adcs.basilisk

    monkeypatch.setattr(adcs.basilisk, "basilisk_available", lambda: False)
    assert main(["sweep", "robust-basilisk", "--quick", "--sync",
                 "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Basilisk is not installed" in err[0]


@pytest.mark.parametrize("seed, draw, steps", [(0, 5, 20), (1, 3, 6)])
def test_a_tree_spanning_the_products_flies_a_drawn_plant(seed, draw,
                                                          steps):
    """17 scenarios (the nominal craft, 1 ± 0.2 principal moments × ±5 %
    products) under the 0.04 rad/s rate bound on a drawn plant: every
    step's QP certified. Draw 5 of seed 0, step 14: the first polishes'
    active sets each broke a box and one step of the active-set method
    still broke one (KKT 1.34e-6, the step refused); draw 3 of seed 1,
    step 3: that step's point kept every box but had added one with the
    wrong sign (KKT 1.87e-6). The second step
    (`stagewise_cascade.polish_more`) meets both."""
    from adcs.robust_mc import robust_scenarios
    from ocp.mpc import RobustMPC

    scen = robust_scenarios(J, 0.2, 0.05)
    model = rigid_spacecraft(J, WHEELS)
    mpc = RobustMPC(model, scen, horizon=20, dt=0.5, rti=True,
                    rate_max=0.04)
    d = draw_plant(J, WHEELS, seed, draw)
    F = rigid_spacecraft(d.inertia, d.wheels).integrator(0.5)
    qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
    x = model.state([1.0, 0.0, 0.0, 0.0])
    for _ in range(steps):
        s = mpc.step(x, qf)
        assert s.status == "rti_step" and s.qp_kkt <= 1e-6
        x = np.asarray(F(x0=x, p=np.r_[s.u, 0, 0, 0])["xf"]).ravel()
