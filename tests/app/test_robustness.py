"""The robustness benchmark, small: default backends right on every case."""

import pytest

from benchmarks.robustness import format_rows, run


@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_default_and_osqp_backends_answer_every_random_problem(backend):
    rows = run(n_wheels=200, n_duties=200, backends=[backend], seed=3)
    assert len(rows) == 4
    for case, b, t, _ in rows:
        assert t["n"] == 200
        assert t["ok"] == 200, (case, b, t)
        assert t["max_error"] < 1e-6
    assert "| wheels: pyramid |" in format_rows(rows)
