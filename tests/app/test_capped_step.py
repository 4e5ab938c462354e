"""`benchmarks.capped_step`: the exported pqp step, capped, flies the
closed loops it tabulates against the uncapped step of the same run."""

import numpy as np

from benchmarks.capped_step import format_rows, run


def test_capped_step_table_compares_with_the_uncapped_step():
    rows = run([8], [5], draws=2, steps=80)
    full, capped = rows
    assert (full["cap"], full["capped"]) == (0, 0.0)
    assert full["cost_median"] == full["cost_worst"] == 1.0
    assert capped["cap"] == 5 and 0 < capped["capped"] < 1
    assert full["unsettled"] == 0 and capped["unsettled"] == 0
    # the capped loop's cost, as a ratio to the uncapped one's
    assert 0.9 <= capped["cost_median"] <= capped["cost_worst"] < 2.0
    assert 0 < full["settle_median"] <= capped["settle_worst"] < 40.0
    text = format_rows(rows, 2, 80)
    assert text.count("\n| 8 |") == 2 and "| 5 |" in text
    assert np.isfinite(capped["settle_median"])
