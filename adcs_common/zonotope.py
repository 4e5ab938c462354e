"""Geometry of 3-D zonotopes: attainable momentum, torque and force sets.

The set ``{c + G x : |x_i| <= 1}`` with generators ``G`` (3, N) is the
image of a box through the wheel axes; its facets are spanned by pairs of
non-parallel generators.
"""

from __future__ import annotations

import numpy as np

from adcs_common.exceptions import RankError

_PARALLEL_TOL = 1e-10


def zonotope_facets(generators: np.ndarray, center=None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Facet half-spaces ``n·x <= d`` of ``{c + G x : |x|_inf <= 1}``.

    Parameters
    ----------
    generators : numpy.ndarray, shape (3, N)
        Generators (e.g. ``h_max_i * axis_i``); zero columns are ignored.
    center : array_like (3,), optional
        Centre c (default the origin).

    Returns
    -------
    normals : numpy.ndarray, shape (F, 3)
        Unit outward normals, each facet once.
    offsets : numpy.ndarray, shape (F,)
        Offsets d: the facet lies in ``n·x = d``.

    Raises
    ------
    RankError
        The generators span fewer than three dimensions.
    """
    G = np.asarray(generators, dtype=float)
    G = G[:, np.linalg.norm(G, axis=0) > 0.0]
    scale = float(np.abs(G).max()) if G.size else 0.0
    rank = (int(np.linalg.matrix_rank(G, tol=1e-9 * scale)) if scale > 0
            else 0)
    if rank < 3:
        raise RankError(f"generators span rank {rank} < 3: the set is flat",
                        rank=rank, required=3)
    i, j = np.triu_indices(G.shape[1], k=1)
    cross = np.cross(G[:, i].T, G[:, j].T)
    norms = np.linalg.norm(cross, axis=1)
    scale = np.linalg.norm(G[:, i], axis=0) * np.linalg.norm(G[:, j], axis=0)
    cross = cross[norms > _PARALLEL_TOL * scale]
    n = cross / np.linalg.norm(cross, axis=1)[:, None]
    # canonical sign, then drop repeats (coplanar generator triples)
    first = np.argmax(np.abs(n) > 1e-9, axis=1)
    n *= np.sign(n[np.arange(len(n)), first])[:, None]
    n = np.unique(np.round(n, 12), axis=0)
    n /= np.linalg.norm(n, axis=1)[:, None]
    normals = np.vstack([n, -n])
    offsets = np.sum(np.abs(normals @ G), axis=1)
    if center is not None:
        offsets = offsets + normals @ np.asarray(center, dtype=float)
    return normals, offsets


def zonotope_support(generators: np.ndarray, direction, center=None
                     ) -> np.ndarray:
    """Support function ``max n·x`` over the zonotope.

    Parameters
    ----------
    direction : array_like, shape (3,) or (3, K)
        Direction(s); not normalised, so a unit vector gives the extent.
    """
    d = np.asarray(direction, dtype=float)
    G = np.asarray(generators, dtype=float)
    h = np.sum(np.abs(G.T @ d), axis=0)
    if center is not None:
        h = h + np.asarray(center, dtype=float) @ d
    return h


def radial_extent(normals: np.ndarray, offsets: np.ndarray, direction
                  ) -> np.ndarray:
    """Largest ``t >= 0`` with ``t·u`` inside ``{n·x <= d}``, u unit.

    Parameters
    ----------
    normals, offsets : as returned by `zonotope_facets` (origin inside).
    direction : array_like, shape (3,) or (3, K)
        Direction(s), normalised here.

    Returns
    -------
    float or numpy.ndarray (K,)
        The distance from the origin to the boundary along each direction
        (inf when unbounded).
    """
    d = np.asarray(direction, dtype=float)
    u = d / np.linalg.norm(d, axis=0)
    proj = normals @ u
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(proj > 1e-15, offsets.reshape(-1, *[1] * (u.ndim - 1))
                     / proj, np.inf)
    return np.min(t, axis=0)


def gauge(normals: np.ndarray, offsets: np.ndarray, point) -> np.ndarray:
    """Minkowski gauge: the smallest ``s >= 0`` with ``point`` in ``s·Z``.

    ``point`` lies inside the set when the gauge is at most 1, and
    ``point / gauge`` is on its boundary.
    """
    p = np.asarray(point, dtype=float)
    return np.maximum(np.max((normals @ p) / offsets.reshape(
        -1, *[1] * (p.ndim - 1)), axis=0), 0.0)
