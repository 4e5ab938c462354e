"""A closed loop whose QPs a capped primal active set solves reaches the
target as the uncapped one does (`benchmarks.primal_loops`)."""

import numpy as np

from benchmarks.horizon_qps import study_setup
from benchmarks.mpc_worst_case import random_states
from benchmarks.primal_loops import fly


def test_capped_primal_loop_reaches_the_target():
    setup = study_setup(8)
    x0 = random_states(setup[1], 1, np.random.default_rng(0))[0]
    full = fly(8, x0, 80, 0, setup)
    capped = fly(8, x0, 80, 3, setup)
    assert full["capped"] == 0 and capped["capped"] > 0
    assert full["daqp"] >= 1                  # the loop's first step
    for r in (full, capped):
        assert np.rad2deg(r["final_error"]) < 0.1
        assert 0 < r["settle_time"] < 40.0
