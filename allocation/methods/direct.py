"""Direct allocation: Durham's facet of the attainable set."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.zonotope import zonotope_facets

from ..arrays import WheelArray
from ._common import bounded_lsq, problem

#: Weight of the demand term when splitting a facet among coplanar wheels.
_FACET_GAMMA = 1e10


def direct_allocation(array: WheelArray, torque: ArrayLike,
                      lo: ArrayLike | None = None,
                      hi: ArrayLike | None = None) -> np.ndarray:
    r"""Direct allocation (Durham's facet search).

    Durham, W. C., "Constrained control allocation", Journal of Guidance,
    Control, and Dynamics 16(4), 717–725, 1993.

    The attainable set :math:`\Phi = \{A m : lo \le m \le hi\}` is a
    zonotope whose facets are spanned by pairs of wheel axes (normal
    :math:`n = a_i \times a_j`); on the facet every other wheel sits at
    the bound :math:`\mathrm{sign}(n\cdot a_k)`. The facet the demand's
    direction hits is the one minimising

    .. math:: \alpha^* = \min_{n\cdot M > 0}\; d_n / (n \cdot M)

    (``n·x <= d_n`` the facet); the two free wheels solve
    :math:`[a_i\;a_j]\,m_{ij} = \alpha^* M - \sum_k a_k m_k`, giving the
    boundary point :math:`m^*`. Durham's answer is then
    :math:`m = m^*/\alpha^*` if :math:`\alpha^* \ge 1` (inside: the
    boundary solution scaled back) and :math:`m = m^*` otherwise (the
    demand scaled back, direction kept). Where more than two working axes
    lie in the facet's plane (parallel or coplanar wheels) the free wheels
    share the facet by minimum norm.

    Exact for every attainable demand (it reaches the whole set) and
    direction-preserving outside it, so its achieved torque equals the
    QP's with ``saturation="scale"`` everywhere and its wheel torques
    equal the QP's on and beyond the boundary. Inside, the torques are the
    scaled boundary solution, not the minimum-norm one. Needs the origin
    inside the set (``lo < 0 < hi`` on enough wheels); where a bound
    excludes it (a wheel that must brake) it returns ``clip(0, lo, hi)``.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Wheel torques [N·m].
    """
    A, M, low, high = problem(array, torque, lo, hi)
    rest = np.clip(np.zeros(A.shape[1]), low, high)
    nm = float(np.linalg.norm(M))
    half = (high - low) / 2.0
    centre = A @ ((low + high) / 2.0)
    normals, offsets = zonotope_facets(A * half, centre)
    scale = float(np.max(array.m_max))
    if nm == 0.0 or offsets.size == 0 or np.any(offsets <= 1e-12 * scale):
        return rest
    nM = normals @ M
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(nM > 1e-14 * nm, offsets / nM, np.inf)
    k = int(np.argmin(ratio))
    alpha = float(ratio[k])
    if not np.isfinite(alpha):
        return rest
    na = normals[k] @ A
    tol = 1e-9 * np.max(np.abs(na))
    m = np.where(na > tol, high, low)
    free = (np.abs(na) <= tol) & (high > low)
    m[np.abs(na) <= tol] = rest[np.abs(na) <= tol]
    if free.any():
        r = alpha * M - A[:, ~free] @ m[~free]
        g = np.sqrt(_FACET_GAMMA)
        Af = A[:, free]
        big = np.vstack([g * Af, np.eye(Af.shape[1])])
        rhs = np.concatenate([g * r, np.zeros(Af.shape[1])])
        m[free], _ = bounded_lsq(big, rhs, low[free], high[free])
    return m / alpha if alpha >= 1.0 else m
