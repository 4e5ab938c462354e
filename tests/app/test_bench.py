"""Optimizer comparison: certified answers, table, JSON and plot."""

import json
import re

import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from adcs.bench import TOL, format_table, kkt_residual, run_bench
from adcs.cli import main


def test_kkt_residual_flags_a_wrong_answer():
    # min m1² + m2² s.t. m1 + m2 = 1, 0 <= m <= 0.8: optimum (0.5, 0.5)
    P = 2.0 * np.eye(2)
    C = np.vstack([[1.0, 1.0], np.eye(2)])
    cl = np.array([1.0, 0.0, 0.0])
    cu = np.array([1.0, 0.8, 0.8])
    assert kkt_residual(P, np.zeros(2), C, cl, cu, [0.5, 0.5]) < 1e-14
    # feasible but not optimal: stationarity fails
    assert kkt_residual(P, np.zeros(2), C, cl, cu, [0.7, 0.3]) > 0.1
    # infeasible point
    assert kkt_residual(P, np.zeros(2), C, cl, cu, [0.9, 0.1]) > 0.05
    # active upper bound with the right multiplier sign: q pushes m1 up
    q = np.array([-10.0, 0.0])
    assert kkt_residual(P, q, C, cl, cu, [0.8, 0.2]) < 1e-12


def test_cli_bench_quick(tmp_path, capsys):
    code = main(["bench", "--quick", "--out", str(tmp_path),
                 "--backends", "osqp,quadprog,casadi:qrqp,ipopt,sqpmethod",
                 "--repetitions", "6", "--no-progress"])
    assert code == 0
    out = capsys.readouterr().out
    assert "| wheels | quadprog |" in out
    data = json.loads((tmp_path / "bench.json").read_text())
    rows = data["rows"]
    got = {(r["problem"], r["backend"]) for r in rows}
    assert ("wheels", "osqp") in got and ("thrusters", "casadi:qrqp") in got
    assert ("slew", "ipopt") in got and ("slew", "sqpmethod") in got
    # names a problem does not know are skipped, not failed
    assert ("wheels", "ipopt") not in got
    for r in rows:
        assert r["failures"] == 0 and r["wrong"] == 0, r
        assert r["max_error"] <= TOL
        assert r["median_s"] > 0
    assert (tmp_path / "bench.png").stat().st_size > 1000


def test_run_bench_rejects_unknown_problem():
    with pytest.raises(InvalidValueError, match="problems"):
        run_bench(problems=["nosuch"], progress=False)
    with pytest.raises(InvalidValueError, match="repetitions"):
        run_bench(problems=["wheels"], repetitions=0, progress=False)


def test_format_table_has_one_line_per_row():
    rows = run_bench(problems=["wheels"], backends=["quadprog", "daqp"],
                     repetitions=3, progress=False)
    assert format_table(rows).count("\n") == len(rows) + 1


def test_fast_wrong_answers_are_reported_wrong():
    from adcs.bench import bench_thrusters

    rows = {r.backend: r for r in bench_thrusters(
        ["quadprog", "osqp@loose"], reps=12, seed=3)}
    assert rows["quadprog"].ok
    loose = rows["osqp@loose"]
    # OSQP at eps 1e-3 without polishing: points off the optimum, which
    # the QP layer's certificate polishes on their active set (before it,
    # this row had KKT residuals over 1e-3 and wrong answers)
    assert loose.wrong == 0
    assert loose.max_kkt <= 1e-6
    # the note states what was measured, not what should happen
    counted = re.search(r"the certificate corrected (\d+) of (\d+) of its "
                        r"points by more than 1e-06 \(largest move "
                        r"([0-9.e+-]+)\) and refused (\d+); after it the "
                        r"bench's check found 0 of 12 wrong", loose.note)
    assert counted, loose.note
    assert int(counted[2]) == 12 and 1 <= int(counted[1]) <= 12
    assert 1e-6 < float(counted[3]) < 0.1
    assert "must" not in loose.note


def test_the_certificate_reports_how_far_it_moved_a_point():
    from allocation import QPAllocator

    from adcs.bench.problems import wheel_problem

    arr, demands = wheel_problem(None, 3, seed=0)     # bounds active
    loose = QPAllocator(arr, solver="osqp", solver_options={
        "eps_abs": 1e-3, "eps_rel": 1e-3, "polishing": False})
    exact = QPAllocator(arr, solver="daqp")
    moves = []
    for M in demands:
        res = loose.allocate(M)
        moves.append(res.extras["certificate"]["moved"])
        np.testing.assert_allclose(res.torques, exact.allocate(M).torques,
                                   atol=1e-9)
    assert max(moves) > 1e-6          # OSQP's loose point was corrected


def test_ctrl_c_keeps_the_finished_rows_and_exits_130(tmp_path, capsys,
                                                      monkeypatch):
    import json

    import adcs.bench as bench

    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(bench, "bench_thrusters", stop)
    code = main(["bench", "--quick", "--problems", "wheels,thrusters",
                 "--backends", "daqp", "--out", str(tmp_path),
                 "--no-progress"])
    assert code == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "stopped during 'thrusters'" in err[0]
    saved = json.loads((tmp_path / "bench.json").read_text())
    assert saved["interrupted_during"] == "thrusters"
    assert [r["problem"] for r in saved["rows"]] == ["wheels"]
    assert dict(saved["provenance"])["python"]


def test_a_backend_past_its_budget_is_cut_short_and_marked_too_slow():
    from adcs.bench import to_frame

    rows = run_bench(problems=["wheels"], backends=["daqp", "osqp@loose"],
                     repetitions=50, progress=False, budget=1e-9)
    for r in rows:
        assert r.n == 1 and r.requested == 50 and r.too_slow
        assert "too slow: 1 of 50 solves" in r.note
    loose = next(r for r in rows if r.backend == "osqp@loose")
    assert "control row" in loose.note
    frame = to_frame(rows)
    assert list(frame["backend"]) == ["daqp", "osqp@loose"]
    assert frame["too_slow"].all() and "note" in frame
    with pytest.raises(InvalidValueError, match="budget"):
        run_bench(problems=["wheels"], budget=0.0, progress=False)


def test_unknown_backend_is_one_line_and_status_2(capsys):
    assert main(["bench", "--backends", "nosuch", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'nosuch' is not available" in err[0]


def test_methods_rows_on_request():
    """The literature's methods run on request: the redistributed and
    cascaded inverses reach every bench demand with the QP's torques;
    direct allocation reaches them all with other torques."""
    from adcs.bench import DEFAULT_PROBLEMS

    assert "methods" not in DEFAULT_PROBLEMS
    rows = {r.backend: r for r in run_bench(
        problems=["methods"], backends=["method:rpi", "method:cgi",
                                        "method:direct"],
        repetitions=10, progress=False)}
    assert set(rows) == {"method:rpi", "method:cgi", "method:direct"}
    for name in ("method:rpi", "method:cgi"):
        assert rows[name].ok and rows[name].max_error <= 1e-9
    direct = rows["method:direct"]
    assert direct.max_kkt <= 1e-6 and "0/10 demands missed" in direct.note
