"""Momentum and torque envelopes of a wheel array ([1], theory §1.2)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import NamedTuple, TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from adcs_common.results import ResultMixin

from adcs_common.exceptions import InvalidValueError, RankError, ShapeError
from adcs_common.validation import as_finite_array, check_instance

from .arrays import WheelArray
from .zonotope import radial_extent, zonotope_facets

if TYPE_CHECKING:
    import pandas as pd


__all__ = ["Envelope", "Facets", "envelope", "unit_directions"]

#: Envelope kinds and the `WheelArray` capacity each one uses.
_CAPACITY = {"momentum": "h_max", "torque": "m_max"}
#: Units of each kind, for reports and plot labels.
UNITS = {"momentum": "N·m·s", "torque": "N·m"}

_PARALLEL_TOL = 1e-10
_ON_FACET_TOL = 1e-9


class Facets(NamedTuple):
    """Facet half-spaces ``normals @ x <= offsets`` of a polytope.

    Attributes
    ----------
    normals : numpy.ndarray, shape (F, 3)
        Unit outward normals [1], each facet once.
    offsets : numpy.ndarray, shape (F,)
        Distances of the facet planes from the origin, in the envelope's
        units [N·m·s] or [N·m].
    """

    normals: np.ndarray
    offsets: np.ndarray


def unit_directions(direction, name: str = "direction") -> np.ndarray:
    """Check direction(s) and return them as unit vectors.

    Parameters
    ----------
    direction : array_like, shape (3,) or (3, K)
        Direction(s) in the body frame, any non-zero length.
    name : str
        Argument name used in error messages.

    Returns
    -------
    numpy.ndarray, shape (3,) or (3, K)
        Unit vectors.

    Raises
    ------
    ShapeError
        ``direction`` is not (3,) or (3, K).
    InvalidValueError
        ``direction`` holds NaN/inf or a zero vector.
    """
    d = as_finite_array(direction, name)
    if d.ndim not in (1, 2) or d.shape[0] != 3:
        raise ShapeError(
            f"{name} must have shape (3,) or (3, K), got {d.shape}")
    norms = np.linalg.norm(d, axis=0)
    if np.any(norms < 1e-300):
        bad = np.flatnonzero(np.atleast_1d(norms) < 1e-300).tolist()
        raise InvalidValueError(
            f"{name} must be non-zero; zero vector(s) at column(s) {bad}")
    return d / norms


def _merge_parallel(G: np.ndarray) -> np.ndarray:
    """Merge parallel or antiparallel generators into one each.

    The segment sums ``[-g, g] + [-c g', c g']`` with ``g' ∥ g`` are one
    segment of half-length ``|g| + |g'|``, so the zonotope is unchanged.
    """
    G = G[:, np.linalg.norm(G, axis=0) > 0.0]
    merged: list[np.ndarray] = []
    for g in G.T:
        for k, m in enumerate(merged):
            cross = np.linalg.norm(np.cross(m, g))
            if cross <= _PARALLEL_TOL * np.linalg.norm(m) * np.linalg.norm(g):
                sign = 1.0 if m @ g > 0 else -1.0
                merged[k] = m + sign * g
                break
        else:
            merged.append(np.array(g))
    return np.column_stack(merged)


def _zonotope_vertices(G: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Vertices of ``{G x : |x|_inf <= 1}`` from its facet normals.

    The face maximising ``n·x`` is the sum of ``sign(n·g_k) g_k`` over the
    generators off the facet plane plus the segments of the generators in
    it; its corners are the ``2^k`` sign choices of the ``k`` in-plane
    generators (``k = 2`` unless three generators are coplanar). This
    visits ``F·2^k`` candidates instead of all ``2^N`` sign patterns; the
    convex hull then keeps the true vertices.
    """
    scale = np.linalg.norm(G, axis=0)
    proj = normals @ G                                   # (F, N)
    in_plane = np.abs(proj) <= _ON_FACET_TOL * scale
    candidates = []
    for n_proj, plane in zip(proj, in_plane):
        base = np.where(plane, 0.0, np.sign(n_proj))
        idx = np.flatnonzero(plane)
        for signs in itertools.product((-1.0, 1.0), repeat=len(idx)):
            s = base.copy()
            s[idx] = signs
            candidates.append(G @ s)
    from scipy.spatial import ConvexHull   # lazy: keeps import fast

    pts = np.unique(np.round(np.array(candidates), 12), axis=0)
    hull = ConvexHull(pts)
    return pts[np.sort(hull.vertices)]


@dataclass(frozen=True, eq=False, repr=False)
class Envelope(ResultMixin):
    r"""Attainable momentum or torque set of a wheel array: a zonotope.

    The set :math:`S = \{A\,\mathrm{diag}(c)\,x : |x_i| \le 1\}` of
    [1] ("properties of the wheel system"), ``c`` the momentum
    capacity H* [N·m·s] or torque capacity m_max [N·m] of each working
    wheel; failed wheels are left out. For the Meteor-M pyramid it is the
    12-faced polyhedron with rhombic faces of side 2H*.

    The set is always centrally symmetric about the origin (each wheel can
    store or apply ±capacity), so every ``-u`` quantity equals the ``u``
    one; in particular the ``-`` axis intercepts equal `axis_max`.

    Attributes
    ----------
    kind : {"momentum", "torque"}
        Which capacity spans the set.
    units : str
        ``"N·m·s"`` or ``"N·m"``.
    generators : numpy.ndarray, shape (3, N_working)
        Columns ``c_i h_i`` of the working wheels [units].
    vertices : numpy.ndarray, shape (V, 3)
        Vertices [units], one per row, no repeats.
    facets : Facets
        ``(normals (F, 3), offsets (F,))`` with ``normals @ x <= offsets``
        on the set; offsets in [units].
    inscribed_radius : float
        Radius of the largest origin-centred sphere inside the set, the
        smallest facet offset [units] (the paper's r ≈ 1.63 H*).
    circumscribed_radius : float
        Largest vertex norm [units] (the paper's circumscribed sphere).
    axis_max : numpy.ndarray, shape (3,)
        Largest momentum/torque purely along body x, y, z: the axis
        intercepts of the set [units] (the paper's H*x, H*y, H*z). Equal to
        the support along the axis when the axis meets a vertex (nominal
        pyramid), smaller otherwise (after a failure).
    capacity_sum : float
        Arithmetic sum of the working wheels' capacities [units] (the
        paper's H_Σ = 4H*).
    utilisation : float
        ``inscribed_radius / capacity_sum`` [1], the paper's coefficient of
        use r/H_Σ. Only working wheels count in H_Σ: after a failure it
        measures what the remaining wheels deliver of what they could.
    volume : float
        Volume [units³], exact:
        :math:`8\sum_{i<j<k}|\det(g_i, g_j, g_k)|`.
    failed : tuple of int
        0-based indices of the failed wheels left out.
    """

    kind: str
    units: str
    generators: np.ndarray
    vertices: np.ndarray
    facets: Facets
    inscribed_radius: float
    circumscribed_radius: float
    axis_max: np.ndarray
    capacity_sum: float
    utilisation: float
    volume: float
    failed: tuple[int, ...] = ()

    @property
    def n_facets(self) -> int:
        """Number of facets F (12 for the pyramid, 6 for a box)."""
        return int(self.facets.normals.shape[0])

    @property
    def n_vertices(self) -> int:
        """Number of vertices V (14 for the pyramid, 8 for a box)."""
        return int(self.vertices.shape[0])

    def support(self, direction: ArrayLike) -> float | np.ndarray:
        r"""Extent of the set along direction(s): the support function.

        .. math:: h_S(u) = \max_{x \in S} u \cdot x
                  = \sum_i |u \cdot g_i|, \quad u = d/|d|

        Parameters
        ----------
        direction : array_like, shape (3,) or (3, K)
            Body-frame direction(s), normalised here (any non-zero length).

        Returns
        -------
        float or numpy.ndarray, shape (K,)
            Farthest extent [units]; the farthest point need not lie on the
            direction itself (compare `radial_extent`).
        """
        u = unit_directions(direction)
        h = np.sum(np.abs(self.generators.T @ u), axis=0)
        return float(h) if u.ndim == 1 else h

    def radial_extent(self, direction: ArrayLike) -> float | np.ndarray:
        """Largest ``t`` with ``t·u`` in the set (the ray's exit point).

        Parameters
        ----------
        direction : array_like, shape (3,) or (3, K)
            Body-frame direction(s), normalised here.

        Returns
        -------
        float or numpy.ndarray, shape (K,)
            Largest momentum/torque purely along each direction [units];
            `axis_max` is this along the body axes.
        """
        u = unit_directions(direction)
        r = radial_extent(self.facets.normals, self.facets.offsets, u)
        return float(r) if u.ndim == 1 else r

    def contains(self, point: ArrayLike,
                 tol: float = 1e-9) -> bool | np.ndarray:
        """Whether point(s) (3,) or (3, K) lie in the set (within tol)."""
        p = np.asarray(point, dtype=float)
        if p.ndim not in (1, 2) or p.shape[0] != 3:
            raise ShapeError(
                f"point must have shape (3,) or (3, K), got {p.shape}")
        p = as_finite_array(p, "point")
        off = self.facets.offsets.reshape(-1, *[1] * (p.ndim - 1))
        inside = np.all(self.facets.normals @ p <= off * (1 + tol) + tol,
                        axis=0)
        return bool(inside) if p.ndim == 1 else inside


def envelope(array: WheelArray, kind: str = "momentum") -> Envelope:
    r"""Momentum or torque envelope of a wheel array ([1], theory §1.2).

    .. math::
        S = \{A H : |H_i| \le H^*_i\}\ \text{(momentum)},\qquad
        \{A m : |m_i| \le m_{\max,i}\}\ \text{(torque)}

    with A the working axes (failed wheels left out). Facets come from
    pairs of generators (`zonotope_facets`), vertices from the sign
    pattern of each facet (no 2^N enumeration), so arrays with many
    wheels are cheap. Scale-factor errors are not part of the envelope
    (the capacity is the physical limit; see `allocation.accuracy`).

    Parameters
    ----------
    array : WheelArray
        The array; ``array.h_max`` [N·m·s] or ``array.m_max`` [N·m] sets
        each wheel's capacity.
    kind : {"momentum", "torque"}
        Which capacity spans the set.

    Returns
    -------
    Envelope
        Geometry in the array's units.

    Raises
    ------
    InvalidValueError
        ``kind`` is not one of the two, or ``array`` is not a WheelArray.
    RankError
        The working wheels span fewer than three dimensions (the set is
        flat; e.g. two wheels left of the pyramid).
    """
    check_instance(array, WheelArray, "array")
    if not isinstance(kind, str) or kind not in _CAPACITY:
        raise InvalidValueError(
            f"kind must be 'momentum' or 'torque', got {kind!r}")
    capacity = np.asarray(getattr(array, _CAPACITY[kind]))
    active = array.active
    G = array.axes[:, active] * capacity[active]           # (3, N_w)
    # relative tolerance: capacities of 1e-10 are as valid as of 1e3
    rank_tol = 1e-9 * float(np.abs(G).max(initial=0.0))
    r = int(np.linalg.matrix_rank(G, tol=rank_tol)) if rank_tol > 0 else 0
    if r < 3:
        raise RankError(
            f"array: the working wheels span rank {r} < 3 (failed wheels "
            f"{[i + 1 for i in array.failed]}); the {kind} envelope is "
            "flat", rank=r, required=3)
    merged = _merge_parallel(G)
    normals, offsets = zonotope_facets(merged)
    vertices = _zonotope_vertices(merged, normals)
    axis_max = radial_extent(normals, offsets, np.eye(3))
    vol = 8.0 * sum(
        abs(np.linalg.det(merged[:, list(c)]))
        for c in itertools.combinations(range(merged.shape[1]), 3))
    inscribed = float(np.min(offsets))
    cap_sum = float(np.sum(capacity[active]))
    for arr in (G, vertices, normals, offsets, axis_max):
        arr.setflags(write=False)
    return Envelope(
        kind=kind, units=UNITS[kind], generators=G, vertices=vertices,
        facets=Facets(normals, offsets), inscribed_radius=inscribed,
        circumscribed_radius=float(np.max(np.linalg.norm(vertices,
                                                         axis=1))),
        axis_max=axis_max, capacity_sum=cap_sum,
        utilisation=inscribed / cap_sum, volume=float(vol),
        failed=tuple(array.failed))


def envelope_frame(array: WheelArray, kind: str = "momentum",
                   failures: bool = True) -> pd.DataFrame:
    """Envelope figures, nominal and per single failure, as a DataFrame.

    One row per case (``failed``: "none" or the wheel named 1..N):
    inscribed radius, axis maxima and support along x, y, z, utilisation
    and facet count [N·m·s or N·m, as ``kind``]. Cases whose working
    wheels no longer span 3-D are left out.
    """
    import pandas as pd

    check_instance(array, WheelArray, "array")
    cases = [("none", array)]
    if failures:
        cases += [(str(k + 1), array.with_failed(k))
                  for k in range(array.n_wheels) if array.active[k]]
    rows = []
    for name, arr in cases:
        if arr.rank < 3:
            continue
        env = envelope(arr, kind)
        sup = np.asarray(env.support(np.eye(3)))     # (3,)
        rows.append({"failed": name,
                     "inscribed_radius": env.inscribed_radius,
                     "axis_max_x": env.axis_max[0],
                     "axis_max_y": env.axis_max[1],
                     "axis_max_z": env.axis_max[2],
                     "support_x": sup[0], "support_y": sup[1],
                     "support_z": sup[2], "utilisation": env.utilisation,
                     "facets": env.n_facets})
    return pd.DataFrame(rows)
