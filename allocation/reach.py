"""Share of the attainable torque set a law reaches (theory §1.2)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence, TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from adcs_common.results import ResultMixin

from adcs_common.exceptions import AdcsError, InvalidValueError, ShapeError
from adcs_common.validation import as_finite_scalar, as_vector, check_items

from .arrays import WheelArray
from .envelope import envelope, unit_directions
from .laws import LinearLaw, min_norm_law, weighted_law

if TYPE_CHECKING:
    import pandas as pd


__all__ = [
    "ReachResult",
    "fibonacci_directions",
    "format_reach_table",
    "law_extent",
    "reach_table",
    "torque_reach",
]

_SAMPLINGS = ("fibonacci", "random")


def fibonacci_directions(n: int) -> np.ndarray:
    """Near-uniform unit directions on the sphere (Fibonacci lattice).

    Parameters
    ----------
    n : int
        Number of directions (>= 1).

    Returns
    -------
    numpy.ndarray, shape (3, n)
        Unit vectors; each stands for an equal area ``4π/n`` of the sphere.
    """
    n = _check_count(n, "n")
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    rho = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    return np.vstack([rho * np.cos(phi), rho * np.sin(phi), z])


def _check_count(n: Any, name: str) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InvalidValueError(f"{name} must be a positive int, got {n!r}")
    return int(n)


def _law_name(law: Any, name: str | None) -> str:
    if name is not None:
        return str(name)
    return str(getattr(law, "name", None) or getattr(
        law, "__name__", None) or type(law).__name__)


def _linear_extent(array: WheelArray, gains: np.ndarray, u: np.ndarray,
                   tol: float) -> np.ndarray:
    r"""Exact reach of ``m = G M`` along unit columns u (3, K) [N·m].

    .. math:: r(u) = 1 / \max_i |G_i u| / m_{\max,i}

    over working wheels, and 0 where ``A G u != u`` (the law is not exact
    there, e.g. it commands a failed wheel).
    """
    act = array.active
    load = np.abs(gains[act] @ u) / array.m_max[act][:, None]   # (N_w, K)
    with np.errstate(divide="ignore"):
        r = 1.0 / np.max(load, axis=0)
    miss = np.linalg.norm(array.working_axes @ gains @ u - u, axis=0)
    return np.where(miss <= tol, r, 0.0)


def _torques(law: Any, M: np.ndarray, n: int) -> np.ndarray | None:
    """Wheel torques of a generic law for one demand, None on failure."""
    try:
        out = law.allocate(M) if hasattr(law, "allocate") else law(M)
    except AdcsError:
        return None
    m = np.asarray(getattr(out, "torques", out), dtype=float)
    if m.shape != (n,):
        raise ShapeError(
            f"law must return {n} wheel torques (or an object with a "
            f"'torques' attribute of shape ({n},)), got shape {m.shape}")
    return m if np.all(np.isfinite(m)) else None


def _generic_extent(array: WheelArray, law: Any, u: np.ndarray,
                    r_set: np.ndarray, tol: float, rtol: float
                    ) -> np.ndarray:
    """Reach of any law along unit columns u (3, K) by bisection [N·m]."""
    A = array.working_axes
    act = array.active
    m_max = array.m_max
    scale = float(np.max(m_max))

    def ok(M: np.ndarray) -> bool:
        m = _torques(law, M, array.n_wheels)
        if m is None:
            return False
        exact = np.linalg.norm(A @ m - M) <= tol * max(
            float(np.linalg.norm(M)), scale)
        return bool(exact and np.all(np.abs(m[act]) <= m_max[act]
                                     * (1.0 + tol)))

    if hasattr(law, "allocate_batch"):
        try:
            return _batch_extent(array, law, u, r_set, tol, rtol)
        except AdcsError:       # a row failed: bisect one demand at a time
            pass
    out = np.empty(u.shape[1])
    for k in range(u.shape[1]):
        hi = float(r_set[k])
        if ok(hi * (1.0 - tol) * u[:, k]):
            out[k] = hi
            continue
        lo = 0.0
        while hi - lo > rtol * r_set[k]:
            mid = 0.5 * (lo + hi)
            if ok(mid * u[:, k]):
                lo = mid
            else:
                hi = mid
        out[k] = lo
    return out


def _batch_extent(array: WheelArray, law: Any, u: np.ndarray,
                  r_set: np.ndarray, tol: float, rtol: float) -> np.ndarray:
    """Bisect like `_generic_extent`, every direction in one batch call.

    For a law with ``allocate_batch``: the same test and the same steps,
    one ``allocate_batch`` call per bisection step for all directions.
    """
    A = array.working_axes
    act = array.active
    lim = array.m_max[act] * (1.0 + tol)
    scale = float(np.max(array.m_max))

    def ok(t: np.ndarray, cols: np.ndarray) -> np.ndarray:
        M = (t * u[:, cols]).T
        m = np.asarray(law.allocate_batch(M).torques, dtype=float)
        miss = np.linalg.norm(m @ A.T - M, axis=1)
        bound = np.maximum(np.linalg.norm(M, axis=1), scale)
        return (miss <= tol * bound) & np.all(np.abs(m[:, act]) <= lim,
                                              axis=1)

    every = np.arange(u.shape[1])
    hi = np.asarray(r_set, dtype=float).copy()
    lo = np.zeros_like(hi)
    done = ok(hi * (1.0 - tol), every)
    lo[done] = hi[done]
    open_ = ~done & (hi - lo > rtol * r_set)
    while open_.any():
        cols = np.flatnonzero(open_)
        mid = 0.5 * (lo[cols] + hi[cols])
        good = ok(mid, cols)
        lo[cols[good]] = mid[good]
        hi[cols[~good]] = mid[~good]
        open_ = ~done & (hi - lo > rtol * r_set)
    return lo


def law_extent(array: WheelArray, law: Any, direction: ArrayLike, *,
               tol: float = 1e-6, rtol: float = 1e-4) -> float | np.ndarray:
    r"""Largest torque a law produces along direction(s) within limits.

    For a `LinearLaw` ``m = G M`` (exact):

    .. math:: r(u) = \Big(\max_i \frac{|G_i u|}{m_{\max,i}}\Big)^{-1}

    For any other law, bisection on ``t`` with the test "``law(t u)``
    gives ``A m = t u`` within ``tol`` and ``|m_i| <= m_max,i (1 + tol)``
    on every working wheel", between 0 and the set's own extent. The
    reached set is assumed star-shaped about the origin (true for exact
    linear laws and for convex allocators such as a bounded QP).

    Parameters
    ----------
    array : WheelArray
        Working axes A (failed columns zeroed) and m_max [N·m].
    law : LinearLaw, object with ``allocate(M)``, or callable
        ``allocate``/the call takes a demand (3,) [N·m] and returns the
        wheel torques (N,) [N·m] or an object with a ``torques`` attribute
        (its ``status`` is not trusted: the torque test decides). A raised
        toolbox error (`AdcsError`) counts as "not reached". A law with
        ``allocate_batch(M)`` (M of shape (K, 3), e.g. `QPAllocator`) is
        bisected for all directions at once, one batch call per step.
    direction : array_like, shape (3,) or (3, K)
        Body-frame direction(s), normalised here.
    tol : float
        Relative tolerance of the exactness and limit tests [1].
    rtol : float
        Bisection stops when the bracket is below ``rtol`` times the set's
        extent [1] (generic laws only).

    Returns
    -------
    float or numpy.ndarray, shape (K,)
        Extent along each direction [N·m]; 0 where the law is not exact.
    """
    u = unit_directions(direction)
    uk = u.reshape(3, -1)
    tol = _check_tol(tol, "tol")
    rtol = _check_tol(rtol, "rtol")
    r = _extent(array, law, uk, tol, rtol)
    return float(r[0]) if u.ndim == 1 else r


def _check_tol(value: Any, name: str) -> float:
    v = as_finite_scalar(value, name)
    if not 0.0 < v < 1.0:
        raise InvalidValueError(f"{name} must lie in (0, 1), got {v!r}")
    return v


def _extent(array: WheelArray, law: Any, u: np.ndarray, tol: float,
            rtol: float) -> np.ndarray:
    if not isinstance(array, WheelArray):
        raise InvalidValueError(
            f"array must be a WheelArray, got {type(array).__name__}")
    if isinstance(law, LinearLaw):
        gains = np.asarray(law.gains, dtype=float)
        if gains.shape != (array.n_wheels, 3):
            raise ShapeError(
                f"law.gains must have shape ({array.n_wheels}, 3), got "
                f"{gains.shape}")
        return _linear_extent(array, gains, u, tol)
    if not (hasattr(law, "allocate") or callable(law)):
        raise InvalidValueError(
            "law must be a LinearLaw, an object with allocate(M) or a "
            f"callable, got {type(law).__name__}")
    r_set = envelope(array, "torque").radial_extent(u)
    return _generic_extent(array, law, u, np.atleast_1d(r_set), tol, rtol)


@dataclass(frozen=True, eq=False, repr=False)
class ReachResult(ResultMixin):
    r"""Fraction of the attainable torque set a law reaches.

    The attainable set is the zonotope :math:`A\cdot[-m_{\max},
    m_{\max}]^N` of the working wheels (`allocation.envelope` with
    ``kind="torque"``). Along a unit direction u the law reaches
    ``r_law(u)`` and the set extends to ``r_set(u)``; the fraction is their
    ratio.

    Attributes
    ----------
    law : str
        Law name.
    failed : tuple of int
        0-based failed wheels of the array analysed.
    mean_direction_fraction : float
        Mean of ``r_law/r_set`` over the sampled directions [1].
    min_direction_fraction : float
        Smallest fraction found [1]: the sampled minimum, refined by a
        local search on the sphere for linear laws.
    worst_direction : numpy.ndarray, shape (3,)
        Unit direction of that minimum (the set is centrally symmetric,
        so ``-worst_direction`` is as bad).
    worst_law_extent, worst_set_extent : float
        ``r_law`` and ``r_set`` along it [N·m].
    volume_fraction : float
        Volume reached / volume of the set [1].
    volume_method : {"exact", "radial"}
        ``"exact"``: polytope ``{M : |G_i M| <= m_max,i}`` by half-space
        intersection (linear laws); ``"radial"``: ``mean r_law³ / mean
        r_set³`` over the directions (volume = ∫ r³/3 dΩ).
    n_directions : int
        Number of directions sampled.
    sampling : {"fibonacci", "random"}
        How they were drawn.
    directions : numpy.ndarray, shape (3, K)
        The unit directions.
    law_extent, set_extent : numpy.ndarray, shape (K,)
        ``r_law`` and ``r_set`` per direction [N·m].
    """

    law: str
    failed: tuple[int, ...]
    mean_direction_fraction: float
    min_direction_fraction: float
    worst_direction: np.ndarray
    worst_law_extent: float
    worst_set_extent: float
    volume_fraction: float
    volume_method: str
    n_directions: int
    sampling: str
    directions: np.ndarray
    law_extent: np.ndarray
    set_extent: np.ndarray

    @property
    def fractions(self) -> np.ndarray:
        """Per-direction fractions ``r_law / r_set`` (K,) [1]."""
        return self.law_extent / self.set_extent


def _linear_volume(array: WheelArray, gains: np.ndarray, tol: float
                   ) -> float:
    """Exact volume of ``{M : |G_i M| <= m_max,i}`` (0 if not exact)."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    if np.linalg.norm(array.working_axes @ gains - np.eye(3)) > tol:
        return 0.0
    act = array.active
    G = gains[act]
    b = array.m_max[act]
    keep = np.linalg.norm(G, axis=1) > 0.0
    G, b = G[keep], b[keep]
    halfspaces = np.vstack([np.hstack([G, -b[:, None]]),
                            np.hstack([-G, -b[:, None]])])
    hs = HalfspaceIntersection(halfspaces, np.zeros(3))
    return float(ConvexHull(hs.intersections).volume)


def _refine_linear(array: WheelArray, gains: np.ndarray, env, u0s,
                   tol: float) -> tuple[float, np.ndarray]:
    """Local minimum of the linear law's fraction near the worst samples."""
    from scipy.optimize import minimize

    def frac(x: np.ndarray) -> float:
        nx = np.linalg.norm(x)
        if nx == 0.0:
            return np.inf
        u = (x / nx)[:, None]
        return float(_linear_extent(array, gains, u, tol)[0]
                     / env.radial_extent(u)[0])

    best_f, best_u = np.inf, u0s[:, 0]
    for u0 in u0s.T:
        res = minimize(frac, u0, method="Nelder-Mead",
                       options={"xatol": 1e-10, "fatol": 1e-13,
                                "maxiter": 4000})
        if res.fun < best_f:
            best_f, best_u = float(res.fun), res.x / np.linalg.norm(res.x)
    return best_f, best_u


def torque_reach(array: WheelArray, law: Any, *,
                 n_directions: int | None = None,
                 sampling: str = "fibonacci", seed: int = 0,
                 tol: float = 1e-6, rtol: float = 1e-4, refine: bool = True,
                 name: str | None = None) -> ReachResult:
    r"""Measure the share of the attainable torque set a law reaches.

    theory §1.2: with :math:`|m_i| \le m_{\max}` the attainable torque set is
    the zonotope :math:`A\cdot[-m_{\max}, m_{\max}]^N`; the minimum-norm
    law ([1] eq. 5) saturates a wheel before the demand leaves it.

    By directions: for unit u, ``r_law(u)`` (see `law_extent`) against
    the set's radial extent ``r_set(u)``. By volume, from the radial
    integral

    .. math:: \mathrm{vol} = \tfrac13 \oint r(u)^3\,d\Omega
              \;\Rightarrow\; \frac{\mathrm{vol}_{law}}{\mathrm{vol}_{set}}
              \approx \frac{\overline{r_{law}^3}}{\overline{r_{set}^3}}

    over uniform directions, or exactly for a `LinearLaw` from the
    polytope :math:`\{M : |G M| \le m_{\max}\}` (scipy
    HalfspaceIntersection + ConvexHull).

    Parameters
    ----------
    array : WheelArray
        Axes, m_max [N·m] and failed wheels (left out of the set). Scale
        factor errors are ignored here (see `allocation.accuracy`).
    law : LinearLaw, object with ``allocate(M)``, or callable
        See `law_extent`. Non-linear laws cost about ``14 n_directions``
        allocations (one when the law reaches the boundary).
    n_directions : int, optional
        Number of directions K; default 4000 for a `LinearLaw` (exact and
        vectorised), 500 for other laws (bisection, one allocation per
        step).
    sampling : {"fibonacci", "random"}
        Fibonacci lattice (deterministic, equal areas) or uniform random
        unit vectors from ``numpy.random.default_rng(seed)``.
    seed : int
        Seed of the random directions.
    tol, rtol : float
        Tolerances of `law_extent`. For an iterative solver use a ``tol``
        comparable to the solver's own tolerance, or its near-boundary
        answers count as misses.
    refine : bool
        For linear laws, refine the worst sampled direction by a local
        search (Nelder-Mead on the sphere); the sampled minimum otherwise.
    name : str, optional
        Law name for the report (default ``law.name`` or the type name).

    Returns
    -------
    ReachResult

    Raises
    ------
    InvalidValueError
        Unknown ``sampling``, bad counts or tolerances, law of no known
        kind.
    RankError
        The working wheels do not span 3-D space.
    """
    if n_directions is None:
        n_directions = 4000 if isinstance(law, LinearLaw) else 500
    n = _check_count(n_directions, "n_directions")
    if sampling not in _SAMPLINGS:
        raise InvalidValueError(
            f"sampling must be 'fibonacci' or 'random', got {sampling!r}")
    tol = _check_tol(tol, "tol")
    rtol = _check_tol(rtol, "rtol")
    if sampling == "fibonacci":
        u = fibonacci_directions(n)
    else:
        if isinstance(seed, bool) or not isinstance(
                seed, (int, np.integer)) or seed < 0:
            raise InvalidValueError(
                f"seed must be a non-negative int, got {seed!r}")
        u = np.random.default_rng(seed).normal(size=(3, n))
        u /= np.linalg.norm(u, axis=0)
    env = envelope(array, "torque")      # validates array, rank
    r_set = np.asarray(env.radial_extent(u))
    r_law = _extent(array, law, u, tol, rtol)
    frac = r_law / r_set
    k = int(np.argmin(frac))
    f_min, u_min = float(frac[k]), u[:, k]
    if isinstance(law, LinearLaw):
        gains = np.asarray(law.gains, dtype=float)
        if refine and 0.0 < f_min < 1.0 - tol:
            starts = u[:, np.argsort(frac)[:8]]
            f_ref, u_ref = _refine_linear(array, gains, env, starts, tol)
            if f_ref < f_min:
                f_min, u_min = f_ref, u_ref
        volume = _linear_volume(array, gains, tol) / env.volume
        method = "exact"
    else:
        volume = float(np.mean(r_law ** 3) / np.mean(r_set ** 3))
        method = "radial"
    w_law = float(_extent(array, law, u_min[:, None], tol, rtol)[0])
    w_set = float(env.radial_extent(u_min))
    return ReachResult(
        law=_law_name(law, name), failed=tuple(array.failed),
        mean_direction_fraction=float(np.mean(frac)),
        min_direction_fraction=f_min, worst_direction=u_min,
        worst_law_extent=w_law, worst_set_extent=w_set,
        volume_fraction=float(volume), volume_method=method,
        n_directions=n, sampling=sampling, directions=u,
        law_extent=r_law, set_extent=r_set)


def reach_table(array: WheelArray,
                laws: Mapping[str, Callable[[WheelArray], Any]] | None = None,
                *, weights: Sequence[float] | np.ndarray | None = None,
                **options: Any) -> list[ReachResult]:
    r"""Reach of the closed-form laws (and others), nominal and per failure.

    Rows, in order: for the array as given, then with each working wheel
    failed in turn (cases whose working wheels no longer span 3-D are
    skipped), one row per law: the minimum-norm law (eq. 5), the weighted
    law (criterion :math:`\sum V_i m_i^2`), then each extra law. Every
    law is rebuilt for the failed array (the reconfigured law of seed
    001: the failed wheel's column of A zeroed).

    Parameters
    ----------
    array : WheelArray
    laws : mapping of str to callable, optional
        Extra laws as factories ``name -> f(array) -> law`` (e.g. the QP
        allocator), so each case gets its own law.
    weights : array_like (N,), optional
        Weights V_i of the weighted law; default ``1 / m_max_i**2``
        (minimum of the normalised torques, :math:`\sum (m_i/m_{\max,i})^2`,
        which equals the minimum-norm law when all wheels are alike).
    **options
        Passed to `torque_reach` (``n_directions``, ``sampling``, ...).

    Returns
    -------
    list of ReachResult
        One per (case, law); ``row.failed`` and ``row.law`` name it.
    """
    unknown = set(options) - {"n_directions", "sampling", "seed", "tol",
                              "rtol", "refine"}
    if unknown:
        raise InvalidValueError(
            f"reach_table got unknown option(s) {sorted(unknown)}; "
            "allowed: n_directions, sampling, seed, tol, rtol, refine")
    if not isinstance(array, WheelArray):
        raise InvalidValueError(
            f"array must be a WheelArray, got {type(array).__name__}")
    w = (1.0 / np.asarray(array.m_max) ** 2 if weights is None
         else as_vector(weights, array.n_wheels, "weights"))
    extra = dict(laws or {})
    for key, factory in extra.items():
        if not callable(factory):
            raise InvalidValueError(
                f"laws[{key!r}] must be a factory f(array) -> law, got "
                f"{type(factory).__name__}")
    cases = [array] + [array.with_failed(int(k))
                       for k in np.flatnonzero(array.active)]
    rows = []
    for case in cases:
        if case.rank < 3:
            continue
        built = [(None, min_norm_law(case)),
                 ("weighted (sum V_i m_i^2)", weighted_law(case, w))]
        built += [(key, factory(case)) for key, factory in extra.items()]
        for label, law in built:
            rows.append(torque_reach(case, law, name=label, **options))
    return rows


def format_reach_table(rows: Sequence[ReachResult]) -> str:
    """Markdown table of `reach_table` rows (wheels named 1..N)."""
    lines = ["| failed | law | mean | min | worst direction | volume |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        failed = ", ".join(f"RW{i + 1}" for i in r.failed) or "none"
        u = ", ".join(f"{c:+.3f}" for c in r.worst_direction)
        lines.append(
            f"| {failed} | {r.law} | {100 * r.mean_direction_fraction:.1f}"
            f" % | {100 * r.min_direction_fraction:.1f} % | ({u}) | "
            f"{100 * r.volume_fraction:.1f} % ({r.volume_method}) |")
    return "\n".join(lines)


def reach_frame(rows: Sequence[ReachResult]) -> pd.DataFrame:
    """`reach_table` rows as a `pandas.DataFrame` (fractions in [0, 1]).

    Columns: law, failed (wheels named 1..N), mean and worst-direction
    fraction, the worst direction (x, y, z), volume fraction and how it
    was computed, number of directions.
    """
    import pandas as pd

    rows = check_items(rows, ReachResult, "rows")
    return pd.DataFrame([{
        "law": r.law,
        "failed": ", ".join(str(i + 1) for i in r.failed) or "none",
        "mean_direction_fraction": r.mean_direction_fraction,
        "min_direction_fraction": r.min_direction_fraction,
        "worst_x": r.worst_direction[0], "worst_y": r.worst_direction[1],
        "worst_z": r.worst_direction[2],
        "volume_fraction": r.volume_fraction,
        "volume_method": r.volume_method,
        "n_directions": r.n_directions} for r in rows])
