"""The trade curve: nominal radius against worst single-failure radius.

`trade_curve` computes the Pareto front of a wheel array's two radii, the
inscribed radius of its envelope nominally and the worst one after any
single wheel fails, by an epsilon-constraint: for failure radii ``eps``
from that of the nominal optimum up to the failure optimum it maximises
the nominal radius subject to ``r_fail >= eps`` (the NLP of
`allocation.design_nlp`, warm-started from the neighbouring points and
from both optima). Every point is certified by the exact envelope code
(`certify_layout`), and only the certified, non-dominated points are
kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from numpy.typing import ArrayLike

import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.results import ResultMixin
from adcs_common.validation import as_count, as_vector

from .arrays import WheelArray
from .design import ArrayDesign, certify_layout, design_array
from .design_nlp import EPS_SCHEDULE, build_design_nlp, family_axes

__all__ = ["TradeCurve", "reference_layouts", "trade_curve"]

#: Smoothing widths of one epsilon-constraint solve (from a warm start).
_TRADE_SCHEDULE = EPS_SCHEDULE[-4:]


@dataclass(frozen=True, eq=False, repr=False)
class TradeCurve(ResultMixin):
    """The Pareto front of nominal against worst single-failure radius.

    Attributes
    ----------
    n_wheels : int
        Number of wheels N.
    quantity : {"momentum", "torque"}
        The envelope.
    capacity : numpy.ndarray, shape (N,)
        Each wheel's capacity [N·m·s or N·m].
    worst_failure_radius : numpy.ndarray, shape (P,)
        Certified worst inscribed radius over every single-wheel failure
        of each front point, increasing [units of ``capacity``].
    radius : numpy.ndarray, shape (P,)
        Certified nominal inscribed radius of each point, non-increasing
        [units].
    axes : numpy.ndarray, shape (P, 3, N)
        Unit spin axes of each point's layout.
    nominal_optimum : float
        Best nominal radius (`design_array` with no failure) [units].
    failure_optimum : float
        Best worst single-failure radius (`design_array` with one
        failure) [units].
    """

    n_wheels: int
    quantity: str
    capacity: np.ndarray
    worst_failure_radius: np.ndarray
    radius: np.ndarray
    axes: np.ndarray
    nominal_optimum: float
    failure_optimum: float

    @property
    def n_points(self) -> int:
        """Number P of points on the front."""
        return int(self.radius.size)


def _icosahedral_axes() -> np.ndarray:
    phi = (1 + np.sqrt(5)) / 2
    v = np.array([[0, 1, phi], [0, -1, phi], [1, phi, 0], [-1, phi, 0],
                  [phi, 0, 1], [phi, 0, -1]], dtype=float).T
    return v / np.linalg.norm(v, axis=0)


def reference_layouts() -> dict[str, tuple[np.ndarray, float, float]]:
    """The reference layouts of the design problem, with their radii.

    Returns
    -------
    dict
        Name -> ``(axes, nominal, failed)``: unit spin axes (3, N), and
        the reference nominal inscribed radius and worst single-failure
        radius for unit capacity per wheel (NaN where the layout is not
        the reference of that radius). Computed from the facet formula;
        the cone angles are to 1e-7 degree.
    """
    nan = float("nan")
    cone = {a: family_axes("cone", n, [np.deg2rad(a)])
            for n, a in ((4, np.rad2deg(np.arccos(1 / np.sqrt(3)))),
                         (5, 54.2322925), (5, 48.0300847))}
    a4, a5n, a5f = cone
    return {
        "4 wheels, tetrahedral pyramid (54.7356°)":
            (cone[a4], 4 / np.sqrt(6), 2 / np.sqrt(6)),
        "4 wheels, 3 orthogonal + 1 skew (NASA standard)":
            (WheelArray.orthogonal_plus_skew(skew="equal_angle").axes,
             np.sqrt(2), 1 / np.sqrt(3)),
        "5 wheels, best cone (54.232°)": (cone[a5n], 2.182643356, nan),
        "5 wheels, cone best for one failure (48.030°)":
            (cone[a5f], nan, np.sqrt(5) - 1),
        "6 wheels, icosahedral axes":
            (_icosahedral_axes(), 2.752763841, 1.902113033),
        "4 wheels, the Meteor-M pyramid (55°, 45°)":
            (WheelArray.pyramid().axes, 1.630253, nan),
    }


def _solve_at(nlp, n, axes, capacity, eps_fail, quantity):
    """Maximise the nominal radius with ``r_fail >= eps_fail`` from axes.

    Returns the certified (nominal, worst failure, axes) or None.
    """
    params = axes[:, 1:].ravel(order="F")      # the free family: a0 = z
    t0 = np.array([0.0, eps_fail])
    for eps in _TRADE_SCHEDULE:
        z, _ = nlp.solve(params, capacity, t0, eps, 1.0, eps_fail)
        params, t0 = z[:nlp.n_par], z[-nlp.n_t:]
    out = family_axes("free", n, params)
    out = out / np.linalg.norm(out, axis=0)
    nominal, worst = certify_layout(out, capacity, 1, quantity)
    return nominal, worst, out


def _to_z(axes: np.ndarray) -> np.ndarray:
    """Rotate a layout so that its first axis is body z (the free
    family's fixed axis); radii are unchanged by rotation."""
    a = axes[:, 0] / np.linalg.norm(axes[:, 0])
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(a, z), float(a @ z)
    if np.linalg.norm(v) < 1e-12:
        return axes if c > 0 else np.diag([1.0, -1.0, -1.0]) @ axes
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    rot = np.eye(3) + vx + vx @ vx / (1 + c)
    return rot @ axes


def _pareto(points, tol):
    """Non-dominated points, sorted by increasing failure radius."""
    pts = sorted(points, key=lambda p: (-p[1], -p[0]))
    front, best_nom = [], -np.inf
    for nom, worst, axes in pts:               # decreasing failure radius
        if nom > best_nom + tol:
            front.append((nom, worst, axes))
            best_nom = nom
    return front[::-1]


def trade_curve(n_wheels: int, *, points: int = 9,
                quantity: str = "momentum", capacity: ArrayLike = 1.0,
                starts: int = 10, seed: int | None = 0,
                tol: float = 1e-7) -> TradeCurve:
    """Pareto front of nominal radius against worst single-failure radius.

    Parameters
    ----------
    n_wheels : int
        Number of wheels N (4..12; one failure must leave three).
    points : int
        Number of failure-radius levels of the epsilon-constraint between
        the two optima (at least 2; both ends included).
    quantity : {"momentum", "torque"}
        The envelope.
    capacity : float or array_like (N,)
        Each wheel's capacity [N·m·s or N·m], fixed.
    starts : int
        Random starts of each of the two end-point designs.
    seed : int or None
        Seed of those starts.
    tol : float
        Tolerance [units] of the certified failure radius against its
        level, and of dominance.

    Returns
    -------
    TradeCurve
        The certified non-dominated points, increasing in failure radius;
        the first is the nominal optimum, the last the failure optimum
        (one point when one layout is both).

    Raises
    ------
    InvalidValueError
        Fewer than 4 wheels, fewer than 2 points, a bad capacity.
    """
    n = as_count(n_wheels, "n_wheels", minimum=4)
    points = as_count(points, "points", minimum=2)
    capacity = as_vector(capacity, n, "capacity")
    if np.any(capacity <= 0):
        raise InvalidValueError("capacity must be positive")
    common: dict[str, Any] = dict(quantity=quantity, capacity=capacity,
                                  starts=starts, seed=seed)
    nom: ArrayDesign = design_array(n, **common)
    fail: ArrayDesign = design_array(n, failures=1, **common)
    nlp = build_design_nlp("free", n, 1, None)
    ends = [(nom.radius, nom.worst_failure_radius, nom.axes)]
    # the failure end: the largest nominal radius at the failure optimum
    top = _solve_at(nlp, n, _to_z(fail.axes), capacity,
                    fail.worst_failure_radius - tol, quantity)
    ends.append(top if top[1] >= fail.worst_failure_radius - 2 * tol
                else (fail.radius, fail.worst_failure_radius, fail.axes))
    found = list(ends)
    lo, hi = nom.worst_failure_radius, ends[1][1]
    if hi - lo > tol:
        prev = _to_z(nom.axes)
        for level in np.linspace(lo, hi, points)[1:-1]:
            cands = [_solve_at(nlp, n, start, capacity, level, quantity)
                     for start in (prev, _to_z(ends[1][2]))]
            cands = [c for c in cands if c[1] >= level - tol]
            if cands:
                best = max(cands, key=lambda c: c[0])
                found.append(best)
                prev = _to_z(best[2])
    front = _pareto(found, tol)
    return TradeCurve(
        n_wheels=n, quantity=quantity, capacity=capacity,
        worst_failure_radius=np.array([p[1] for p in front]),
        radius=np.array([p[0] for p in front]),
        axes=np.array([p[2] for p in front]),
        nominal_optimum=nom.radius, failure_optimum=fail.worst_failure_radius)
