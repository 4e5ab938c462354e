"""Bad input at the public boundary: the toolbox's own error, every time.

Each class of mistake (None, a string, NaN, inf, a bool for a number, a
float for an index, a scalar for a vector, non-positive limits,
degenerate physics, unknown names) on each public entry point raises an
`AdcsError` (which also subclasses ValueError or TypeError); never a
NumPy or CasADi traceback, never a silent acceptance.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import allocation as al
import ocp
import thrusters as th
from adcs_common.exceptions import AdcsError, SolverError
from ocp.codegen import export_c
from ocp.mpc import AttitudeMPC

ARR = al.WheelArray.pyramid(h_max=1.0, m_max=0.1)
UNIT = th.six_thruster_unit()
MODEL = ocp.rigid_spacecraft(np.diag([3.0, 2.5, 3.5]), ARR)
Q0, Q1 = [1.0, 0, 0, 0], [0, 1.0, 0, 0]

#: entry point -> callable of the bad value, and the bad values it gets
PROBES = {
    "WheelArray.pyramid(h_max)": (
        lambda v: al.WheelArray.pyramid(h_max=v),
        [None, "abc", np.nan, np.inf, -1.0, 0.0, True]),
    "WheelArray.pyramid(delta)": (
        lambda v: al.WheelArray.pyramid(v), [None, "abc", np.nan, [1.0]]),
    "WheelArray.with_failed": (
        lambda v: ARR.with_failed(v),
        [None, "abc", np.nan, np.inf, 1.5, 1.0, True, 4, -1]),
    "WheelArray.from_axes": (
        lambda v: al.WheelArray.from_axes(v, normalize=True),
        [None, "abc", np.zeros((3, 4)), [[1.0, 0, 0]], np.full((3, 4),
                                                              np.nan)]),
    "min_norm_gains": (al.min_norm_gains, [None, "abc", 1.0, [1.0]]),
    "envelope(kind)": (lambda v: al.envelope(ARR, v),
                       [None, "abc", [1.0], 1.0]),
    "QPAllocator(weights)": (lambda v: al.QPAllocator(ARR, v),
                             ["abc", np.nan, -1.0, 0.0, [1.0, 2.0], True]),
    "QPAllocator(check_tol)": (lambda v: al.QPAllocator(ARR, check_tol=v),
                               [None, "abc", np.nan, -1.0, 0.0, 2.0]),
    "QPAllocator(solver)": (lambda v: al.QPAllocator(ARR, solver=v),
                            [None, "abc", 1.0, "casadi:nope"]),
    "QPAllocator(solver_options)": (
        lambda v: al.QPAllocator(ARR, solver_options=v),
        ["abc", 1.0, [1.0], True]),
    "QPAllocator.allocate(torque)": (
        lambda v: al.QPAllocator(ARR).allocate(v),
        [None, "abc", np.nan, 0.1, [0.1], [np.inf, 0, 0]]),
    "QPAllocator.allocate_fast(torque)": (
        lambda v: al.QPAllocator(ARR).allocate_fast(v),
        [None, "abc", np.nan, 0.1, [0.1], [np.inf, 0, 0]]),
    "QPAllocator.allocate(dt)": (
        lambda v: al.QPAllocator(ARR).allocate([0.1, 0, 0], np.zeros(4), v),
        ["abc", np.nan, -1.0, 0.0, True]),
    "six_thruster_unit(R)": (lambda v: th.six_thruster_unit(R=v),
                             [None, "abc", np.nan, -1.0, 0.0, True]),
    "DutyCycleAllocator(h_max)": (
        lambda v: th.DutyCycleAllocator(UNIT, 2.0, v),
        [None, "abc", np.nan, -1.0, 0.0, [1.0], True]),
    "DutyCycleAllocator(solver_options)": (
        lambda v: th.DutyCycleAllocator(UNIT, 2.0, 0.01,
                                        solver_options=v),
        ["abc", 1.0, [1.0], True]),
    "DutyCycleAllocator.solve(M)": (
        lambda v: th.DutyCycleAllocator(UNIT, 2.0, 0.01).solve(0.0, v),
        [None, "abc", 0.001, [0.001], [np.nan, 0.0]]),
    "rigid_spacecraft(inertia)": (
        lambda v: ocp.rigid_spacecraft(v, ARR),
        [None, "abc", np.nan, -1.0, np.eye(3) * 1e-300, np.ones((3, 3))]),
    "eigenaxis_slew(inertia)": (
        lambda v: ocp.eigenaxis_slew(v, Q0, Q1, wheels=ARR),
        [None, np.eye(3) * 1e-300, np.eye(3) * np.nan, -np.eye(3)]),
    "eigenaxis_slew(q0)": (
        lambda v: ocp.eigenaxis_slew(np.eye(3), v, Q1, wheels=ARR),
        [None, "abc", 1.0, [0, 0, 0, 0], [np.nan, 0, 0, 0], [1.0, 0]]),
    "time_optimal_slew(N)": (
        lambda v: ocp.time_optimal_slew(np.eye(3), Q0, Q1, wheels=ARR,
                                        N=v),
        [None, "abc", np.nan, 1, 2.5, True]),
    "time_optimal_slew(rate_max)": (
        lambda v: ocp.time_optimal_slew(np.eye(3), Q0, Q1, wheels=ARR,
                                        N=10, rate_max=v),
        ["abc", np.nan, -1.0, 0.0, 1e-300, 1e200]),
    "min_energy_slew(T)": (
        lambda v: ocp.min_energy_slew(np.eye(3), Q0, Q1, wheels=ARR, N=10,
                                      T=v),
        [None, "abc", np.nan, -1.0, 0.0, 1e200]),
    "AttitudeMPC(max_iter)": (
        lambda v: AttitudeMPC(MODEL, horizon=4, max_iter=v),
        [None, "abc", np.nan, np.inf, 0, 2.5, True]),
    "AttitudeMPC.step(x)": (
        lambda v: AttitudeMPC(MODEL, horizon=4).step(v, Q1),
        [None, "abc", np.zeros(11), np.r_[2.0, np.zeros(10)],
         np.full(11, np.nan), [1.0, 0.0]]),
    "export_c(mpc_variants)": (
        lambda v: export_c("/tmp/adcs-probe-export", wheels=ARR,
                           mpc_variants=v),
        [None, "mpc_step", ("mpc_stpe",), (1.0,)]),
    "quat_from_axis_angle": (lambda v: ocp.quat_from_axis_angle(v, 1.0),
                             [None, "abc", [0, 0, 0], [np.nan, 0, 0], 1.0]),
    "sign_matrix_gains": (lambda v: al.sign_matrix_gains(v, 0.7),
                          [None, "abc", [1.0], np.nan]),
    "pyramid_failure_gains": (
        lambda v: al.pyramid_failure_gains(v, 0.9, 0.7),
        [None, [1.0], 1.0, True, 4]),
    "LinearLaw.allocate": (lambda v: al.min_norm_law(ARR).allocate(v),
                           ["abc", None, [np.nan, 0, 0], [0.1]]),
    "orbit_rate": (ocp.orbit_rate, [None, "abc", -1.0, 0.0, 1e200]),
    "gravity_gradient_torque(w0)": (
        lambda v: ocp.gravity_gradient_torque(np.eye(3), [0, 0, 1], v),
        [None, "abc", [1.0], np.nan, -1.0, 1e200]),
    "SpacecraftModel.simulate(x0)": (
        lambda v: MODEL.simulate(v, [0.0, 1.0], np.zeros((1, 4))),
        [None, "abc", np.full(11, np.nan), np.full(11, 1e200)]),
    "quaternion_feedback_slew(natural_frequency)": (
        lambda v: ocp.quaternion_feedback_slew(
            np.eye(3), Q0, Q1, wheels=ARR, natural_frequency=v,
            t_final=5.0),
        [None, "abc", -1.0, 0.0, 1e200]),
    "compare_slews(angles_deg)": (
        lambda v: ocp.compare_slews(np.eye(3), ARR, [1, 0, 0], v),
        [None, "abc", [np.nan], -1.0]),
    # issue #23 item 14: the building blocks
    "conic_allocator_function(array)": (
        al.conic_allocator_function, [None, "abc", np.eye(3)]),
    "conic_allocator_function(...)(M)": (
        lambda v: al.conic_allocator_function(ARR)(v),
        [None, "abc", [np.nan, 0, 0], [np.inf, 0, 0], [0.1], 0.1]),
    "conic_allocator_function(dt)(h)": (
        lambda v: al.conic_allocator_function(ARR, dt=0.5)([0.1, 0, 0], v),
        [None, [np.nan, 0, 0, 0], [0.0]]),
    "unloading_law(unit)": (
        lambda v: th.unloading_law(v, 0.5, [0.0, 0.0, 0.0], 2.0),
        [None, "abc", ARR]),
    "reorientation_law(unit)": (
        lambda v: th.reorientation_law(v, 0.0, [0.0, 0.0]),
        [None, "abc"]),
    "DutyCycleAllocator(unit)": (
        lambda v: th.DutyCycleAllocator(v, 2.0, 0.01), [None, "abc", ARR]),
    "export_c(wheels)": (
        lambda v: export_c("/tmp/adcs-probe-export", wheels=v),
        [np.eye(3), "abc", UNIT]),
    "export_c(thrusters)": (
        lambda v: export_c("/tmp/adcs-probe-export", wheels=ARR,
                           thrusters=v),
        [np.eye(3), "abc", ARR]),
    "six_thruster_unit(center_of_mass)": (
        lambda v: th.six_thruster_unit(center_of_mass=v),
        [None, "abc", [np.nan, 0, 0], [1.0]]),
    "six_thruster_unit(**kwargs)": (
        lambda v: th.six_thruster_unit(**{v: 1}), ["bogus", "R0"]),
}
CASES = [(name, i) for name, (_, bad) in PROBES.items()
         for i in range(len(bad))]


@pytest.mark.parametrize("name, i", CASES,
                         ids=[f"{n}-{i}" for n, i in CASES])
def test_bad_input_gets_the_toolboxs_own_error(name, i):
    call, bad = PROBES[name]
    with pytest.raises(AdcsError) as info:
        call(bad[i])
    assert isinstance(info.value, (ValueError, TypeError, RuntimeError,
                                   SolverError))


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.none(), st.text(max_size=3), st.booleans(),
                 st.floats(allow_nan=True, allow_infinity=True),
                 st.lists(st.floats(), max_size=2)))
def test_random_bad_limits_never_escape_untyped(value):
    for build in (lambda v: al.WheelArray.pyramid(h_max=v, m_max=0.1),
                  lambda v: th.DutyCycleAllocator(UNIT, 2.0, v),
                  lambda v: al.QPAllocator(ARR).allocate([0.1, 0, 0],
                                                         np.zeros(4), v)):
        try:
            build(value)
        except AdcsError:
            pass


def test_tiny_capacities_and_huge_axes_are_valid_arrays():
    tiny = al.WheelArray.pyramid(h_max=1e-10, m_max=1e-10)
    env = al.envelope(tiny, "torque")          # not "rank 0, flat"
    assert env.inscribed_radius == pytest.approx(
        al.envelope(ARR, "torque").inscribed_radius * 1e-9, rel=1e-9)
    big = al.WheelArray.from_axes(np.eye(3) * 1e200, normalize=True)
    np.testing.assert_array_equal(big.axes, np.eye(3))


def test_the_wheel_function_reports_nan_as_its_status():
    """Where it cannot raise (buffer, ``call``, C), NaN in gives NaN out
    and a NaN violation: ``violation <= tol`` is false (documented)."""
    import casadi as ca

    f = al.conic_allocator_function(ARR)
    m, alpha, violation = f.call([ca.DM([np.nan, 0.0, 0.0])])
    assert np.isnan(float(violation))
    assert not float(violation) <= 1e-9
    assert np.all(np.isnan(np.asarray(m)))
    m, _, violation = f([0.01, 0.0, 0.0])          # a finite demand answers
    assert float(violation) <= 1e-9
