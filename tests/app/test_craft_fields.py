"""Every field of a spacecraft file reaches every tool that uses it.

`FIELDS` is the table of docs/spacecraft.md: each field of the TOML file
and the tools whose output it must change. The test writes a base craft,
changes one field at a time and compares each tool's craft-dependent
output (the cheapest entry point that still goes through the craft: the
report's tables and slew setup, the bench's problem builders, the
export's functions on their samples, the failure sweep's cases and MPCs,
the Basilisk scenarios' setup objects, not run). A field must change the
output of exactly the tools listed: one that is dropped fails, and so
does a table entry no tool honours.
"""

import copy
import itertools

import numpy as np
import pytest

from ocp.spacecraft import load_spacecraft

#: The base craft, as a TOML table (written by `_toml`).
BASE = {
    "name": "base",
    "description": "base craft of the field test",
    "inertia": [3.0, 2.5, 3.5],
    "rate_max_deg": 1.5,
    "wheels": {"pyramid": {"delta_deg": 55.0, "gamma_deg": 45.0},
               "h_max": 0.2, "m_max": 0.05,
               "names": ["A", "B", "C", "D"]},
    "thrusters": {"kind": "six_thruster_unit", "R": 0.25, "L": 0.3,
                  "thrust": 0.5},
}

TOOLS = ("report", "bench", "export", "sweep", "basilisk")
ALL = set(TOOLS)
THRUSTER_TOOLS = {"report", "bench", "export", "basilisk"}


def _set(path, value):
    def edit(d):
        *head, last = path.split(".")
        for k in head:
            d = d[k]
        if value is None:
            del d[last]
        else:
            d[last] = value
    return edit


#: field (TOML key) -> (edit of the base craft, tools that must use it)
FIELDS = {
    "name": (_set("name", "other"), {"report", "basilisk"}),
    "description": (_set("description", "other craft"), {"report"}),
    "inertia": (_set("inertia", [3.0, 2.5, 4.5]), ALL),
    "rate_max_deg": (_set("rate_max_deg", 0.5), ALL),
    "wheels.<layout>": (_set("wheels.pyramid", {"delta_deg": 50.0,
                                                "gamma_deg": 45.0}), ALL),
    "wheels.h_max": (_set("wheels.h_max", 0.3), ALL),
    "wheels.m_max": (_set("wheels.m_max", 0.08), ALL),
    "wheels.failed": (_set("wheels.failed", [2]), ALL),
    "wheels.names": (_set("wheels.names", ["W", "X", "Y", "Z"]),
                     {"report"}),
    "thrusters": (_set("thrusters", None), THRUSTER_TOOLS),
    "thrusters.R": (_set("thrusters.R", 0.3), THRUSTER_TOOLS),
    # L moves the engines along their thrust: only Basilisk's positions
    "thrusters.L": (_set("thrusters.L", 0.35), {"basilisk"}),
    "thrusters.thrust": (_set("thrusters.thrust", 0.6), THRUSTER_TOOLS),
    "thrusters.center_of_mass": (
        _set("thrusters.center_of_mass", [0.0, 0.0, 0.02]),
        THRUSTER_TOOLS),
    # the file's thrust is the steady thrust at its pressure: the
    # pressure alone changes no tool (`DutyCycleAllocator.set_pressure`
    # uses it in flight)
    "thrusters.pressure": (_set("thrusters.pressure", 8.0e5), set()),
    # the offset b_i of P = a_i p + b_i: `thrust` stays the steady thrust
    # at the file's pressure, so it too changes no tool's nominal output
    "thrusters.thrust_offset": (_set("thrusters.thrust_offset", 0.1),
                                set()),
    "thrusters.correction": (_set("thrusters.correction", 0.9),
                             THRUSTER_TOOLS),
    # the propellant figures; one Isp for all engines leaves the duties
    "thrusters.isp": (_set("thrusters.isp", 180.0),
                      {"report", "bench", "basilisk"}),
    "thrusters.min_on_time": (_set("thrusters.min_on_time", 0.05),
                              {"basilisk"}),
    "thrusters.names": (_set("thrusters.names",
                             ["a", "b", "c", "d", "e", "f"]), {"report"}),
}


def _value(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_value(x)}"
                               for k, x in v.items()) + " }"
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return repr(v)


def _toml(d: dict) -> str:
    top = [f"{k} = {_value(v)}" for k, v in d.items()
           if not isinstance(v, dict)]
    tables = [f"\n[{k}]\n" + "\n".join(f"{kk} = {_value(vv)}"
                                       for kk, vv in v.items())
              for k, v in d.items() if isinstance(v, dict)]
    return "\n".join(top) + "\n" + "\n".join(tables) + "\n"


_COUNT = itertools.count()


@pytest.fixture(scope="module")
def crafts(tmp_path_factory):
    """field -> TOML path of the craft with that field changed ("" base)."""
    folder = tmp_path_factory.mktemp("crafts")
    out = {}
    for field, (edit, _) in [("", (lambda d: None, None)),
                             *FIELDS.items()]:
        d = copy.deepcopy(BASE)
        edit(d)
        # a new file name each time: the sweep caches crafts by path
        path = folder / f"craft{next(_COUNT)}.toml"
        path.write_text(_toml(d))
        load_spacecraft(path)          # a valid file
        out[field] = str(path)
    return out


# ------------------------------------------------------------- the probes
def _mpc_print(ctl) -> list:
    """An MPC's bounds and its model's dynamics at a fixed point."""
    model = ctl.model
    x = np.r_[0.9, 0.1, -0.2, 0.3, 0.01, -0.02, 0.03,
              0.01 * np.arange(1, model.nx - 6)]
    u = 0.001 * np.arange(1, model.nu + 1)
    return [ctl.lbz, ctl.ubz, np.asarray(model.dynamics(
        x, u, np.zeros(3))).ravel()]


def _table_print(table) -> list:
    return [table.title, [[str(c) for c in row] for row in table.rows]]


def probe_report(path):
    from adcs.studies import spacecraft as study

    sc = load_spacecraft(path)
    _, _, eig, ctl, dt = study.slew_setup(sc)
    out = [_table_print(study.craft_table(sc)),
           _table_print(study.envelope_table(sc)), eig.T, dt,
           _mpc_print(ctl)]
    if sc.thrusters is not None:
        out.append(_table_print(study.thruster_table(sc)))
    return out


def probe_bench(path):
    from adcs.bench.problems import (
        THRUSTER_H_MAX,
        slew_controller,
        thruster_problem,
        wheel_problem,
    )
    from allocation import QPAllocator
    from thrusters import DutyCycleAllocator

    arr, demands = wheel_problem(path, reps=3)
    out = [np.array(demands),
           [QPAllocator(arr).allocate(1.5 * M).torques for M in demands]]
    unit, cases = thruster_problem(path, reps=3)
    if unit is not None:
        alloc = DutyCycleAllocator(unit, 2.0, THRUSTER_H_MAX,
                                   tracking="weighted", bound="box")
        for P_T, M, H, tau in cases:
            r = alloc.solve_theta(alloc.theta(P_T, M, H, tau))
            out += [r.duty, r.propellant]
    mpc, x0, qf = slew_controller(path, solver="sqpmethod")
    return out + [_mpc_print(mpc), x0, qf]


def probe_export(path, tmp_path):
    from ocp.codegen.export import export_c

    res = export_c(tmp_path / f"c{next(_COUNT)}", path, horizon=5,
                   mpc_variants=("mpc_cond_step",), wheel_qp_plugin="qrqp",
                   duty_qp_plugin="qrqp")
    out = [res.extras["rate_max"], sorted(res.functions)]
    for name, f in res.functions.items():
        sample = res.samples[name]
        out.append([np.asarray(v).ravel() for v in f(*sample)]
                   if f.n_out() > 1 else np.asarray(f(*sample)).ravel())
    return out


def probe_sweep(path):
    from adcs.sweep import builtin

    rows = builtin._failures(True, spacecraft=path)
    q0, qf, T, dt = builtin.failure_setup(path, rows[0]["angle_deg"])
    text = builtin._craft_text(path)
    out = [[r["wheel"] for r in rows], T, dt,
           _mpc_print(builtin._mpc(text, str(path), -1, dt))]
    out.append(_mpc_print(builtin._mpc(text, str(path),
                                       rows[0]["wheel"] - 1, dt)))
    ag = builtin._agility(True, spacecraft=path)[0]
    sc = builtin._craft(path)
    from ocp import eigenaxis_slew, quat_from_axis_angle

    qa = quat_from_axis_angle(builtin.fibonacci_axes()[ag["axis"]],
                              np.deg2rad(ag["angle_deg"]))
    out.append(eigenaxis_slew(sc, q0, qa).T)
    return out


def _rw_print(setup) -> list:
    rw = setup.wheels
    out = [np.asarray(setup.hub.hub.IHubPntBc_B)]
    for i in range(setup.spacecraft.wheels.n_wheels):
        r = rw.ReactionWheelData[i]
        out.append([np.ravel(r.gsHat_B), r.u_max, r.Omega_max])
    veh, cfg = (m.read() for m in setup.keep[:2])
    n = setup.spacecraft.wheels.n_wheels
    out += [list(veh.ISCPntB_B), list(cfg.GsMatrix_B)[:3 * n],
            list(cfg.uMax)[:n], setup.spacecraft.name]
    if setup.availability is not None:
        out.append(list(setup.availability.wheelAvailability)[:n])
    alloc = setup.alloc
    if hasattr(alloc, "array"):
        out.append(alloc.allocator(tuple(alloc.array.failed)).allocate(
            np.array([0.01, -0.02, 0.03])).torques)
    return out


def probe_basilisk(path):
    pytest.importorskip("Basilisk")
    from adcs.basilisk.mpc_scenario import mpc_controller
    from adcs.basilisk.scenarios import ALLOCATORS, build_loop
    from adcs.basilisk.thruster_scenario import (
        THRUSTER_CHAINS,
        build_reorientation,
    )

    out = [_rw_print(build_loop(a, path)) for a in ALLOCATORS]
    mpc, J = mpc_controller(spacecraft=path)
    out += [_mpc_print(mpc), J]
    if load_spacecraft(path).thrusters is not None:
        for chain in THRUSTER_CHAINS:
            sim, parts = build_reorientation(chain, spacecraft=path)
            for t in parts["factory"].thrusterList.values():
                out.append([np.ravel(t.thrLoc_B), np.ravel(t.thrDir_B),
                            t.MaxThrust, t.steadyIsp])
            out.append(np.asarray(parts["hub"].hub.IHubPntBc_B))
            for m in parts["chain"]:
                if hasattr(m, "thrMinFireTime"):
                    out.append(m.thrMinFireTime)
                if hasattr(m, "allocator"):
                    r = m.allocator.solve(0.0, np.array([0.01, -0.004]))
                    out += [r.duty, r.propellant]
    return out


PROBES = {"report": probe_report, "bench": probe_bench,
          "export": probe_export, "sweep": probe_sweep,
          "basilisk": probe_basilisk}


def _differs(a, b) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) != len(b) or any(_differs(x, y) for x, y in zip(a, b))
    if isinstance(a, str) or isinstance(b, str) or a is None or b is None:
        return a != b
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape != b.shape or not np.array_equal(a, b, equal_nan=True)


_BASE_OUT: dict = {}


def _run(tool, path, tmp_path):
    probe = PROBES[tool]
    return probe(path, tmp_path) if tool == "export" else probe(path)


@pytest.mark.parametrize("tool", TOOLS)
@pytest.mark.parametrize("field", list(FIELDS))
def test_each_field_changes_exactly_the_tools_that_use_it(
        field, tool, crafts, tmp_path):
    """Change one field: the tools of its row change, the others not."""
    if tool not in _BASE_OUT:
        _BASE_OUT[tool] = _run(tool, crafts[""], tmp_path)
    changed = _differs(_BASE_OUT[tool], _run(tool, crafts[field], tmp_path))
    must = tool in FIELDS[field][1]
    assert changed == must, (
        f"{field} {'does not reach' if must else 'changes'} {tool}")


def test_the_table_is_in_the_docs():
    """docs/spacecraft.md lists every field of `FIELDS` with its tools."""
    from pathlib import Path

    text = (Path(__file__).parents[2] / "docs" / "spacecraft.md").read_text(
        encoding="utf-8")
    for field, (_, tools) in FIELDS.items():
        row = next((line for line in text.splitlines()
                    if line.startswith(f"| `{field}`")), None)
        assert row is not None, f"no row for {field} in docs/spacecraft.md"
        listed = set(row.split("|")[2].split("(")[0].split())
        assert listed == tools, (field, listed, tools)


def test_exported_mpc_keeps_the_crafts_rate_limit(crafts, tmp_path):
    """Issue #23 item 9: export_c(spacecraft=...) dropped rate_max."""
    from ocp.codegen.export import export_c

    sc = load_spacecraft(crafts[""])
    res = export_c(tmp_path / "c", sc, horizon=8,
                   mpc_variants=("mpc_cond_step",))
    f = res.functions["mpc_cond_step"]
    z = np.asarray(f(*res.samples["mpc_cond_step"])[1]).ravel()
    nx, nu = 7 + sc.wheels.n_wheels, sc.wheels.n_wheels
    rates = np.array([z[k * (nx + nu) + 4:k * (nx + nu) + 7]
                      for k in range(9)])
    assert res.extras["rate_max"] == sc.rate_max
    # 1.5°/s, as AttitudeMPC on the same craft (before the fix: 4.76°/s planned)
    assert np.abs(rates).max() <= sc.rate_max * (1 + 1e-6)
    assert np.abs(rates).max() >= 0.99 * sc.rate_max
