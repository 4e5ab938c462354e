"""Inside Basilisk: its rwMotorTorque against our laws, our module in it."""

import numpy as np
import pytest

pytest.importorskip(
    "Basilisk", reason='Basilisk is an optional extra: pip install -e '
    '".[basilisk]" (the bsk package)')

from Basilisk.architecture import messaging  # noqa: E402
from Basilisk.fswAlgorithms import rwMotorTorque  # noqa: E402
from Basilisk.utilities import SimulationBaseClass, macros  # noqa: E402

from adcs.basilisk.convert import (  # noqa: E402
    gs_matrix,
    mrp_to_quaternion,
    quaternion_to_mrp,
)
from adcs.basilisk.modules import WheelQPAllocatorModule  # noqa: E402
from allocation import QPAllocator, min_norm_gains  # noqa: E402
from ocp.spacecraft import load_spacecraft  # noqa: E402

ARRAY = load_spacecraft("meteor-m").wheels
DEMANDS = np.random.default_rng(8).normal(scale=0.15, size=(6, 3))


def one_step(module_of, L, avail=None, period=0.5,
             output=("rwMotorTorqueOutMsg", "motorTorque", 4)):
    """Run one step of a module on the torque request ``L``.

    ``output``: the module's output message, its field, entries kept.
    """
    sim = SimulationBaseClass.SimBaseClass()
    sim.CreateNewProcess("p").addTask(sim.CreateNewTask(
        "t", macros.sec2nano(period)))
    cmd = messaging.CmdTorqueBodyMsgPayload()
    cmd.torqueRequestBody = [float(v) for v in L]
    cmd_msg = messaging.CmdTorqueBodyMsg().write(cmd)
    mod, keep = module_of(cmd_msg)
    if avail is not None:
        a = messaging.RWAvailabilityMsgPayload()
        a.wheelAvailability = [messaging.AVAILABLE if ok else
                               messaging.UNAVAILABLE for ok in avail]
        keep.append(messaging.RWAvailabilityMsg().write(a))
        mod.rwAvailInMsg.subscribeTo(keep[-1])
    sim.AddModelToTask("t", mod)
    msg, field, n = output
    rec = getattr(mod, msg).recorder()
    sim.AddModelToTask("t", rec)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(period))
    sim.ExecuteSimulation()
    return np.asarray(getattr(rec, field))[-1][:n]


def basilisk_min_norm(cmd_msg):
    mod = rwMotorTorque.rwMotorTorque()
    mod.ModelTag = "rwMotorTorque"
    mod.controlAxes_B = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    cfg = messaging.RWArrayConfigMsgPayload()
    cfg.GsMatrix_B = gs_matrix(ARRAY)
    cfg.JsList = [0.1] * ARRAY.n_wheels
    cfg.numRW = ARRAY.n_wheels
    cfg_msg = messaging.RWArrayConfigMsg().write(cfg)
    mod.vehControlInMsg.subscribeTo(cmd_msg)
    mod.rwParamsInMsg.subscribeTo(cfg_msg)
    return mod, [cfg_msg]


@pytest.mark.parametrize("failed", [None, 1])
def test_rw_motor_torque_is_our_minimum_norm_law(failed):
    """u_s = m of the min-norm law on A m = -L_r (nominal, one failed)."""
    arr = ARRAY if failed is None else ARRAY.with_failed(failed)
    G = min_norm_gains(arr)
    avail = None if failed is None else [i != failed for i in range(4)]
    for L in DEMANDS:
        us = one_step(basilisk_min_norm, L, avail)
        np.testing.assert_allclose(us, G @ (-L), atol=1e-12, rtol=0)
        if failed is not None:
            assert us[failed] == 0.0


@pytest.mark.parametrize("failed", [None, 2])
def test_our_module_inside_basilisk_equals_the_allocator(failed):
    direct = QPAllocator(ARRAY if failed is None
                         else ARRAY.with_failed(failed))
    avail = None if failed is None else [i != failed for i in range(4)]

    def ours(cmd_msg):
        mod = WheelQPAllocatorModule(ARRAY)
        mod.ModelTag = "wheelQP"
        mod.vehControlInMsg.subscribeTo(cmd_msg)
        return mod, []

    saturated = 0
    for L in np.r_[DEMANDS, 4 * DEMANDS]:
        m = one_step(ours, L, avail)
        ref = direct.allocate(-L)
        np.testing.assert_allclose(m, ref.torques, atol=1e-12, rtol=0)
        saturated += ref.status == "saturated"
    assert saturated > 0        # bounds active: the QP, not a closed form


def test_mrp_and_quaternion_round_trip():
    from adcs_common.quaternion import quat_from_axis_angle

    q = quat_from_axis_angle([1.0, -2.0, 0.5], 2.5)
    s = quaternion_to_mrp(q)
    assert np.linalg.norm(s) <= 1.0
    np.testing.assert_allclose(mrp_to_quaternion(s), q, atol=1e-15)
    np.testing.assert_allclose(4 * np.arctan(np.linalg.norm(s)), 2.5)


@pytest.fixture(scope="module")
def saturated():
    from adcs.basilisk.scenarios import compare_loops

    return compare_loops(t_final=120.0)


def test_saturated_slew_ours_keeps_the_torque_direction(saturated):
    """Demands beyond the wheels: clipping turns the torque, ours not."""
    clipped, ours = saturated["rwMotorTorque"], saturated["QPAllocator"]
    assert np.degrees(clipped.direction_error.max()) > 20.0
    assert np.degrees(ours.direction_error.max()) < 1e-4
    # both within the wheels' torque limit, the slew under way
    for r in (clipped, ours):
        assert np.abs(r.wheel_torque).max() <= 0.2 + 1e-12
        assert np.degrees(r.pointing_error[-1]) < 20.0
    assert clipped.summary()["max direction error [deg]"] > 20.0


def test_a_wheel_failing_mid_slew_is_dropped_by_both_allocators():
    from adcs.basilisk.scenarios import compare_loops

    runs = compare_loops(t_final=60.0, fail_wheel=1, t_fail=10.0)
    k = np.searchsorted(runs["QPAllocator"].t, 11.0)
    for r in runs.values():
        assert np.all(r.wheel_torque[k:, 1] == 0.0)
    assert np.degrees(runs["QPAllocator"].direction_error.max()) < 1e-4
    assert np.degrees(runs["rwMotorTorque"].direction_error.max()) > 20.0


def test_loop_figure_and_bad_arguments(saturated):
    import matplotlib

    matplotlib.use("Agg")
    from adcs.basilisk.plots import plot_loops
    from adcs.basilisk.scenarios import run_loop
    from adcs_common.exceptions import InvalidValueError

    fig = plot_loops(saturated)
    assert len(fig.axes) == 4
    with pytest.raises(InvalidValueError, match="allocator"):
        run_loop("nosuch")
    with pytest.raises(InvalidValueError, match="deg2rad"):
        run_loop("QPAllocator", angle=40.0)
    with pytest.raises(InvalidValueError, match="t_fail"):
        run_loop("QPAllocator", fail_wheel=1, t_fail=500.0, t_final=100.0)


def test_identical_motion_in_basilisk_and_ours_free_of_control():
    """The hub/rotor mapping of convert: same motion under motor torques."""
    from Basilisk.architecture import messaging as msg
    from adcs.basilisk.convert import hub_inertia, rotor_momenta
    from adcs.basilisk.scenarios import spacecraft_task
    from allocation import WheelArray
    from ocp import rigid_spacecraft

    J = np.diag([3.0, 2.5, 3.5])
    wheels = WheelArray.pyramid(h_max=0.2, m_max=0.05)
    np.testing.assert_allclose(hub_inertia(J, wheels, 1e-3) - J,
                               1e-3 * wheels.axes @ wheels.axes.T)
    sim = SimulationBaseClass.SimBaseClass()
    sc, rw, nav = spacecraft_task(sim, J, wheels, 1e-3, 0.01)
    w0 = np.array([0.02, -0.01, 0.03])
    sc.hub.omega_BN_BInit = [[v] for v in w0]
    u = [0.01, -0.02, 0.005, 0.0]
    cmd = msg.ArrayMotorTorqueMsgPayload()
    cmd.motorTorque = u + [0.0] * (msg.MAX_EFF_CNT - 4)
    cmd_msg = msg.ArrayMotorTorqueMsg().write(cmd)
    rw.rwMotorCmdInMsg.subscribeTo(cmd_msg)
    rec = sc.scStateOutMsg.recorder()
    speeds = rw.rwSpeedOutMsg.recorder()
    sim.AddModelToTask("dyn", rec)
    sim.AddModelToTask("dyn", speeds)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(10.0))
    sim.ExecuteSimulation()
    model = rigid_spacecraft(J, wheels)
    x0 = model.state([1, 0, 0, 0], w0, rotor_momenta(wheels, 1e-3,
                                                     np.zeros(4), w0))
    xf = np.asarray(model.integrator(10.0)(x0=x0, p=np.r_[u, 0, 0, 0])[
        "xf"]).ravel()
    np.testing.assert_allclose(mrp_to_quaternion(rec.sigma_BN[-1]), xf[:4],
                               atol=1e-7)
    np.testing.assert_allclose(rec.omega_BN_B[-1], xf[4:7], atol=1e-8)
    np.testing.assert_allclose(
        rotor_momenta(wheels, 1e-3, speeds.wheelSpeeds[-1][:4],
                      rec.omega_BN_B[-1]), xf[7:], atol=1e-9)


def test_mpc_slew_in_basilisk_matches_our_simulation():
    from adcs.basilisk.mpc_scenario import mpc_slew

    s = mpc_slew(t_final=40.0).summary()      # settling: 0.0014° left
    assert s["final error, Basilisk [deg]"] == pytest.approx(
        s["final error, ours [deg]"], rel=1e-3)
    assert s["final error, ours [deg]"] < 0.01
    assert s["max |Δ error| [deg]"] < 1e-2
    assert s["torque bound excess, Basilisk [N·m]"] <= 1e-12
    assert s["momentum bound excess, Basilisk [N·m·s]"] <= 1e-12


def test_thruster_duty_module_equals_the_allocator():
    from adcs.basilisk.modules import ThrusterDutyModule
    from thrusters import DutyCycleAllocator, six_thruster_unit

    direct = DutyCycleAllocator(six_thruster_unit(), 2.0, 1e3,
                                tracking="weighted")
    def duty_module(cmd_msg):
        mod = ThrusterDutyModule(DutyCycleAllocator(
            six_thruster_unit(), 2.0, 1e3, tracking="weighted"))
        mod.ModelTag = "duty"
        mod.cmdTorqueInMsg.subscribeTo(cmd_msg)
        return mod, []

    for L in [np.array([0.02, 0.0, -0.01]), np.array([0.3, 0.1, 0.2])]:
        on = one_step(duty_module, L, period=2.0,
                      output=("onTimeOutMsg", "OnTimeRequest", 6))
        ref = direct.solve(0.0, L[[0, 2]])
        np.testing.assert_allclose(on, 2.0 * ref.duty, atol=1e-12, rtol=0)


def test_reorientation_with_the_unit_ours_leaves_less_delta_v():
    """[4]'s unit in Basilisk: the QP's zero net thrust vs the mapping."""
    from adcs.basilisk.thruster_scenario import compare_reorientation

    runs = compare_reorientation(t_final=60.0)
    fsw, ours = runs["thrForceMapping"], runs["DutyCycleAllocator"]
    for r in runs.values():
        assert np.degrees(r.pointing_error[-1]) < 5.0       # from 30°
        assert np.all(r.on_time >= 0.0) and np.all(r.on_time <= 2.0)
    assert ours.summary()["residual |Δv| [m/s]"] < \
        fsw.summary()["residual |Δv| [m/s]"]
    assert ours.on_time.sum() < fsw.on_time.sum()


def test_scenarios_take_the_users_spacecraft(tmp_path):
    """A TOML file of one's own reaches the Basilisk scenarios."""
    from adcs.basilisk.mpc_scenario import mpc_slew
    from adcs.basilisk.thruster_scenario import reorientation
    from adcs_common.exceptions import InvalidValueError
    from ocp.spacecraft import load_spacecraft

    path = tmp_path / "sat.toml"
    path.write_text(load_spacecraft("demo").to_toml())
    s = mpc_slew(spacecraft=path, angle=np.deg2rad(20.0),
                 t_final=10.0).summary()
    assert s["torque bound excess, Basilisk [N·m]"] <= 1e-12
    run = reorientation("DutyCycleAllocator", spacecraft=path,
                        t_final=10.0)
    assert np.all(run.on_time >= 0.0)
    with pytest.raises(InvalidValueError, match="no thrusters"):
        reorientation("DutyCycleAllocator", spacecraft="meteor-m")


# ------------------------------------------- faults of the modules (#23.12)
def test_module_constructors_refuse_bad_arguments():
    from adcs.basilisk.modules import AttitudeMPCModule, ThrusterDutyModule
    from adcs_common.exceptions import (
        AdcsError,
        InvalidValueError,
        SolverNotFound,
    )

    for kw, name in (({"dt": 0.0}, "dt"), ({"dt": -0.5}, "dt"),
                     ({"dt": float("nan")}, "dt"), ({"Js": -0.1}, "Js"),
                     ({"Js": [0.1, 0.1]}, "Js")):
        with pytest.raises(AdcsError, match=name):
            WheelQPAllocatorModule(ARRAY, **kw)
    with pytest.raises(SolverNotFound, match="bogus"):
        WheelQPAllocatorModule(ARRAY, solver="bogus")
    with pytest.raises(InvalidValueError, match="mpc"):
        AttitudeMPCModule(None, [1.0, 0.0, 0.0, 0.0], 1e-3)
    with pytest.raises(InvalidValueError, match="allocator"):
        ThrusterDutyModule(None)


def _kept(factory, subscribe=True):
    """A `one_step` module builder that keeps the module in ``mods``."""
    mods = []

    def build(cmd_msg):
        mod = factory()
        mod.ModelTag = "under_test"
        if subscribe:
            getattr(mod, "vehControlInMsg", getattr(
                mod, "cmdTorqueInMsg", None)).subscribeTo(cmd_msg)
        mods.append(mod)
        return mod, []
    return build, mods


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_a_nan_or_inf_request_gives_zero_torques_and_a_status(bad):
    """Before: RuntimeError: SWIG director method error."""
    from adcs.basilisk.modules import INVALID_INPUT, OK

    build, mods = _kept(lambda: WheelQPAllocatorModule(ARRAY))
    m = one_step(build, [0.01, bad, 0.0])
    assert np.all(m == 0.0)
    assert mods[0].status == INVALID_INPUT and mods[0].last is None
    assert "torqueRequestBody" in mods[0].fault and mods[0].faults >= 1
    build, mods = _kept(lambda: WheelQPAllocatorModule(ARRAY))
    assert np.any(one_step(build, [0.01, -0.02, 0.0]) != 0.0)
    assert mods[0].status == OK


def test_every_wheel_unavailable_gives_zero_torques_and_a_status():
    from adcs.basilisk.modules import NO_WHEELS

    build, mods = _kept(lambda: WheelQPAllocatorModule(ARRAY))
    m = one_step(build, [0.01, -0.02, 0.0], avail=[False] * 4)
    assert np.all(m == 0.0) and mods[0].status == NO_WHEELS
    build, mods = _kept(lambda: WheelQPAllocatorModule(ARRAY))
    m = one_step(build, [0.01, -0.02, 0.0],     # two left: no 3-D span
                 avail=[True, False, True, False])
    assert np.all(m == 0.0) and mods[0].status == NO_WHEELS


def test_an_unsubscribed_reader_gives_zero_torques_and_a_status():
    from adcs.basilisk.modules import UNSUBSCRIBED

    build, mods = _kept(lambda: WheelQPAllocatorModule(ARRAY),
                        subscribe=False)
    m = one_step(build, [0.01, -0.02, 0.0])
    assert np.all(m == 0.0) and mods[0].status == UNSUBSCRIBED
    assert "vehControlInMsg" in mods[0].fault


def test_the_thruster_module_answers_nan_with_zero_on_times():
    from adcs.basilisk.modules import INVALID_INPUT, UNSUBSCRIBED
    from adcs.basilisk.modules import ThrusterDutyModule
    from thrusters import DutyCycleAllocator, six_thruster_unit

    def make():
        return ThrusterDutyModule(DutyCycleAllocator(
            six_thruster_unit(), 2.0, 1e3, tracking="weighted"))

    for subscribe, L, status in ((True, [float("nan"), 0.0, 0.01],
                                  INVALID_INPUT),
                                 (False, [0.01, 0.0, 0.01], UNSUBSCRIBED)):
        build, mods = _kept(make, subscribe)
        on = one_step(build, L, period=2.0,
                      output=("onTimeOutMsg", "OnTimeRequest", 6))
        assert np.all(on == 0.0) and mods[0].status == status


def test_the_mpc_module_without_navigation_writes_zero_torques():
    from adcs.basilisk.modules import UNSUBSCRIBED, AttitudeMPCModule
    from ocp.mpc import AttitudeMPC

    craft = load_spacecraft("demo")
    build, mods = _kept(lambda: AttitudeMPCModule(
        AttitudeMPC(craft, horizon=4, rti=True), [0.0, 1.0, 0.0, 0.0],
        1e-3), subscribe=False)
    m = one_step(build, [0.0, 0.0, 0.0])
    assert np.all(m == 0.0) and mods[0].status == UNSUBSCRIBED
    assert "attNavInMsg" in mods[0].fault and mods[0].steps == []
