"""Pseudo-inverse family: plain, redistributed, cascaded, daisy chain.

Every function takes a `WheelArray` (axes (3, N), per-wheel torque limits
``m_max`` [N·m], failed wheels held at zero), a demanded array torque
``M`` (3,) [N·m] and optional per-wheel bounds ``lo``/``hi`` (N,) [N·m]
(e.g. momentum-limited wheels), and returns wheel torques ``m`` (N,)
[N·m] inside the bounds.
"""

from __future__ import annotations

from itertools import combinations
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError

from ..arrays import WheelArray
from ._common import pinv, problem


def pseudo_inverse(array: WheelArray, torque: ArrayLike,
                   lo: ArrayLike | None = None,
                   hi: ArrayLike | None = None) -> np.ndarray:
    r"""Plain pseudo-inverse, clipped: :math:`m = \mathrm{sat}(A^+ M)`.

    The baseline of every comparison in the literature (e.g. Bodson,
    "Evaluation of optimization methods for control allocation", JGCD
    25(4), 2002); [1] eq. (5) with unit weights. Exact (``A m = M``)
    only where no wheel saturates.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Wheel torques [N·m].
    """
    A, M, low, high = problem(array, torque, lo, hi)
    return np.clip(pinv(A) @ M, low, high)


def redistributed_pinv(array: WheelArray, torque: ArrayLike,
                       lo: ArrayLike | None = None,
                       hi: ArrayLike | None = None) -> np.ndarray:
    r"""Redistributed pseudo-inverse (RPI).

    Virnig, J. C. and Bodden, D. S., "Multivariable control allocation
    and control law conditioning when control effectors limit", AIAA
    Guidance, Navigation and Control Conference, AIAA-94-3609, 1994.

    With S the saturated wheels (held at their bounds) and F the free
    ones, each pass solves

    .. math:: m_F = A_F^{+}\,(M - A_S m_S)

    and moves every free wheel that violates its bound into S, clipped;
    it stops when no free wheel violates (or none is left; the last pass
    is then a least-squares answer). All violators are saturated at once
    (compare `cascaded_inverse`).

    Falls short: it is exact wherever it ends with no violation, but a
    wheel clipped early is never freed again, so it does not reach the
    whole attainable set (demands near its boundary are missed), and where
    it redistributes its answer need not be the minimum-norm one.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Wheel torques [N·m].
    """
    return _redistribute(array, torque, lo, hi, _saturate_all)


def _saturate_all(m, free, low, high, sat) -> bool:
    """Clip every free violator and fix it (False: none violates)."""
    bad = free & ((m < low) | (m > high))
    if not bad.any():
        return False
    m[bad] = np.clip(m[bad], low[bad], high[bad])
    sat |= bad
    return True


def _saturate_worst(m, free, low, high, sat) -> bool:
    """Fix the free wheel most beyond its bound, relative to its range."""
    over = np.where(free, np.maximum(m - high, low - m), -np.inf)
    if not np.any(over > 0.0):
        return False
    span = np.maximum(high - low, 1e-300)
    i = int(np.argmax(np.where(free, over / span, -np.inf)))
    m[i] = high[i] if m[i] > high[i] else low[i]
    sat[i] = True
    return True


def _redistribute(array, torque, lo, hi, saturate) -> np.ndarray:
    """The generalised-inverse cascade both redistribution methods run.

    ``m_F = A_F⁺ (M - A_S m_S)`` on the free wheels F, then
    ``saturate(m, free, low, high, sat)`` moves violators into S (in
    place) and says whether it moved any; at most N + 1 stages.
    """
    A, M, low, high = problem(array, torque, lo, hi)
    n = A.shape[1]
    m = np.zeros(n)
    sat = low == high
    m[sat] = low[sat]
    for _ in range(n + 1):
        free = ~sat
        if not free.any():
            break
        r = M - A[:, sat] @ m[sat]
        m[free] = pinv(A[:, free]) @ r
        if not saturate(m, free, low, high, sat):
            break
    return np.clip(m, low, high)


def cascaded_inverse(array: WheelArray, torque: ArrayLike,
                     lo: ArrayLike | None = None,
                     hi: ArrayLike | None = None) -> np.ndarray:
    r"""Cascaded generalised inverse (CGI).

    Bordignon, K. A. and Durham, W. C., "Closed-form solutions to
    constrained control allocation problem", Journal of Guidance,
    Control, and Dynamics 18(5), 1000–1007, 1995.

    A cascade of generalised inverses on the shrinking set F of free
    wheels, :math:`m_F = A_F^{+}(M - A_S m_S)` at each stage. The variant
    implemented here removes one wheel per stage: the free wheel whose
    generalised-inverse command exceeds its bound by the largest ratio
    :math:`m_i/\text{bound}_i` is saturated at that bound and the remaining
    moment is re-solved on the others (the all-at-once variant is
    `redistributed_pinv`; the literature often treats the two as one
    family, e.g. Härkegård 2003). Stops when no free wheel violates.

    Falls short like `redistributed_pinv`: exact where it ends with no
    violation, not on the whole attainable set, not minimum-norm after a
    redistribution.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Wheel torques [N·m].
    """
    return _redistribute(array, torque, lo, hi, _saturate_worst)


def default_groups(array: WheelArray) -> tuple[tuple[int, ...], ...]:
    """Daisy-chain groups: the first triad that spans 3-D, then the rest.

    The first three working wheels (in index order) whose axes span 3-D
    space form the primary group, the other working wheels the secondary
    one: the triad then the skew wheel of a 3 + 1 array, one wheel of each
    pair (0, 2, 4) then the other three of six orthogonal pairs.
    """
    work = [int(i) for i in np.flatnonzero(array.active)]
    if len(work) <= 3:
        return (tuple(work),)
    A = array.working_axes
    for tri in combinations(work, 3):
        if abs(np.linalg.det(A[:, list(tri)])) > 1e-9:
            return (tri, tuple(i for i in work if i not in tri))
    return (tuple(work),)


def daisy_chain(array: WheelArray, torque: ArrayLike,
                lo: ArrayLike | None = None, hi: ArrayLike | None = None,
                groups: Sequence[Sequence[int]] | None = None
                ) -> np.ndarray:
    r"""Daisy-chain allocation over groups of wheels.

    Adams, R. J., Buffington, J. M., Sparks, A. G. and Banda, S. S.,
    *Robust Multivariable Flight Control*, Springer, 1994; analysed in
    Buffington, J. M. and Enns, D. F., "Lyapunov stability analysis of
    daisy chain control allocation", JGCD 19(6), 1226–1230, 1996.

    Group k receives what the groups before it left undone:

    .. math:: m_k = \mathrm{sat}\big(A_k^{+}\,(M - \textstyle\sum_{j<k}
              A_j m_j)\big)

    It applies to arrays whose wheels fall into a primary group that spans
    3-D space and back-up groups: the 3 + 1 array (triad, then the skew
    wheel) and six wheels as two triads. On a pyramid every triple spans
    3-D but no split is natural; the default groups (first three working
    wheels, then the rest) are used there too.

    Falls short: exact only where the chain ends with no residual; the
    secondary group acts only on what the primary could not do, so it
    reaches less than the attainable set and is never minimum-norm once
    the secondary group works.

    Parameters
    ----------
    groups : sequence of sequences of int, optional
        0-based wheel indices of each group, in order (default
        `default_groups`). Wheels in no group get zero torque.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Wheel torques [N·m].
    """
    A, M, low, high = problem(array, torque, lo, hi)
    n = A.shape[1]
    groups = default_groups(array) if groups is None else groups
    m = np.clip(np.zeros(n), low, high)
    seen: set[int] = set()
    r = M - A @ m
    for g in groups:
        idx = np.asarray([int(i) for i in g], dtype=int)
        if idx.size == 0:
            continue
        if np.any((idx < 0) | (idx >= n)) or seen & set(idx.tolist()):
            raise InvalidValueError(
                f"groups must hold distinct 0-based indices < {n}, got "
                f"{groups!r}")
        seen |= set(idx.tolist())
        r = r + A[:, idx] @ m[idx]
        m[idx] = np.clip(pinv(A[:, idx]) @ r, low[idx], high[idx])
        r = r - A[:, idx] @ m[idx]
    return m
