"""Bad input that used to escape (issue #23, items 13-16).

Each test reproduces one finding: before the fix it ran into an untyped
error, a hang, silent acceptance or exhausted memory; now the toolbox's
own error comes quickly.
"""

import os

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
    ({"solver": "sqpmethod"}, "nlpsol 'sqpmethod'.*allowed: .*max_iter"),
    ({"solver": "ipopt"}, "nlpsol 'ipopt'"),
    ({}, "solver='condensed' takes solver_options 'step_tol' and "
         "'anderson' only"),
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
                    solver="sqpmethod",
                    solver_options={"qpsol_options": {"bogus": 1}})
    with pytest.raises(InvalidValueError, match="must be a dict"):
        AttitudeMPC(load_spacecraft("meteor-m"), horizon=3,
                    solver_options=[("max_iter", 3)])


# ------------------------------------------------------------ item 15
def _axes_toml(n, seed=0):
    ax = np.random.default_rng(seed).normal(size=(n, 3))
    rows = ",".join("[%r,%r,%r]" % tuple(map(float, a)) for a in ax)
    return ("name = 'many'\ninertia = [1.0, 1.0, 1.0]\n[wheels]\n"
            f"h_max = 1.0\nm_max = 0.1\naxes = [{rows}]\n")


def test_ten_thousand_wheels_are_refused_quickly(tmp_path):
    """It loaded, then QPAllocator, export_c and bench needed 1.1 GiB
    (MemoryError), envelope/report/sweep ran past 150 s, AttitudeMPC
    raised std::bad_alloc."""
    import time

    from allocation import WheelArray
    from allocation.arrays import MAX_WHEELS
    from ocp.spacecraft import SpacecraftFileError, load_spacecraft

    path = tmp_path / "many.toml"
    path.write_text(_axes_toml(10_000))
    t0 = time.perf_counter()
    with pytest.raises(SpacecraftFileError, match="at most 64 wheels"):
        load_spacecraft(path)
    axes = np.random.default_rng(1).normal(size=(3, 10_000))
    with pytest.raises(InvalidValueError, match="at most 64 wheels"):
        WheelArray.from_axes(axes, h_max=1.0, m_max=0.1, normalize=True)
    assert time.perf_counter() - t0 < 2.0
    assert MAX_WHEELS == 64
    path.write_text(_axes_toml(MAX_WHEELS))
    assert load_spacecraft(path).wheels.n_wheels == MAX_WHEELS
    path.write_text(_axes_toml(MAX_WHEELS + 1))
    with pytest.raises(SpacecraftFileError, match="got 65"):
        load_spacecraft(path)


@pytest.mark.parametrize("kind", ["fifo", "devzero", "link-devzero",
                                  "too-big"])
def test_only_regular_files_under_the_cap_are_read(tmp_path, kind):
    """A FIFO named x.toml hung load_spacecraft; /dev/zero exhausted
    memory."""
    from ocp.spacecraft import SpacecraftFileError, load_spacecraft
    from ocp.spacecraft.toml_io import MAX_FILE_BYTES

    path = tmp_path / "x.toml"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "devzero":
        path = "/dev/zero"
    elif kind == "link-devzero":
        path.symlink_to("/dev/zero")
    else:
        path.write_text("# padding\n" * (MAX_FILE_BYTES // 10 + 1))
    match = "at most" if kind == "too-big" else "not a regular file"
    with pytest.raises(SpacecraftFileError, match=match):
        load_spacecraft(path)


def test_a_huge_integer_and_deep_nesting_are_file_errors():
    """10**400 gave OverflowError; 5,000 nested brackets RecursionError."""
    from ocp.spacecraft import SpacecraftFileError
    from ocp.spacecraft.toml_io import spacecraft_from_toml

    base = "name = 'a'\n[wheels]\nh_max = 1.0\nm_max = 0.1\n" \
           "orthogonal_pairs = {}\n"
    with pytest.raises(SpacecraftFileError, match=r"inertia.*finite"):
        spacecraft_from_toml(f"inertia = [1{'0' * 400}, 1, 1]\n" + base)
    with pytest.raises(SpacecraftFileError, match=r"h_max.*finite"):
        spacecraft_from_toml("inertia = [1, 1, 1]\n"
                             + base.replace("1.0", "1" + "0" * 400, 1))
    deep = "[" * 5000 + "1" + "]" * 5000
    with pytest.raises(SpacecraftFileError, match="nested too deeply"):
        spacecraft_from_toml(f"inertia = {deep}\n" + base)
    with pytest.raises(SpacecraftFileError, match="at most two deep"):
        spacecraft_from_toml("inertia = [[[1.0]]]\n" + base)
    with pytest.raises(SpacecraftFileError, match="at most"):
        spacecraft_from_toml("# x\n" * (1 << 19))


# ------------------------------------------------------------ item 16
def test_printing_to_a_full_disk_is_one_line_and_status_2():
    """`adcs spacecraft demo > /dev/full` gave an OSError traceback."""
    import subprocess
    import sys

    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    with open("/dev/full", "w") as full:
        run = subprocess.run(
            [sys.executable, "-c", "import sys; from adcs.cli import main; "
             "sys.exit(main(['spacecraft', 'meteor-m']))"],
            stdout=full, stderr=subprocess.PIPE, text=True, timeout=60)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("adcs: error:")
    assert "Traceback" not in run.stderr


NASTY = "sat\x00\x01\t\n\r\x1b[31m\x7f\"\\ ü"


def test_names_with_control_characters_round_trip(tmp_path):
    """Spacecraft.save wrote files it could not read back."""
    from allocation import WheelArray
    from ocp.spacecraft import Spacecraft, load_spacecraft
    from thrusters import six_thruster_unit

    import dataclasses

    wheels = dataclasses.replace(
        WheelArray.pyramid(*ARR_ARGS, h_max=1.0, m_max=0.1),
        names=("a\x00", "b\n", "c\x7f", "d\\\""))
    unit = six_thruster_unit(names=tuple(f"T{i}\x1b" for i in range(6)))
    sc = Spacecraft(NASTY, np.diag([3.0, 2.5, 3.5]), wheels, unit,
                    description=NASTY[::-1])
    path = tmp_path / "nasty.toml"
    sc.save(path)
    back = load_spacecraft(path)
    assert back.name == sc.name and back.description == sc.description
    assert back.wheels.names == wheels.names
    assert back.thrusters.names == unit.names


def test_a_name_no_file_can_hold_is_refused(tmp_path):
    from adcs_common.exceptions import AdcsError
    from allocation import WheelArray
    from ocp.spacecraft import Spacecraft

    sc = Spacecraft("bad\ud800", np.eye(3),
                    WheelArray.pyramid(*ARR_ARGS, h_max=1.0, m_max=0.1))
    with pytest.raises(AdcsError, match="surrogate"):
        sc.save(tmp_path / "bad.toml")
    assert not (tmp_path / "bad.toml").exists()
