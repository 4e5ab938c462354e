"""Bad input that used to escape (issue #23, items 13-16).

Each test reproduces one finding: before the fix it ran into an untyped
error, a hang, silent acceptance or exhausted memory; now the toolbox's
own error comes quickly.
"""

import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from adcs_common.qp import available_solvers

ARR_ARGS = (np.deg2rad(55), np.deg2rad(45))


@pytest.fixture(scope="module")
def pyramid():
    from allocation import WheelArray

    return WheelArray.pyramid(*ARR_ARGS, h_max=4.0, m_max=0.2)


# ------------------------------------------------------------ item 13
QP_NAMES = [n for n in ("osqp", "daqp", "casadi:qrqp", "casadi:osqp",
                        "casadi:daqp", "qpsolvers:clarabel", "piqp",
                        "quadprog", "proxqp", "qpsolvers:osqp")
            if n in available_solvers()]


@pytest.mark.parametrize("solver", QP_NAMES)
def test_unknown_qp_option_refused_at_construction(pyramid, solver):
    """daqp and piqp ignored it; osqp, qpsolvers and CasADi raised an
    untyped error at the first call."""
    from allocation import QPAllocator

    with pytest.raises(InvalidValueError, match=r"bogus.*allowed: .*\w"):
        QPAllocator(pyramid, solver=solver, solver_options={"bogus": 1})


@pytest.mark.parametrize("solver, options", [
    ("osqp", {"eps_abs": 1e-8, "accept_inaccurate": True}),
    ("daqp", {"primal_tol": 1e-9}),
    ("casadi:qrqp", {"max_iter": 500}),
    ("casadi:osqp", {"osqp": {"eps_abs": 1e-8}}),
])
def test_known_qp_options_still_taken(pyramid, solver, options):
    from allocation import QPAllocator

    if solver not in available_solvers():
        pytest.skip(f"{solver} not installed")
    res = QPAllocator(pyramid, solver=solver,
                      solver_options=options).allocate([0.1, 0.0, 0.0])
    assert res.status == "optimal"


def test_nested_and_typed_casadi_options_refused(pyramid):
    from allocation import QPAllocator

    with pytest.raises(InvalidValueError, match="casadi:osqp"):
        QPAllocator(pyramid, solver="casadi:osqp",
                    solver_options={"osqp": {"bogus": 1}})
    with pytest.raises(InvalidValueError, match="max_iter"):
        QPAllocator(pyramid, solver="casadi:qrqp",
                    solver_options={"max_iter": "many"})


def test_duty_cycle_allocator_checks_options():
    from thrusters import DutyCycleAllocator, six_thruster_unit

    with pytest.raises(InvalidValueError, match="bogus.*allowed"):
        DutyCycleAllocator(six_thruster_unit(), 10.0, 0.012, solver="daqp",
                           solver_options={"bogus": 1})


@pytest.mark.parametrize("kwargs, match", [
    ({}, "nlpsol 'sqpmethod'.*allowed: .*max_iter"),
    ({"solver": "ipopt"}, "nlpsol 'ipopt'"),
])
def test_mpc_unknown_option_refused(kwargs, match):
    from ocp.mpc import AttitudeMPC
    from ocp.spacecraft import load_spacecraft

    with pytest.raises(InvalidValueError, match=match):
        AttitudeMPC(load_spacecraft("meteor-m"), horizon=3,
                    solver_options={"bogus": 1}, **kwargs)


def test_mpc_nested_qpsol_option_refused():
    from ocp.mpc import AttitudeMPC
    from ocp.spacecraft import load_spacecraft

    with pytest.raises(InvalidValueError, match="qpsol 'qrqp'.*allowed"):
        AttitudeMPC(load_spacecraft("meteor-m"), horizon=3,
                    solver_options={"qpsol_options": {"bogus": 1}})
    with pytest.raises(InvalidValueError, match="must be a dict"):
        AttitudeMPC(load_spacecraft("meteor-m"), horizon=3,
                    solver_options=[("max_iter", 3)])
