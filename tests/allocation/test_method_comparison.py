"""The coverage computation of the method comparison, on known answers."""

import numpy as np

from allocation import WheelArray, min_norm_law, torque_reach
from allocation.method_comparison import (
    compare_methods,
    format_comparison,
    sample_attainable,
)
from allocation.methods import pseudo_inverse


def test_samples_are_attainable_and_uniform():
    array = WheelArray.orthogonal_pairs(m_max=0.2)      # the box ±0.4
    D = sample_attainable(array, 4000, seed=2)
    assert D.shape == (4000, 3)
    assert np.all(np.abs(D) <= 0.4)
    # uniform in a box: each octant holds 1/8
    share = np.mean(np.all(D > 0, axis=1))
    assert abs(share - 1 / 8) < 4 * np.sqrt(1 / 8 * 7 / 8 / 4000)


def test_coverage_known_answers():
    """The exact QP reaches 100 %; the clipped pseudo-inverse reaches the
    exact linear-law volume of `torque_reach` within 4 standard errors."""
    array = WheelArray.pyramid(h_max=4.0, m_max=0.2)
    rows = compare_methods(array, {"pseudo-inverse": pseudo_inverse},
                           n_samples=3000, n_directions=40)
    by = {r.method: r for r in rows}
    for qp in ("exact QP (scale)", "exact QP (least squares)"):
        assert by[qp].volume_fraction == 1.0
        assert by[qp].min_direction_fraction > 0.998
        assert by[qp].qp_agreement == 1.0
    exact = torque_reach(array, min_norm_law(array)).volume_fraction
    pi = by["pseudo-inverse"]
    assert 0.3 < exact < 0.95
    assert abs(pi.volume_fraction - exact) < 4 * pi.volume_stderr
    assert pi.miss_error_p50 > 1e-3
    assert "pseudo-inverse" in format_comparison(rows)
