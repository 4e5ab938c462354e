"""``adcs design``: the JSON reproduces the reference radii; --out loads."""

import json

import numpy as np
import pytest

from adcs.cli import main
from allocation import certify_layout
from ocp.spacecraft import load_spacecraft


def _design(capsys, *argv):
    assert main(["design", *argv, "--json", "--starts", "4"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("argv, radius, failure", [
    (["--wheels", "4"], 4 / np.sqrt(6), 2 / np.sqrt(6)),
    (["--wheels", "6"], 2.752764, 1.902113),
    (["--wheels", "5", "--failures", "1"], None, np.sqrt(5) - 1),
])
def test_json_reproduces_the_table(capsys, argv, radius, failure):
    out = _design(capsys, *argv)
    n = int(argv[1])
    axes = np.array(out["axes"]).T                  # rows are wheels 1..N
    assert axes.shape == (3, n)
    if radius is not None:
        assert out["radius"] >= radius - 1e-6
    assert out["worst_failure_radius"] >= failure - 1e-6
    assert (out["radius"], out["worst_failure_radius"]) == pytest.approx(
        certify_layout(axes), abs=1e-9)


def test_out_writes_a_craft_that_loads_and_reports(capsys, tmp_path):
    f = tmp_path / "designed.toml"
    assert main(["design", "--wheels", "5", "--failures", "1", "--starts",
                 "3", "--h-max", "4", "--m-max", "0.2", "--out",
                 str(f)]) == 0
    sc = load_spacecraft(f)
    assert sc.wheels.n_wheels == 5
    assert np.allclose(sc.wheels.h_max, 4.0)
    assert np.allclose(sc.wheels.m_max, 0.2)
    assert certify_layout(sc.wheels.axes, 4.0, 1)[1] == pytest.approx(
        4 * (np.sqrt(5) - 1), abs=1e-5)
    assert "wrote" in capsys.readouterr().out
    assert main(["report", "--quick", "--studies", "spacecraft",
                 "--spacecraft", str(f), "--out",
                 str(tmp_path / "rep")]) == 0
    # and through the other tools: the bench and the C export
    assert main(["bench", "--quick", "--problems", "wheels", "--backends",
                 "daqp,quadprog", "--no-progress", "--spacecraft", str(f),
                 "--out", str(tmp_path / "bench")]) == 0
    assert (tmp_path / "bench").is_dir()
    assert main(["export", "--spacecraft", str(f), "--mpc", "",
                 "--out", str(tmp_path / "c")]) == 0
    assert "wheel_qp" in (tmp_path / "c" / "adcs_codegen.h").read_text()


@pytest.mark.parametrize("argv, message", [
    (["--wheels", "2"], ">= 3"),
    (["--wheels", "5", "--family", "pyramid"], "4 wheels"),
    (["--wheels", "4", "--failures", "2"], "at least 3"),
    (["--wheels", "4", "--h-max", "-1"], "positive"),
    (["--wheels", "4", "--out", "/no/such/folder/x.toml"], "folder"),
])
def test_mistakes_are_one_line_and_status_2(capsys, argv, message):
    assert main(["design", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
