"""The robustness benchmark, small: every backend, no wrong success.

Before the QP layer's optimality certificate the same run (1,000 wheel
cases, 1,000 duty cycles, seed 1) had wrong answers reported as a
success on clarabel, piqp, proxqp, casadi:qrqp (wheels) and osqp,
piqp, casadi:qrqp, casadi:osqp (duties, custom thruster sets up to 43 of
250).
"""

from benchmarks.robustness import format_rows, run, totals


def test_every_backend_answers_every_random_problem_right_or_says_so():
    rows = run(n_wheels=300, n_duties=300, backends=["all"], seed=3)
    assert {case.split(":")[0] for case, *_ in rows} == {"wheels",
                                                         "duties"}
    for case, b, t, _ in rows:
        assert t["wrong"] == 0, (case, b, t)
        assert t["ok"] + t["failed"] == t["n"]
        assert not t["max_error"] > 1e-6
    table = format_rows(totals(rows))
    assert "| wheels | daqp | 300 | 300 | 0 | 0 |" in table
    # the six-thruster unit and random custom sets with weighted tracking
    assert any("custom set" in case for case, *_ in rows)
