"""Accuracy of the realised torque, [1] "accuracy estimate" (theory §1.3).

M1 = A_1 m̂ with the actual axes A_1 and m̂_i = m_i (1 ± Δ_i); the error
ΔM = M − M1 and the cross-coupling angle Δα between M and M1.
"""

import time

import matplotlib
import numpy as np
import pytest

from allocation import (
    InvalidValueError,
    RankError,
    ShapeError,
    WheelArray,
    min_norm_gains,
)
from allocation.accuracy import (
    actual_axes,
    compare_law_axes,
    gain_error_uniform,
    gain_error_uniform_as_printed,
    monte_carlo_accuracy,
    monte_carlo_accuracy_array,
    paper_actual_axes_as_printed,
    tilted_axes,
    torque_error,
)
from allocation.plots import plot_accuracy_histogram
from conftest import DELTA, GAMMA

matplotlib.use("Agg")

DEG = np.pi / 180.0
ONES = np.ones(4)


def realised(pyramid, delta_i, gamma_i, demand, d_scale=0.0):
    """M1 = A_1 m (1 - Δ) with the nominal law (5)."""
    m = min_norm_gains(pyramid) @ demand
    return actual_axes(delta_i, gamma_i) @ (m * (1.0 - d_scale))


# ------------------------------------------------------------ case (a)
def test_case_a_direct_computation_gives_minus_2_094_percent(pyramid):
    M = np.array([0.7, 0.0, 0.0])
    M1 = realised(pyramid, (DELTA - 0.5 * DEG) * ONES,
                  (GAMMA - 0.3 * DEG) * ONES, M, d_scale=0.02)
    rel = (M1[0] - M[0]) / M[0]
    assert rel == pytest.approx(-0.02094, abs=5e-6)
    assert rel == pytest.approx(
        gain_error_uniform(0.5 * DEG, 0.3 * DEG, 0.02), abs=1e-14)
    # the direction is kept: Δα = 0
    np.testing.assert_allclose(M1[1:], 0.0, atol=1e-15)
    assert torque_error(M, M1).angle == pytest.approx(0.0, abs=1e-15)


def test_case_a_printed_formula_without_1_over_sdcg_is_wrong(pyramid):
    printed = gain_error_uniform_as_printed(0.5 * DEG, 0.3 * DEG, 0.02)
    assert printed == pytest.approx(-0.01213, abs=5e-6)
    correct = gain_error_uniform(0.5 * DEG, 0.3 * DEG, 0.02)
    assert correct == pytest.approx(printed / (np.sin(DELTA)
                                               * np.cos(GAMMA)))
    assert abs(correct - printed) > 0.008


# ------------------------------------------------------------ case (b)
@pytest.mark.parametrize("d_gamma_deg", [0.1, 0.3, 1.0])
def test_case_b_torque_is_rotated_by_delta_gamma(pyramid, d_gamma_deg):
    dg = d_gamma_deg * DEG
    gamma_i = GAMMA + dg * np.array([-1.0, 1.0, 1.0, -1.0])
    for M in ([1.0, 0.0, 0.0], [0.3, -0.8, 0.0], [-0.5, 0.5, 0.0]):
        M = np.array(M)
        M1 = realised(pyramid, DELTA * ONES, gamma_i, M)
        err = torque_error(M, M1)
        assert err.angle == pytest.approx(dg, abs=1e-13)
        assert err.magnitude_error == pytest.approx(0.0, abs=1e-13)
        # exactly the rotation about z by Δγ
        c, s = np.cos(dg), np.sin(dg)
        np.testing.assert_allclose(M1, [c * M[0] - s * M[1],
                                        s * M[0] + c * M[1], 0.0],
                                   atol=1e-14)


# ---------------------------------------------------- erratum: row 2
def test_printed_actual_A_with_row_2_all_positive_is_not_A_at_zero_error(
        pyramid):
    printed = paper_actual_axes_as_printed(DELTA * ONES, GAMMA * ONES)
    assert np.all(printed[1] > 0)
    assert not np.allclose(printed, pyramid.axes)
    np.testing.assert_allclose(printed[1, [1, 2]], -pyramid.axes[1, [1, 2]])
    # with it, a pure Mx demand would leak into My at zero error
    M = np.array([1.0, 0.0, 0.0])
    leak = printed @ min_norm_gains(pyramid) @ M
    # m_i = -Mx/(4 sδcγ) each, row 2 sums 4 sδsγ m_i = -tan γ Mx
    assert leak[1] == pytest.approx(-np.tan(GAMMA), abs=1e-14)
    # the signs of the nominal A give zero error
    np.testing.assert_allclose(actual_axes(DELTA * ONES, GAMMA * ONES),
                               pyramid.axes, atol=1e-15)


def test_actual_axes_is_vectorised_over_samples():
    rng = np.random.default_rng(0)
    d = DELTA + rng.uniform(-0.01, 0.01, (5, 4))
    g = GAMMA + rng.uniform(-0.01, 0.01, (5, 4))
    stack = actual_axes(d, g)
    assert stack.shape == (5, 3, 4)
    for s in range(5):
        np.testing.assert_array_equal(stack[s], actual_axes(d[s], g[s]))
    np.testing.assert_allclose(np.linalg.norm(stack, axis=1), 1.0)


# --------------------------------------------------------- Monte Carlo
def test_monte_carlo_zero_tolerances_zero_error():
    r = monte_carlo_accuracy(d_delta_tol=0.0, d_gamma_tol=0.0,
                             scale_tol=0.0, n_samples=1000)
    assert r.relative_error_stats.max < 1e-14
    assert r.angle_stats.max < 1e-14


def test_monte_carlo_scale_errors_match_the_analytic_variance(pyramid):
    # ΔM = -A diag(Δ) m, E Δ_i² = t²/3 (uniform), |h_i| = 1:
    # E|ΔM|² = t²/3 |m|² = t²/3 Mᵀ(AAᵀ)⁻¹M
    t = 0.02
    M = np.array([1.0, 0.0, 0.0])
    r = monte_carlo_accuracy(d_delta_tol=0.0, d_gamma_tol=0.0, scale_tol=t,
                             demand=M, n_samples=100_000)
    A = pyramid.axes
    expected = t ** 2 / 3.0 * M @ np.linalg.solve(A @ A.T, M)
    sq = r.relative_error ** 2
    assert np.mean(sq) == pytest.approx(
        expected, abs=3.0 * np.std(sq) / np.sqrt(sq.size))


def test_monte_carlo_normal_3_sigma_is_tighter_than_uniform():
    # rms ratio sqrt((t/3)² / (t²/3)) = 1/sqrt(3) for a linear error
    kw = dict(d_delta_tol=0.0, d_gamma_tol=0.0, scale_tol=0.02,
              demand=[0.0, 1.0, 0.0], n_samples=100_000)
    uni = monte_carlo_accuracy(distribution="uniform", **kw)
    nor = monte_carlo_accuracy(distribution="normal", **kw)
    ratio = np.sqrt(np.mean(nor.relative_error ** 2)
                    / np.mean(uni.relative_error ** 2))
    assert ratio == pytest.approx(1.0 / np.sqrt(3.0), rel=0.01)


def test_measured_axes_remove_the_coupling():
    # perfect measurement, no scale errors: the law fits the actual axes
    r = monte_carlo_accuracy(d_delta_tol=1.0 * DEG, d_gamma_tol=1.0 * DEG,
                             scale_tol=0.0, law_axes="measured",
                             measure_delta_tol=0.0, measure_gamma_tol=0.0,
                             n_samples=2000)
    assert r.angle_stats.max < 1e-12
    assert r.relative_error_stats.max < 1e-12


def test_measurement_errors_take_the_place_of_mounting_tolerances():
    # law with measured axes (mounting 1°, measurement 0.1°) ~ law with
    # nominal axes and mounting 0.1° (first order in the small angles)
    nominal, measured = compare_law_axes(
        d_delta_tol=1.0 * DEG, d_gamma_tol=1.0 * DEG, scale_tol=0.0,
        measure_delta_tol=0.1 * DEG, measure_gamma_tol=0.1 * DEG,
        n_samples=50_000)
    small = monte_carlo_accuracy(d_delta_tol=0.1 * DEG,
                                 d_gamma_tol=0.1 * DEG, scale_tol=0.0,
                                 n_samples=50_000, seed=7)
    np.testing.assert_array_equal(nominal.d_delta, measured.d_delta)
    for q in ("relative_error_stats", "angle_stats"):
        got, ref = getattr(measured, q), getattr(small, q)
        assert got.mean == pytest.approx(ref.mean, rel=0.03)
        assert got.p95 == pytest.approx(ref.p95, rel=0.03)
        assert got.mean < getattr(nominal, q).mean / 5.0


def test_monte_carlo_100k_samples_take_under_a_second():
    kw = dict(d_delta_tol=0.5 * DEG, d_gamma_tol=0.5 * DEG, scale_tol=0.02,
              n_samples=100_000)
    best = np.inf
    for law_axes, extra in (("nominal", {}),
                            ("measured", dict(measure_delta_tol=0.05 * DEG,
                                              measure_gamma_tol=0.05
                                              * DEG))):
        for _ in range(2):
            t0 = time.perf_counter()
            r = monte_carlo_accuracy(law_axes=law_axes, **extra, **kw)
            best = min(best, time.perf_counter() - t0)
        assert best < 1.0
        best = np.inf
        assert r.relative_error.shape == (100_000,)


def test_monte_carlo_result_fields_and_summaries():
    r = monte_carlo_accuracy(d_delta_tol=0.5 * DEG, d_gamma_tol=0.3 * DEG,
                             scale_tol=0.02, n_samples=5000,
                             distribution="normal", seed=3)
    assert r.d_delta.shape == r.d_gamma.shape == r.d_scale.shape == (5000,
                                                                     4)
    assert np.max(np.abs(r.d_delta)) < 0.5 * DEG * 5 / 3     # 5σ, σ = t/3
    np.testing.assert_allclose(np.linalg.norm(r.demands, axis=1), 1.0)
    for s in (r.relative_error_stats, r.angle_stats,
              r.magnitude_error_stats):
        assert 0.0 < s.mean <= s.p95 <= s.max
    assert r.tolerances == {"d_delta": 0.5 * DEG, "d_gamma": 0.3 * DEG,
                            "scale": 0.02}


def test_monte_carlo_per_sample_demands_and_failed_wheel():
    M = np.random.default_rng(1).normal(size=(3, 300))
    r = monte_carlo_accuracy(d_delta_tol=0.0, d_gamma_tol=0.0,
                             scale_tol=0.0, demand=M, n_samples=300,
                             failed=[2])
    np.testing.assert_allclose(r.demands, M.T)
    assert r.relative_error_stats.max < 1e-13
    with pytest.raises(RankError):
        monte_carlo_accuracy(d_delta_tol=0.0, d_gamma_tol=0.0,
                             scale_tol=0.0, failed=[0, 1])


# ------------------------------------------------- any array (theory §1.4)
def test_tilted_axes_match_with_mounting_errors():
    arr = WheelArray.orthogonal_plus_skew()
    rng = np.random.default_rng(2)
    ta, tb = rng.uniform(-0.02, 0.02, (2, 6, 4))
    stack = tilted_axes(arr.axes, ta, tb)
    assert stack.shape == (6, 3, 4)
    for s in range(6):
        np.testing.assert_allclose(
            stack[s], arr.with_mounting_errors(ta[s], tb[s]).axes,
            atol=1e-15)
    one = tilted_axes(arr.axes, ta[0], tb[0])     # (N,) tilts: (3, N)
    assert one.shape == (3, 4)
    np.testing.assert_allclose(one, stack[0], rtol=0, atol=1e-15)


def test_orthogonal_triad_coupling_angle_is_the_axis_tilt():
    # wheels on x, y, z and M = (1, 0, 0): m = (1, 0, 0), M1 = h1 tilted,
    # cos Δα = h1·e_x = cos a cos b
    triad = WheelArray.from_axes(np.eye(3))
    r = monte_carlo_accuracy_array(triad, tilt_tol=1.0 * DEG, scale_tol=0.0,
                                   demand=[1.0, 0.0, 0.0], n_samples=1000)
    assert r.mounting == "tilts"
    np.testing.assert_allclose(
        r.angle, np.arccos(np.cos(r.d_delta[:, 0]) * np.cos(r.d_gamma[:, 0])),
        atol=1e-7)   # arccos near 1 limits the reference to ~1e-8


def test_array_monte_carlo_measured_axes_remove_the_coupling():
    arr = WheelArray.orthogonal_plus_skew(failed=[1])
    r = monte_carlo_accuracy_array(arr, tilt_tol=1.0 * DEG, scale_tol=0.0,
                                   law_axes="measured", measure_tol=0.0,
                                   n_samples=2000)
    assert r.relative_error_stats.max < 1e-12
    nominal = monte_carlo_accuracy_array(arr, tilt_tol=1.0 * DEG,
                                         scale_tol=0.0, n_samples=2000)
    assert nominal.relative_error_stats.mean > 1e-3
    with pytest.raises(InvalidValueError, match="measure_tol"):
        monte_carlo_accuracy_array(arr, tilt_tol=0.0, scale_tol=0.0,
                                   law_axes="measured")


# ------------------------------------------------------------ bad input
@pytest.mark.parametrize("kwargs, error, name", [
    (dict(distribution="lognormal"), InvalidValueError, "distribution"),
    (dict(law_axes="true"), InvalidValueError, "law_axes"),
    (dict(law_axes="measured"), InvalidValueError, "measure_delta_tol"),
    (dict(measure_delta_tol=0.1, measure_gamma_tol=0.1), InvalidValueError,
     "measure_delta_tol"),
    (dict(d_delta_tol=-1.0), InvalidValueError, "d_delta_tol"),
    (dict(scale_tol=np.nan), InvalidValueError, "scale_tol"),
    (dict(demand=[1.0, 0.0]), ShapeError, "demand"),
    (dict(demand=[0.0, 0.0, 0.0]), InvalidValueError, "demand"),
    (dict(demand=[np.nan, 0.0, 1.0]), InvalidValueError, "demand"),
    (dict(n_samples=0), InvalidValueError, "n_samples"),
    (dict(failed=[4]), InvalidValueError, "failed"),
    (dict(seed=-1), InvalidValueError, "seed"),
])
def test_bad_monte_carlo_input_names_the_argument(kwargs, error, name):
    base = dict(d_delta_tol=0.001, d_gamma_tol=0.001, scale_tol=0.01,
                n_samples=10)
    with pytest.raises(error, match=name):
        monte_carlo_accuracy(**(base | kwargs))


def test_bad_axes_angles_are_rejected():
    with pytest.raises(ShapeError, match="delta_i"):
        actual_axes(np.zeros(3), np.zeros(3))
    with pytest.raises(InvalidValueError, match="gamma_i"):
        actual_axes(np.zeros(4), [0.0, np.nan, 0.0, 0.0])


# ------------------------------------------------------------------ plot
@pytest.mark.parametrize("quantity", ["relative_error", "angle"])
def test_histogram_plot(quantity):
    r = monte_carlo_accuracy(d_delta_tol=0.5 * DEG, d_gamma_tol=0.5 * DEG,
                             scale_tol=0.02, n_samples=2000)
    ax = plot_accuracy_histogram(r, quantity=quantity)
    ax.figure.canvas.draw()
    assert len(ax.patches) == 60
    assert ax.get_xlabel().startswith("|ΔM|" if quantity.startswith("rel")
                                      else "Δα")
    with pytest.raises(InvalidValueError, match="quantity"):
        plot_accuracy_histogram(r, quantity="torque")
