"""Momentum envelope of [1] ("properties of the wheel system"), theory §1.2.

One test per row of the theory §1.2 table (H* = 1), nominal and after each
single failure. The pyramid is symmetric under the reflections y -> -y
(swaps wheels 1-2 and 3-4) and z -> -z (swaps 1-4 and 2-3), so all four
single failures give the same numbers; the tests check every wheel.
"""

import itertools

import matplotlib
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from allocation import InvalidValueError, RankError, ShapeError, WheelArray
from allocation.envelope import Envelope, envelope
from allocation.plots import facet_polygons, plot_envelope
from conftest import DELTA, GAMMA

matplotlib.use("Agg")

SD, CD = np.sin(DELTA), np.cos(DELTA)
SG, CG = np.sin(GAMMA), np.cos(GAMMA)
WHEELS = [0, 1, 2, 3]
EX, EY, EZ = np.eye(3)


@pytest.fixture
def env(pyramid) -> Envelope:
    return envelope(pyramid, "momentum")


# ------------------------------------------------------ theory §1.2, nominal
def test_row_Hx_star_is_4_sin_delta_cos_gamma_2_3169(env):
    assert env.axis_max[0] == pytest.approx(4 * SD * CG, abs=1e-12)
    assert env.axis_max[0] == pytest.approx(2.3169, abs=5e-5)


def test_row_Hy_star_is_4_sin_delta_sin_gamma_2_3169(env):
    assert env.axis_max[1] == pytest.approx(4 * SD * SG, abs=1e-12)
    assert env.axis_max[1] == pytest.approx(2.3169, abs=5e-5)


def test_row_Hz_star_is_4_cos_delta_2_2943(env):
    assert env.axis_max[2] == pytest.approx(4 * CD, abs=1e-12)
    assert env.axis_max[2] == pytest.approx(2.2943, abs=5e-5)


def test_nominal_axis_max_equals_support_along_the_axes(env):
    # the body axes meet vertices of the pyramid's zonotope
    np.testing.assert_allclose(env.support(np.eye(3)), env.axis_max,
                               atol=1e-12)
    np.testing.assert_allclose(env.radial_extent(-np.eye(3)), env.axis_max,
                               atol=1e-12)


def test_row_circumscribed_radius_equals_Hx_star_2_3169(env):
    assert env.circumscribed_radius == pytest.approx(env.axis_max[0],
                                                     abs=1e-12)
    assert env.circumscribed_radius == pytest.approx(2.3169, abs=5e-5)


def test_row_inscribed_radius_1_6303(env):
    assert env.inscribed_radius == pytest.approx(1.6303, abs=5e-5)
    # the sphere of that radius touches a facet: support there equals r
    n = env.facets.normals[np.argmin(env.facets.offsets)]
    assert env.support(n) == pytest.approx(env.inscribed_radius, abs=1e-12)


def test_row_utilisation_r_over_4Hstar_0_4076(env):
    assert env.capacity_sum == pytest.approx(4.0)
    assert env.utilisation == pytest.approx(0.4076, abs=5e-5)
    assert env.utilisation == pytest.approx(0.4, abs=0.01)   # the paper


def test_row_12_facets_rhombic_with_side_2Hstar(env):
    assert env.n_facets == 12
    assert env.n_vertices == 14
    for poly in facet_polygons(env):
        assert poly.shape == (4, 3)
        sides = np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1)
        np.testing.assert_allclose(sides, 2.0, atol=1e-12)


# ------------------------------------------- theory §1.2, one wheel failed
@pytest.mark.parametrize("failed", WHEELS)
def test_row_after_failure_inscribed_radius_0_8151_halved(pyramid, env,
                                                          failed):
    e = envelope(pyramid.with_failed(failed))
    assert e.inscribed_radius == pytest.approx(0.8151, abs=5e-5)
    assert e.inscribed_radius == pytest.approx(env.inscribed_radius / 2,
                                               abs=1e-12)


@pytest.mark.parametrize("failed", WHEELS)
def test_row_after_failure_axis_max_x_y_1_1585_z_1_1472_halved(
        pyramid, env, failed):
    e = envelope(pyramid.with_failed(failed))
    np.testing.assert_allclose(e.axis_max, [1.1585, 1.1585, 1.1472],
                               atol=5e-5)
    np.testing.assert_allclose(e.axis_max, env.axis_max / 2, atol=1e-12)
    # the - intercepts are the same (the set is centrally symmetric)
    np.testing.assert_allclose(e.radial_extent(-np.eye(3)), e.axis_max,
                               atol=1e-12)


@pytest.mark.parametrize("failed", WHEELS)
def test_row_after_failure_support_x_y_1_7377_z_1_7207_off_axis(
        pyramid, failed):
    e = envelope(pyramid.with_failed(failed))
    np.testing.assert_allclose(e.support(np.eye(3)),
                               [1.7377, 1.7377, 1.7207], atol=5e-5)
    # reached at a vertex that is off the axis
    for k in range(3):
        best = e.vertices[np.argmax(e.vertices[:, k])]
        assert best[k] == pytest.approx(e.support(np.eye(3)[k]))
        assert np.linalg.norm(np.delete(best, k)) > 0.5


@pytest.mark.parametrize("failed", WHEELS)
def test_after_failure_the_set_is_a_parallelepiped(pyramid, failed):
    e = envelope(pyramid.with_failed(failed))
    assert (e.n_facets, e.n_vertices) == (6, 8)
    assert e.capacity_sum == 3.0
    assert e.failed == (failed,)


# ---------------------------------------------------- general properties
def test_vertices_match_brute_force_hull_of_all_sign_patterns(env,
                                                              pyramid):
    pts = np.array([pyramid.axes @ np.array(s) for s in
                    itertools.product((-1.0, 1.0), repeat=4)])
    hull_pts = pts[ConvexHull(pts).vertices]
    got = {tuple(np.round(v, 9)) for v in env.vertices}
    assert got == {tuple(np.round(v, 9)) for v in hull_pts}
    assert env.volume == pytest.approx(ConvexHull(pts).volume, rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_arrays_agree_with_brute_force_hull(seed):
    rng = np.random.default_rng(seed)
    n = 5 + seed
    axes = rng.normal(size=(3, n))
    arr = WheelArray.from_axes(axes, h_max=rng.uniform(0.5, 2, n),
                               normalize=True)
    e = envelope(arr)
    pts = np.array([arr.axes @ (arr.h_max * np.array(s)) for s in
                    itertools.product((-1.0, 1.0), repeat=n)])
    hull = ConvexHull(pts)
    assert e.n_vertices == len(hull.vertices)
    assert e.volume == pytest.approx(hull.volume, rel=1e-10)
    assert e.circumscribed_radius == pytest.approx(
        np.max(np.linalg.norm(pts, axis=1)), rel=1e-12)
    assert e.n_facets == n * (n - 1)       # general position
    u = rng.normal(size=(3, 200))
    u /= np.linalg.norm(u, axis=0)
    np.testing.assert_allclose(e.support(u), np.max(pts @ u, axis=0),
                               rtol=1e-12)
    # the ray's exit point lies on the boundary
    r = e.radial_extent(u)
    assert np.all(e.contains(r * u))
    assert not np.any(e.contains(1.001 * r * u))


def test_orthogonal_pairs_is_a_box_hand_checked():
    # Chibis-M: wheels 1-2 on x, 3-4 on y, 5-6 on z; H* = 1, 2, 1, 1, 3, 1
    arr = WheelArray.orthogonal_pairs(h_max=[1.0, 2.0, 1.0, 1.0, 3.0, 1.0])
    e = envelope(arr)
    assert (e.n_facets, e.n_vertices) == (6, 8)
    np.testing.assert_allclose(e.axis_max, [3.0, 2.0, 4.0])
    np.testing.assert_allclose(e.support(np.eye(3)), [3.0, 2.0, 4.0])
    assert e.inscribed_radius == pytest.approx(2.0)
    assert e.circumscribed_radius == pytest.approx(np.sqrt(9 + 4 + 16))
    assert e.volume == pytest.approx(6.0 * 4.0 * 8.0)
    assert e.utilisation == pytest.approx(2.0 / 9.0)
    assert e.support([1.0, 1.0, 0.0]) == pytest.approx(5.0 / np.sqrt(2))
    # wheel 2 (x) failed: the x half-width drops to 1
    e2 = envelope(arr.with_failed(1))
    np.testing.assert_allclose(e2.axis_max, [1.0, 2.0, 4.0])


def test_torque_envelope_uses_m_max(pyramid):
    arr = WheelArray.pyramid(DELTA, GAMMA, h_max=4.0, m_max=0.2)
    e = envelope(arr, kind="torque")
    assert e.units == "N·m"
    assert e.inscribed_radius == pytest.approx(0.2 * 1.6302528, rel=1e-6)
    np.testing.assert_allclose(e.generators, 0.2 * arr.axes)


def test_support_is_vectorised_over_columns(env):
    u = np.array([[1.0, 0.0, 1.0], [0.0, 2.0, 1.0], [0.0, 0.0, 1.0]])
    got = env.support(u)
    assert got.shape == (3,)
    for k in range(3):
        assert got[k] == pytest.approx(env.support(u[:, k]))


# ------------------------------------------------------------ bad input
def test_unknown_kind_is_rejected_naming_it(pyramid):
    with pytest.raises(InvalidValueError, match="kind"):
        envelope(pyramid, kind="energy")


@pytest.mark.parametrize("bad, error", [
    ([np.nan, 0.0, 1.0], InvalidValueError),
    ([0.0, 0.0, 0.0], InvalidValueError),
    ([1.0, 0.0], ShapeError),
    (np.ones((2, 3)), ShapeError),
    (np.ones((3, 2, 2)), ShapeError),
])
def test_bad_direction_raises_naming_direction(env, bad, error):
    with pytest.raises(error, match="direction"):
        env.support(bad)
    with pytest.raises(error, match="direction"):
        env.radial_extent(bad)


def test_flat_set_after_two_failures_raises_rank_error(pyramid):
    with pytest.raises(RankError, match="flat"):
        envelope(pyramid.with_failed(0, 1))


def test_non_array_is_rejected():
    with pytest.raises(InvalidValueError, match="array"):
        envelope(np.eye(3))


# ------------------------------------------------------------------ plot
def test_plot_envelope_draws_12_faces_without_pyplot(env):
    ax = plot_envelope(env, show_spheres=True)
    assert ax.name == "3d"
    ax.figure.canvas.draw()            # renders with Agg, no window
    assert len(ax.collections[0].get_paths()) == 12


def test_plot_envelope_rejects_2d_axes(env):
    from matplotlib.figure import Figure
    with pytest.raises(InvalidValueError, match="ax"):
        plot_envelope(env, ax=Figure().add_subplot())


def test_package_exposes_envelope_as_a_function(pyramid):
    import allocation
    e = allocation.envelope(pyramid, kind="torque")
    assert isinstance(e, allocation.Envelope)
    assert all(hasattr(allocation, name) for name in allocation.__all__)
    assert allocation.__all__ == sorted(allocation.__all__)


def test_orthogonal_plus_equal_angle_skew_inscribed_radius_sqrt2():
    # facet normal e1 x s = (0, -1, 1)/sqrt(2), s = (1, 1, 1)/sqrt(3):
    # offset = |e2·n| + |e3·n| + |s·n| = 2/sqrt(2) = sqrt(2), the smallest
    e = envelope(WheelArray.orthogonal_plus_skew(skew="equal_angle"))
    assert e.inscribed_radius == pytest.approx(np.sqrt(2.0), abs=1e-12)
    assert e.utilisation == pytest.approx(np.sqrt(2.0) / 4.0, abs=1e-12)
    # along x: wheel 1 at +1, the skew wheel at +1 adds 1/sqrt(3) to x and
    # its y, z parts are cancelled by wheels 2, 3 at -1/sqrt(3)
    np.testing.assert_allclose(e.axis_max, 1.0 + 1.0 / np.sqrt(3.0),
                               atol=1e-12)
    assert e.support(np.ones(3)) == pytest.approx(np.sqrt(3.0) + 1.0)


def test_utilisation_of_arrays_with_more_wheels_stays_below_0_47():
    # [1] quoting ref. [5]: with more wheels the coefficient of use
    # does not exceed 0.47; e.g. six wheels on the icosahedron's axes,
    # N wheels on a 54.7° cone
    p = (1.0 + np.sqrt(5.0)) / 2.0
    ico = np.array([[0, 1, p], [0, -1, p], [1, p, 0], [-1, p, 0],
                    [p, 0, 1], [p, 0, -1]], dtype=float).T
    arrays = [WheelArray.from_axes(ico, normalize=True)]
    beta = np.arccos(1.0 / np.sqrt(3.0))
    for n in (5, 6, 8, 12):
        th = 2.0 * np.pi * np.arange(n) / n
        arrays.append(WheelArray.from_axes(np.vstack([
            np.sin(beta) * np.cos(th), np.sin(beta) * np.sin(th),
            np.cos(beta) * np.ones(n)])))
    util = [envelope(a).utilisation for a in arrays]
    assert max(util) <= 0.47
    assert util[0] == pytest.approx(0.4588, abs=5e-5)
    assert util[2] == pytest.approx(4.0 / 9.0, abs=1e-12)   # six on cone


def test_envelope_frame_holds_theory_1_2_nominal_and_failed(pyramid):
    from allocation import envelope_frame

    frame = envelope_frame(pyramid)
    assert list(frame["failed"]) == ["none", "1", "2", "3", "4"]
    nominal = frame.iloc[0]
    assert nominal["inscribed_radius"] == pytest.approx(1.6303, abs=1e-4)
    assert nominal["axis_max_z"] == pytest.approx(2.2943, abs=1e-4)
    assert nominal["utilisation"] == pytest.approx(0.4076, abs=1e-4)
    one = frame.iloc[1]
    assert one["inscribed_radius"] == pytest.approx(0.8151, abs=1e-4)
    assert one["support_z"] == pytest.approx(1.7207, abs=1e-4)
