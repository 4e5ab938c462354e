"""One spacecraft definition: Python, TOML files, the catalogue."""

import numpy as np
import pytest

from allocation import WheelArray
from ocp import eigenaxis_slew, rigid_spacecraft, time_optimal_slew
from ocp.missions.four_wheel_lagrange import FOUR_WHEEL_INERTIA
from ocp.mpc import AttitudeMPC
from ocp.slews.compare import (
    METEOR_M_INERTIA,
    four_wheel_slew_spacecraft,
    meteor_m_spacecraft,
)
from ocp.spacecraft import (
    Spacecraft,
    SpacecraftFileError,
    list_spacecraft,
    load_spacecraft,
    spacecraft_from_toml,
)
from thrusters import six_thruster_unit

MY_SAT = """
name = "my-sat"
inertia = [[120.0, 1.2, 0.0], [1.2, 95.0, 0.0], [0.0, 0.0, 80.0]]
[wheels]
pyramid = { delta_deg = 55.0, gamma_deg = 45.0 }
h_max = 4.0
m_max = 0.2
failed = [2]
[thrusters]
kind = "six_thruster_unit"
R = 0.25
L = 0.3
thrust = 0.5
"""


def test_the_issue_example_file_loads_with_wheel_2_failed():
    sc = spacecraft_from_toml(MY_SAT)
    assert sc.name == "my-sat"
    np.testing.assert_array_equal(sc.inertia[0], [120.0, 1.2, 0.0])
    assert sc.wheels.failed == (1,)            # wheel 2, 0-based 1
    ref = WheelArray.pyramid(np.deg2rad(55), np.deg2rad(45), h_max=4.0,
                             m_max=0.2)
    np.testing.assert_array_equal(sc.wheels.axes, ref.axes)
    np.testing.assert_array_equal(sc.thrusters.torque_matrix(),
                                  six_thruster_unit().torque_matrix())


def test_a_diagonal_inertia_and_per_wheel_capacities():
    sc = spacecraft_from_toml("""
name = "d"
inertia = [10.0, 20.0, 30.0]
[wheels]
axes = [[2, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]
h_max = [1.0, 2.0, 3.0, 4.0]
m_max = 0.1
""")
    np.testing.assert_array_equal(sc.inertia, np.diag([10.0, 20.0, 30.0]))
    np.testing.assert_array_equal(sc.wheels.h_max, [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_allclose(sc.wheels.axes[:, 3], np.ones(3) / 3**0.5,
                               rtol=1e-15)
    assert sc.thrusters is None


@pytest.mark.parametrize("name", sorted(list_spacecraft()))
def test_every_built_in_round_trips_through_toml(name, tmp_path):
    sc = load_spacecraft(name)
    path = tmp_path / f"{name}.toml"
    sc.save(path)
    back = load_spacecraft(path)
    assert back.name == sc.name and back.description == sc.description
    np.testing.assert_array_equal(back.inertia, sc.inertia)
    np.testing.assert_array_equal(back.wheels.axes, sc.wheels.axes)
    np.testing.assert_array_equal(back.wheels.h_max, sc.wheels.h_max)
    np.testing.assert_array_equal(back.wheels.m_max, sc.wheels.m_max)
    assert back.wheels.failed == sc.wheels.failed
    if sc.thrusters is not None:
        np.testing.assert_allclose(back.thrusters.torque_matrix(),
                                   sc.thrusters.torque_matrix(),
                                   rtol=1e-15, atol=1e-18)
        assert back.thrusters.pairs == sc.thrusters.pairs


def test_catalogue_equals_what_the_code_used():
    J, wheels = meteor_m_spacecraft()
    mm = load_spacecraft("Meteor-M")             # names are case-blind
    np.testing.assert_array_equal(mm.inertia, METEOR_M_INERTIA)
    np.testing.assert_array_equal(mm.wheels.axes, wheels.axes)
    np.testing.assert_array_equal(mm.wheels.h_max, wheels.h_max)
    J4, w4 = four_wheel_slew_spacecraft()
    fw = load_spacecraft("four-wheel")
    np.testing.assert_allclose(fw.inertia, J4, rtol=1e-15, atol=0)
    np.testing.assert_allclose(fw.wheels.axes, w4.axes, atol=1e-16)
    np.testing.assert_array_equal(fw.wheels.m_max, w4.m_max)
    assert not np.allclose(fw.inertia, FOUR_WHEEL_INERTIA)  # rotors added
    demo = load_spacecraft("demo")
    np.testing.assert_array_equal(demo.inertia, np.diag([3.0, 2.5, 3.5]))
    np.testing.assert_array_equal(
        demo.wheels.axes, WheelArray.pyramid(h_max=0.2, m_max=0.05).axes)
    np.testing.assert_array_equal(demo.thrusters.torque_matrix(),
                                  six_thruster_unit().torque_matrix())


def test_bilimoria_wie_craft_gives_the_benchmark_time():
    sc = load_spacecraft("bilimoria-wie")
    traj = time_optimal_slew(sc, [1, 0, 0, 0], [0, 1, 0, 0], N=40)
    assert traj.success
    assert traj.T == pytest.approx(3.2430, abs=3e-3)   # paper: 3.2430 s


def test_every_tool_takes_a_spacecraft():
    sc = spacecraft_from_toml(MY_SAT)
    model = rigid_spacecraft(sc)
    assert model.n_wheels == 4 and model.thrusters is not None
    ref = rigid_spacecraft(sc.inertia, sc.wheels, thrusters=sc.thrusters)
    x = model.state([1, 0, 0, 0], [0.01, -0.02, 0.03], [0.1, 0, -0.2, 0.3])
    u = np.r_[0.05, 0.0, -0.1, 0.02, np.full(6, 0.3)]
    np.testing.assert_array_equal(model.dynamics(x, u, np.zeros(3)),
                                  ref.dynamics(x, u, np.zeros(3)))
    qf = [np.cos(0.5), np.sin(0.5), 0, 0]
    assert eigenaxis_slew(sc, [1, 0, 0, 0], qf).T == pytest.approx(
        eigenaxis_slew(sc.inertia, [1, 0, 0, 0], qf, wheels=sc.wheels).T,
        rel=1e-15)
    mpc = AttitudeMPC(sc, horizon=5)
    assert mpc.model.n_wheels == 4
    with pytest.raises(ValueError, match="Spacecraft"):
        rigid_spacecraft(sc, sc.wheels)


def test_rate_limit_of_the_craft_reaches_the_slew():
    base = load_spacecraft("demo")
    slow = Spacecraft(base.name, base.inertia, base.wheels,
                      rate_max=np.deg2rad(1.0))
    qf = [np.cos(0.5), np.sin(0.5), 0, 0]
    t_fast = eigenaxis_slew(base, [1, 0, 0, 0], qf).T
    t_slow = eigenaxis_slew(slow, [1, 0, 0, 0], qf)
    assert t_slow.T > t_fast
    assert t_slow.peak_rate == pytest.approx(np.deg2rad(1.0), rel=1e-9)


BAD = [
    ("", "not valid TOML", "name = \n"),
    ("inertia", "missing", 'name = "x"\n[wheels]\naxes=[[1,0,0]]\n'
     "h_max=1\nm_max=1\n"),
    ("inertia", "positive definite", 'name = "x"\ninertia = [1, -2, 3]\n'
     "[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max=1\nm_max=1\n"),
    ("inertia", "symmetric", 'name = "x"\ninertia = [[1, 2, 0], [0, 1, 0],'
     " [0, 0, 1]]\n[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max=1\n"
     "m_max=1\n"),
    ("wheels.axes", "zero spin axis", 'name = "x"\ninertia = [1, 2, 3]\n'
     "[wheels]\naxes=[[1,0,0],[0,0,0],[0,0,1]]\nh_max=1\nm_max=1\n"),
    ("wheels.failed", "out of range", 'name = "x"\ninertia = [1, 2, 3]\n'
     "[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max=1\nm_max=1\n"
     "failed = [4]\n"),
    ("wheels.failed", "numbers", 'name = "x"\ninertia = [1, 2, 3]\n'
     "[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max=1\nm_max=1\n"
     "failed = [1.5]\n"),
    ("thrusters.kind", "unknown thruster kind", 'name = "x"\n'
     "inertia = [1, 2, 3]\n[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\n"
     'h_max=1\nm_max=1\n[thrusters]\nkind = "ion"\n'),
    ("wheels.m_max", "missing", 'name = "x"\ninertia = [1, 2, 3]\n'
     "[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max=1\n"),
    ("wheels", "m_max must be positive", 'name = "x"\ninertia = [1, 2, 3]\n'
     "[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max=1\nm_max=-1\n"),
    ("wheels.h_max", "must be a number", 'name = "x"\ninertia = [1, 2, 3]\n'
     '[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max="big"\nm_max=1\n'),
    ("", "unknown key", 'name = "x"\nmass = 3\ninertia = [1, 2, 3]\n'
     "[wheels]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\nh_max=1\nm_max=1\n"),
    ("wheels", "exactly one layout", 'name = "x"\ninertia = [1, 2, 3]\n'
     "[wheels]\nh_max=1\nm_max=1\n"),
]


@pytest.mark.parametrize("key, problem, text", BAD,
                         ids=[f"{k or 'file'}-{p}" for k, p, _ in BAD])
def test_a_bad_file_gets_one_error_naming_the_key(key, problem, text):
    with pytest.raises(SpacecraftFileError, match=problem) as info:
        spacecraft_from_toml(text, "my.toml")
    assert info.value.key == key
    assert str(info.value).startswith("my.toml: ")


def test_unknown_names_and_unreadable_files(tmp_path):
    with pytest.raises(SpacecraftFileError, match="built-ins: "):
        load_spacecraft("no-such-craft")
    with pytest.raises(SpacecraftFileError, match="cannot be read"):
        load_spacecraft(tmp_path / "missing.toml")
    with pytest.raises(SpacecraftFileError, match="catalogue name"):
        load_spacecraft(None)
    with pytest.raises(SpacecraftFileError, match="is a folder"):
        load_spacecraft("demo").save(tmp_path)


@pytest.mark.parametrize("field, value, match", [
    ("inertia", np.diag([1.0, np.nan, 1.0]), "finite"),
    ("wheels", "pyramid", "WheelArray"),
    ("rate_max", -1.0, "rate_max"),
    ("name", "", "name"),
])
def test_spacecraft_checks_its_fields(field, value, match):
    kw = dict(name="x", inertia=np.eye(3),
              wheels=WheelArray.pyramid(h_max=1.0, m_max=0.1))
    kw[field] = value
    with pytest.raises(ValueError, match=match):
        Spacecraft(**kw)


def test_names_and_descriptions_with_quotes_survive_the_file(tmp_path):
    base = load_spacecraft("demo")
    odd = Spacecraft('sat "A"\\1', base.inertia, base.wheels,
                     description='two\nlines, "quoted"')
    odd.save(tmp_path / "odd.toml")
    back = load_spacecraft(tmp_path / "odd.toml")
    assert (back.name, back.description) == (odd.name, odd.description)


# -- #26: save writes back the layout and its parameters ------------------
USER_FILE = """
name = "user"
inertia = [120.0, 95.0, 80.0]
rate_max_deg = 2.5
[wheels]
pyramid = { delta_deg = 50.5, gamma_deg = 40.25 }
h_max = 4.0
m_max = 0.2
failed = [2]
[thrusters]
kind = "six_thruster_unit"
R = 0.3
L = 0.4
thrust = 0.5
min_on_time = 0.03
"""


def _same_craft(a, b, axes_atol: float = 0.0) -> None:
    """Equal to the last bit (the axes form: its axes to ``axes_atol``)."""
    np.testing.assert_array_equal(a.inertia, b.inertia)
    assert a.rate_max == b.rate_max
    np.testing.assert_allclose(a.wheels.axes, b.wheels.axes, rtol=0,
                               atol=axes_atol)
    for k in ("h_max", "m_max"):
        np.testing.assert_array_equal(getattr(a.wheels, k),
                                      getattr(b.wheels, k))
    assert a.wheels.failed == b.wheels.failed
    assert a.wheels.names == b.wheels.names
    assert (a.thrusters is None) == (b.thrusters is None)
    if a.thrusters is not None:
        from dataclasses import fields

        for f in fields(a.thrusters):     # every field, offsets included
            np.testing.assert_array_equal(getattr(a.thrusters, f.name),
                                          getattr(b.thrusters, f.name),
                                          err_msg=f.name)


def test_save_writes_the_layout_and_its_parameters(tmp_path):
    sc = spacecraft_from_toml(USER_FILE, "user.toml")
    path = tmp_path / "user.toml"
    sc.save(path)
    text = path.read_text()
    for line in ("inertia = [120.0, 95.0, 80.0]", "rate_max_deg = 2.5",
                 "pyramid = { delta_deg = 50.5, gamma_deg = 40.25 }",
                 "failed = [2]", 'kind = "six_thruster_unit"', "R = 0.3",
                 "L = 0.4", "thrust = 0.5", "min_on_time = 0.03"):
        assert line in text, (line, text)
    for expanded in ("axes =", "positions =", "directions =", "names =",
                     "open_delay"):
        assert expanded not in text, (expanded, text)
    back = load_spacecraft(path)
    _same_craft(back, sc)
    assert back.to_toml() == text                 # a fixed point


@pytest.mark.parametrize("wheels, line", [
    (WheelArray.pyramid(np.deg2rad(60.0), np.deg2rad(30.0), h_max=1.0,
                        m_max=0.1),
     "pyramid = { delta_deg = 60.0, gamma_deg = 30.0 }"),
    (WheelArray.orthogonal_plus_skew(skew="equal_angle"),
     'orthogonal_plus_skew = { skew = "equal_angle" }'),
    (WheelArray.orthogonal_plus_skew(phi2=np.deg2rad(30.0),
                                     phi3=np.deg2rad(20.0)),
     'orthogonal_plus_skew = { skew = "paper", phi2_deg = 30.0, '
     'phi3_deg = 20.0 }'),
    (WheelArray.orthogonal_pairs(h_max=0.05, m_max=2e-4),
     "orthogonal_pairs = {}"),
])
def test_a_layout_built_in_python_is_saved_as_that_layout(wheels, line,
                                                          tmp_path):
    sc = Spacecraft("py", np.diag([3.0, 2.5, 3.5]), wheels)
    sc.save(tmp_path / "py.toml")
    text = (tmp_path / "py.toml").read_text()
    assert line in text and "axes =" not in text, text
    _same_craft(load_spacecraft(tmp_path / "py.toml"), sc)


def test_arrays_no_layout_gives_are_saved_as_axes(tmp_path):
    """Mounting errors, renamed wheels, a moved thruster: general form."""
    wheels = WheelArray.pyramid(d_delta=[1e-3, 0, 0, 0], h_max=1.0,
                                m_max=0.1)
    unit = six_thruster_unit()
    pos = np.array(unit.positions)
    pos[0, [0, 3]] += 0.01                # D1 and its pair D4: 1 cm in x
    from dataclasses import replace

    sc = Spacecraft("odd", np.diag([3.0, 2.5, 3.5]), wheels,
                    replace(unit, positions=pos))
    sc.save(tmp_path / "odd.toml")
    text = (tmp_path / "odd.toml").read_text()
    assert "axes =" in text and 'kind = "custom"' in text
    assert "pyramid" not in text and "six_thruster_unit" not in text
    # the axes form normalises the axes again on reading: 1 ulp
    _same_craft(load_spacecraft(tmp_path / "odd.toml"), sc, 2.3e-16)
    named = Spacecraft("named", np.eye(3), WheelArray.from_axes(
        WheelArray.pyramid().axes, names=("A", "B", "C", "D")))
    named.save(tmp_path / "named.toml")
    text = (tmp_path / "named.toml").read_text()
    assert 'names = ["A", "B", "C", "D"]' in text and "pyramid" in text
    _same_craft(load_spacecraft(tmp_path / "named.toml"), named)


# -- #26: the per-engine thrust offset (eq. 1) survives save -----------------
OFFSET_FILE = USER_FILE.replace(
    "thrust = 0.5\n", "thrust = 0.5\npressure = 800000.0\n"
    "thrust_offset = [0.1, 0.12, 0.08, 0.1, 0.1, 0.11]\n")


def test_save_keeps_the_thrust_offset_the_user_wrote(tmp_path):
    sc = spacecraft_from_toml(OFFSET_FILE, "offset.toml")
    t = sc.thrusters
    np.testing.assert_array_equal(
        t.thrust_offset, [0.1, 0.12, 0.08, 0.1, 0.1, 0.11])
    # a_i = (P - b_i) / p: 0.5 N at 8e5 Pa, 0.4 N of it from the pressure
    assert t.pressure_slope[0] == (0.5 - 0.1) / 8e5 == 5e-7
    np.testing.assert_allclose(t.steady_thrust, 0.5, rtol=0, atol=1e-16)
    path = tmp_path / "offset.toml"
    sc.save(path)
    text = path.read_text()
    for line in ('kind = "six_thruster_unit"', "R = 0.3", "L = 0.4",
                 "thrust = 0.5   # N", "pressure = 800000.0",
                 "thrust_offset = [0.1, 0.12, 0.08, 0.1, 0.1, 0.11]",
                 "pyramid = { delta_deg = 50.5, gamma_deg = 40.25 }"):
        assert line in text, (line, text)
    assert "custom" not in text and "positions" not in text
    back = load_spacecraft(path)
    _same_craft(back, sc)                   # pressure_slope to the bit
    assert back.to_toml() == text
    # at half the pressure the offset keeps 0.1 + 0.2 = 0.3 N, not 0.25 N
    half = replace_pressure(back.thrusters, 4e5)
    assert half.steady_thrust[0] == pytest.approx(0.3, abs=1e-15)


def replace_pressure(t, p):
    from dataclasses import replace

    return replace(t, pressure=p)


@pytest.mark.parametrize("make", [
    lambda: six_thruster_unit(thrust=0.5, thrust_offset=0.05, pressure=8e5),
    lambda: six_thruster_unit(
        thrust=np.random.default_rng(1).uniform(0.3, 0.7, 6),
        thrust_offset=np.random.default_rng(2).uniform(0.0, 0.2, 6),
        pressure=7.7e5),
    lambda: _moved(six_thruster_unit(thrust_offset=0.07)),
], ids=["scalar", "random", "custom"])
def test_a_unit_with_offsets_round_trips_to_the_last_bit(make, tmp_path):
    sc = Spacecraft("py", np.diag([3.0, 2.5, 3.5]), WheelArray.pyramid(
        np.deg2rad(60.0), np.deg2rad(30.0), h_max=1.0, m_max=0.1), make())
    sc.save(tmp_path / "py.toml")
    text = (tmp_path / "py.toml").read_text()
    assert "thrust_offset = " in text and "pyramid = " in text
    back = load_spacecraft(tmp_path / "py.toml")
    _same_craft(back, sc)
    assert back.to_toml() == text
    again = tmp_path / "again.toml"
    back.save(again)
    _same_craft(load_spacecraft(again), sc)


def _moved(unit):
    """``unit`` with D1 and D4 moved 1 cm in x: no six-unit layout."""
    from dataclasses import replace

    pos = np.array(unit.positions)
    pos[0, [0, 3]] += 0.01
    return replace(unit, positions=pos)


def test_custom_thrusters_take_an_offset_and_the_scalar_form(tmp_path):
    text = """
name = "c"
inertia = [3.0, 2.5, 3.5]
[wheels]
pyramid = { delta_deg = 55.0, gamma_deg = 45.0 }
h_max = 0.2
m_max = 0.05
[thrusters]
kind = "custom"
positions = [[0.5, 0.0, 0.2], [-0.5, 0.0, 0.2]]
directions = [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]
thrust = 1.0
thrust_offset = 0.25
"""
    sc = spacecraft_from_toml(text, "c.toml")
    np.testing.assert_array_equal(sc.thrusters.thrust_offset, [0.25, 0.25])
    np.testing.assert_array_equal(sc.thrusters.steady_thrust, [1.0, 1.0])
    out = sc.to_toml()
    assert "thrust = 1.0   # N" in out and "thrust_offset = 0.25" in out
    _same_craft(spacecraft_from_toml(out), sc)


@pytest.mark.parametrize("value, problem", [
    ("[0.1, 0.2]", "thrust_offset must have shape (6)"),
    ('"a"', "must be a number or a list of numbers"),
])
def test_a_bad_thrust_offset_names_its_key(value, problem):
    bad = USER_FILE.replace("thrust = 0.5\n",
                            f"thrust = 0.5\nthrust_offset = {value}\n")
    with pytest.raises(SpacecraftFileError, match="thrust_offset") as exc:
        spacecraft_from_toml(bad, "bad.toml")
    assert problem in str(exc.value)
    assert "\n" not in str(exc.value)
