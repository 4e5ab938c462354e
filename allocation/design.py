"""Choose the wheel array: axes (and sizes) of the largest envelope.

`design_array` picks the spin axes of ``n`` wheels, free or within a
family (`FAMILIES`: cone, four-wheel pyramid, 3 + 1, canted orthogonal
pairs), and optionally each wheel's capacity under a total budget, so as
to maximise

* the inscribed radius of the momentum or torque envelope (the largest
  momentum or torque available in *every* direction), nominal;
* or the worst such radius over every ``k``-wheel failure;
* or a weighted trade ``(1 - w) r_fail + w r_nom``.

Method: the epigraph NLP of `allocation.design_nlp` (facet normals from
pairs of axes, a smooth lower bound of each support value) solved by
IPOPT from several random starts (a failure design follows the nominal
objective first, then the failure one), each answer then certified by the exact
envelope code (`allocation.envelope`): the radii reported are the
certified ones, never the NLP's.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

from numpy.typing import ArrayLike

import numpy as np

from adcs_common.exceptions import InvalidValueError, RankError
from adcs_common.results import ResultMixin
from adcs_common.validation import as_count, as_finite_scalar, as_vector

from .arrays import WheelArray
from .design_nlp import (
    EPS_SCHEDULE,
    FAMILIES,
    build_design_nlp,
    family_axes,
    random_params,
)
from .envelope import envelope

#: Smoothing widths of the nominal phase of a failure design, and of its
#: failure phase that follows.
NOMINAL_SCHEDULE = EPS_SCHEDULE[:5]
FAILURE_SCHEDULE = EPS_SCHEDULE[2:]

__all__ = ["ArrayDesign", "FAMILIES", "certify_layout", "design_array"]

#: Most wheels `design_array` takes (the NLP has one row per facet and
#: failure case: C(n, k) C(n - k, 2)).
MAX_DESIGN_WHEELS = 12
_QUANTITIES = {"momentum", "torque"}


@dataclass(frozen=True, eq=False, repr=False)
class ArrayDesign(ResultMixin):
    """The best layout found, certified by the exact envelope code.

    Attributes
    ----------
    axes : numpy.ndarray, shape (3, N)
        Unit spin axes (body frame) of wheels 0..N-1.
    capacity : numpy.ndarray, shape (N,)
        Each wheel's capacity of ``quantity`` [N·m·s or N·m].
    quantity : {"momentum", "torque"}
        The envelope maximised.
    family : str
        Layout family (a key of `FAMILIES`).
    params : numpy.ndarray
        The family's parameters at the answer: cone half-angle [rad]
        (``cone``), ``(delta, gamma)`` [rad] (``pyramid``), cant angle
        [rad] (``pairs``), the free axes stacked (``free``, ``3+1``).
    failures : int
        Number k of failed wheels the objective guards against.
    nominal_weight : float
        Weight w of the nominal radius in the objective (0..1).
    radius : float
        Certified inscribed radius, nominal [units of ``capacity``].
    worst_failure_radius : float
        Certified worst inscribed radius over every ``max(k, 1)``-wheel
        failure [units] (0 when a failure leaves a flat set).
    objective : float
        Certified objective ``radius`` (k = 0) or ``(1 - w)
        worst_failure_radius + w radius`` [units].
    start_objectives : numpy.ndarray, shape (S,)
        Certified objective reached from each start [units].
    start_times : numpy.ndarray, shape (S,)
        Wall time of each start (continuation and certification) [s].
    reached : float
        Fraction of starts within ``tol`` of the best (or above it).
    """

    axes: np.ndarray
    capacity: np.ndarray
    quantity: str
    family: str
    params: np.ndarray
    failures: int
    nominal_weight: float
    radius: float
    worst_failure_radius: float
    objective: float
    start_objectives: np.ndarray
    start_times: np.ndarray
    reached: float

    def wheel_array(self, h_max: ArrayLike | None = None,
                    m_max: ArrayLike | None = None) -> WheelArray:
        """The layout as a `WheelArray`.

        Parameters
        ----------
        h_max, m_max : float or array_like (N,), optional
            Momentum [N·m·s] and torque [N·m] capacity of each wheel; the
            designed ``quantity`` defaults to `capacity`, the other to
            the same numbers.
        """
        own = {"momentum": h_max, "torque": m_max}[self.quantity]
        other = m_max if self.quantity == "momentum" else h_max
        own = self.capacity if own is None else own
        other = self.capacity if other is None else other
        h, m = (own, other) if self.quantity == "momentum" else (other, own)
        return WheelArray.from_axes(self.axes, h_max=h, m_max=m,
                                    normalize=True)


def certify_layout(axes: ArrayLike, capacity: ArrayLike = 1.0,
                   failures: int = 0,
                   quantity: str = "momentum") -> tuple[float, float]:
    """Exact radii of a layout by the envelope code.

    Parameters
    ----------
    axes : array_like, shape (3, N)
        Spin axes (normalised here).
    capacity : float or array_like (N,)
        Each wheel's capacity [N·m·s or N·m].
    failures : int
        k; the failure radius is the worst over every ``max(k, 1)``-wheel
        failure.
    quantity : {"momentum", "torque"}

    Returns
    -------
    (float, float)
        Nominal inscribed radius and worst failure radius [units]; a
        failure that leaves a flat set counts as 0.
    """
    arr = WheelArray.from_axes(axes, h_max=capacity, m_max=capacity,
                               normalize=True)
    nominal = envelope(arr, quantity).inscribed_radius
    worst = np.inf
    for failed in itertools.combinations(range(arr.n_wheels),
                                         max(failures, 1)):
        try:
            r = envelope(arr.with_failed(*failed), quantity).inscribed_radius
        except RankError:
            r = 0.0
        worst = min(worst, r)
    return float(nominal), float(worst)


def _check(n_wheels, failures, family, quantity, nominal_weight, budget):
    n = as_count(n_wheels, "n_wheels", minimum=3)
    if n > MAX_DESIGN_WHEELS:
        raise InvalidValueError(f"n_wheels must be at most "
                                f"{MAX_DESIGN_WHEELS}, got {n}")
    k = as_count(failures, "failures", minimum=0)
    if n - k < 3:
        raise InvalidValueError(
            f"failures={k} leaves {n - k} of {n} wheels: at least 3 must "
            "work for a 3-D envelope")
    if family not in FAMILIES:
        raise InvalidValueError(f"family must be one of {sorted(FAMILIES)},"
                                f" got {family!r}")
    allowed = FAMILIES[family][0]
    if allowed is not None and n not in allowed:
        raise InvalidValueError(f"family {family!r} has {allowed[0]} "
                                f"wheels, got n_wheels={n}")
    if family == "3+1" and n < 4:
        raise InvalidValueError("family '3+1' needs at least 4 wheels")
    if quantity not in _QUANTITIES:
        raise InvalidValueError(f"quantity must be 'momentum' or 'torque', "
                                f"got {quantity!r}")
    w = as_finite_scalar(nominal_weight, "nominal_weight")
    if not 0.0 <= w <= 1.0:
        raise InvalidValueError(f"nominal_weight must be in [0, 1], got {w}")
    if budget is not None:
        budget = as_finite_scalar(budget, "budget")
        if budget <= 0:
            raise InvalidValueError(f"budget must be positive, got {budget}")
    return n, k, w, budget


def _continuation(nlp, n, params, cap, t0, schedule, w):
    """IPOPT solves along the smoothing widths ``schedule``."""
    ok = False
    for eps in schedule:
        z, ok = nlp.solve(params, cap, t0, eps, w)
        params = z[:nlp.n_par]
        if nlp.budget:
            cap = np.maximum(z[nlp.n_par:nlp.n_par + n], 1e-9 * nlp.budget)
        t0 = z[-nlp.n_t:]
    if not ok:                                 # polish at the last width
        z, ok = nlp.solve(params, cap, t0, schedule[-1], w)
        params = z[:nlp.n_par]
        if nlp.budget:
            cap = np.maximum(z[nlp.n_par:nlp.n_par + n], 1e-9 * nlp.budget)
        t0 = z[-nlp.n_t:]
    return params, cap, t0


def _one_start(nlp, n, family, params, capacity, k, w, quantity):
    """One start: continuation over `EPS_SCHEDULE`, then certify.

    With failures (and w < 1) the start first follows the nominal
    objective (w = 1) down to a moderate width, which carries it into the
    basin of a well-spread layout, and then the failure objective.
    """
    t0 = np.zeros(nlp.n_t)
    cap = capacity
    if k > 0 and w < 1:
        params, cap, t0 = _continuation(nlp, n, params, cap, t0,
                                        NOMINAL_SCHEDULE, 1.0)
        params, cap, t0 = _continuation(nlp, n, params, cap, t0,
                                        FAILURE_SCHEDULE, w)
    else:
        params, cap, t0 = _continuation(nlp, n, params, cap, t0,
                                        EPS_SCHEDULE, w)
    axes = family_axes(family, n, params)
    axes = axes / np.linalg.norm(axes, axis=0)
    nominal, worst = certify_layout(axes, cap, k, quantity)
    obj = nominal if k == 0 else (1 - w) * worst + w * nominal
    return obj, nominal, worst, axes, cap, params


def design_array(n_wheels: int, *, failures: int = 0, family: str = "free",
                 quantity: str = "momentum", nominal_weight: float = 0.0,
                 capacity: ArrayLike = 1.0, budget: float | None = None,
                 starts: int = 20, seed: int | None = 0,
                 tol: float = 1e-6) -> ArrayDesign:
    """Choose the wheel axes (and sizes) of the largest certified envelope.

    Parameters
    ----------
    n_wheels : int
        Number of wheels N (3..`MAX_DESIGN_WHEELS`).
    failures : int
        k: with k > 0 the objective is the worst inscribed radius over
        every k-wheel failure (traded with the nominal radius by
        ``nominal_weight``); N - k >= 3.
    family : str
        ``"free"``, ``"cone"``, ``"pyramid"`` (4 wheels), ``"3+1"`` or
        ``"pairs"`` (6 wheels); see `FAMILIES`.
    quantity : {"momentum", "torque"}
        The envelope maximised (with equal capacities the shapes agree;
        the quantity names the capacity that ``capacity`` and ``budget``
        are in).
    nominal_weight : float
        w in [0, 1]: the objective is ``(1 - w) r_fail + w r_nom`` when
        k > 0 (ignored when k = 0).
    capacity : float or array_like (N,)
        Each wheel's capacity [N·m·s or N·m] when no budget is given.
    budget : float, optional
        Total capacity Σ c_i [N·m·s or N·m]: the capacities become
        decision variables (each >= 0) summing to it.
    starts : int
        Random starts (each one continuation of IPOPT solves).
    seed : int or None
        Seed of the random starts.
    tol : float
        A start "reaches" the best when within ``tol`` [units] of it.

    Returns
    -------
    ArrayDesign
        The best certified layout and the statistics over the starts.

    Raises
    ------
    InvalidValueError
        A bad count, family, quantity, weight or budget.
    """
    n, k, w, budget = _check(n_wheels, failures, family, quantity,
                             nominal_weight, budget)
    starts = as_count(starts, "starts")
    capacity = (np.full(n, budget / n) if budget else
                as_vector(capacity, n, "capacity"))
    if not budget and np.any(capacity <= 0):
        raise InvalidValueError("capacity must be positive")
    nlp = build_design_nlp(family, n, k, budget)
    rng = np.random.default_rng(seed)
    results, times = [], []
    for _ in range(starts):
        t = time.perf_counter()
        results.append(_one_start(nlp, n, family,
                                  random_params(family, n, rng), capacity,
                                  k, w, quantity))
        times.append(time.perf_counter() - t)
    objs = np.array([r[0] for r in results])
    best = int(np.argmax(objs))
    obj, nominal, worst, axes, cap, params = results[best]
    return ArrayDesign(
        axes=axes, capacity=np.asarray(cap, dtype=float), quantity=quantity,
        family=family, params=np.asarray(params, dtype=float), failures=k,
        nominal_weight=w, radius=nominal, worst_failure_radius=worst,
        objective=float(obj), start_objectives=objs,
        start_times=np.array(times),
        reached=float(np.mean(objs >= obj - tol)))
