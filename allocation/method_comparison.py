"""Compare the literature's allocation methods with the exact QP.

The comparison the control-allocation literature runs (Bodson,
"Evaluation of optimization methods for control allocation", JGCD
25(4), 2002; Petersen, J. A. M. and Bodson, M., "Constrained quadratic
programming techniques for control allocation", IEEE Trans. Control
Systems Technology 14(1), 2006): for each method, the share of the
attainable torque set it reaches (by volume and over directions), the
error it leaves on attainable demands beyond its reach, and its speed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from adcs_common.exceptions import InvalidValueError

from .arrays import WheelArray
from .envelope import envelope
from .methods import METHODS
from .qp import QPAllocator
from .reach import fibonacci_directions, law_extent

__all__ = ["MethodComparison", "compare_methods", "comparison_arrays",
           "format_comparison", "sample_attainable"]


@dataclass(frozen=True)
class MethodComparison:
    """One method on one array.

    Attributes
    ----------
    method : str
    failed : tuple of int
        0-based failed wheels of the array.
    volume_fraction : float
        Share of uniformly sampled attainable demands reached [1].
    volume_stderr : float
        Its binomial standard error [1].
    mean_direction_fraction, min_direction_fraction : float
        Mean and least of ``r_method(u) / r_set(u)`` over the directions
        [1] (`law_extent` bisection).
    miss_error_p50, miss_error_p95, miss_error_max : float
        Relative torque error ``|A m - M| / |M|`` [1] on the attainable
        demands the method missed (NaN when it missed none).
    qp_agreement : float
        Share of reached demands where the torques equal the exact QP's
        to ``1e-3 max(m_max)`` [1] (direction-preserving QP for direct
        allocation, least-squares QP otherwise).
    time_per_call : float
        Mean wall time of one call in Python [s].
    n_samples : int
        Attainable demands sampled.
    """

    method: str
    failed: tuple[int, ...]
    volume_fraction: float
    volume_stderr: float
    mean_direction_fraction: float
    min_direction_fraction: float
    miss_error_p50: float
    miss_error_p95: float
    miss_error_max: float
    qp_agreement: float
    time_per_call: float
    n_samples: int


def comparison_arrays(h_max: float = 4.0, m_max: float = 0.2
                      ) -> dict[str, WheelArray]:
    """Return the arrays of the method comparison, by name.

    The pyramid of the papers, the same with wheel 2 failed, 3 + 1, six
    wheels as orthogonal pairs and six on a 54.7356° cone 60° apart
    (wheels named 1..N); each wheel ``h_max`` [N·m·s], ``m_max`` [N·m].
    """
    b = np.arccos(1 / np.sqrt(3))
    az = 2 * np.pi * np.arange(6) / 6
    cone = np.vstack([np.sin(b) * np.cos(az), np.sin(b) * np.sin(az),
                      np.full(6, np.cos(b))])
    return {
        "pyramid": WheelArray.pyramid(h_max=h_max, m_max=m_max),
        "pyramid, wheel 2 failed": WheelArray.pyramid(
            h_max=h_max, m_max=m_max, failed=[1]),
        "3 + 1": WheelArray.orthogonal_plus_skew(h_max=h_max, m_max=m_max),
        "six, orthogonal pairs": WheelArray.orthogonal_pairs(
            h_max=h_max, m_max=m_max),
        "six, cone": WheelArray.from_axes(cone, h_max=h_max, m_max=m_max,
                                          normalize=True),
    }


def sample_attainable(array: WheelArray, n: int, seed: int = 0
                      ) -> np.ndarray:
    """Uniform samples (n, 3) [N·m] of the attainable torque set.

    Rejection sampling over the set's bounding box (fixed seed).
    """
    env = envelope(array, "torque")
    lo = env.vertices.min(axis=0)
    hi = env.vertices.max(axis=0)
    rng = np.random.default_rng(seed)
    out: list[np.ndarray] = []
    count = 0
    while count < n:
        P = rng.uniform(lo, hi, size=(2 * n, 3))
        keep = P[env.contains(P.T, tol=0.0)]
        out.append(keep)
        count += len(keep)
    return np.vstack(out)[:n]


def _qp_method(array: WheelArray, saturation: str) -> Callable:
    qp = QPAllocator(array, saturation=saturation)
    return lambda a, M, lo=None, hi=None: qp.allocate(M).torques


def _one(array: WheelArray, name: str, f: Callable, D: np.ndarray,
         u: np.ndarray, r_set: np.ndarray, refs: dict, tol: float
         ) -> MethodComparison:
    A = array.working_axes
    m_scale = float(np.max(array.m_max))
    t0 = time.perf_counter()
    m = np.array([f(array, M) for M in D])
    dt = (time.perf_counter() - t0) / len(D)
    nM = np.linalg.norm(D, axis=1)
    err = np.linalg.norm(m @ A.T - D, axis=1) / np.maximum(nM, 1e-300)
    ok = (err <= tol) & np.all(np.abs(m) <= array.m_max * (1 + tol),
                               axis=1)
    ref = refs["scale" if name in ("direct allocation", "exact QP (scale)")
               else "least_squares"]
    agree = np.max(np.abs(m - ref), axis=1) <= 1e-3 * m_scale
    miss = err[~ok]
    r = law_extent(array, lambda M: f(array, M), u, tol=tol, rtol=1e-3)
    frac = np.atleast_1d(r) / r_set
    p = float(np.mean(ok))
    q = (lambda x: float(np.percentile(miss, x))) if miss.size else (
        lambda x: float("nan"))
    return MethodComparison(
        method=name, failed=tuple(array.failed), volume_fraction=p,
        volume_stderr=float(np.sqrt(p * (1 - p) / len(D))),
        mean_direction_fraction=float(np.mean(frac)),
        min_direction_fraction=float(np.min(frac)),
        miss_error_p50=q(50), miss_error_p95=q(95), miss_error_max=q(100),
        qp_agreement=float(np.mean(agree[ok])) if ok.any() else 0.0,
        time_per_call=dt, n_samples=len(D))


def compare_methods(array: WheelArray,
                    methods: Mapping[str, Callable] | None = None, *,
                    n_samples: int = 2000, n_directions: int = 100,
                    seed: int = 0, tol: float = 1e-3,
                    include_qp: bool = True) -> list[MethodComparison]:
    r"""Reach, miss error, QP agreement and speed of each method.

    By volume: ``n_samples`` demands uniform in the attainable torque set
    (`sample_attainable`, seed ``seed``); a demand is reached when
    :math:`|A m - M| \le tol\,|M|` and every wheel is within
    ``m_max (1 + tol)``. Over directions: ``n_directions`` Fibonacci
    directions u, the method's radial reach (`law_extent`, bisection
    to 1e-3 of the set's extent) over the set's radial extent
    (`Envelope.radial_extent`).

    Parameters
    ----------
    array : WheelArray
        Nominal or with failed wheels.
    methods : mapping name -> f(array, M) -> m (N,), optional
        Default `allocation.methods.METHODS`.
    n_samples, n_directions : int
        Monte Carlo demands and directions.
    seed : int
        Seed of the demands.
    tol : float
        Relative reach tolerance [1] (1e-3: the fixed-point iteration's
        ε = 1e-4 bias passes, a saturated pseudo-inverse does not).
    include_qp : bool
        Add the exact QP rows (``saturation="scale"`` and
        ``"least_squares"``).

    Returns
    -------
    list of MethodComparison
    """
    if not isinstance(array, WheelArray):
        raise InvalidValueError(
            f"array must be a WheelArray, got {type(array).__name__}")
    if not 0.0 < tol < 1.0:
        raise InvalidValueError(f"tol must lie in (0, 1), got {tol!r}")
    methods = dict(METHODS if methods is None else methods)
    if include_qp:
        methods["exact QP (scale)"] = _qp_method(array, "scale")
        methods["exact QP (least squares)"] = _qp_method(
            array, "least_squares")
    D = sample_attainable(array, int(n_samples), seed)
    qs = QPAllocator(array, saturation="scale")
    ql = QPAllocator(array, saturation="least_squares")
    refs = {"scale": np.array([qs.allocate(M).torques for M in D]),
            "least_squares": np.array([ql.allocate(M).torques
                                       for M in D])}
    u = fibonacci_directions(int(n_directions))
    r_set = np.asarray(envelope(array, "torque").radial_extent(u))
    return [_one(array, name, f, D, u, r_set, refs, tol)
            for name, f in methods.items()]


def format_comparison(rows: Sequence[MethodComparison]) -> str:
    """A plain-text table of `compare_methods` rows (percent, µs)."""
    head = (f"{'method':<30}{'volume %':>10}{'dir mean %':>11}"
            f"{'dir min %':>10}{'miss p50':>10}{'miss p95':>10}"
            f"{'= QP %':>8}{'µs/call':>9}")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r.method:<30}{100 * r.volume_fraction:>10.1f}"
            f"{100 * r.mean_direction_fraction:>11.1f}"
            f"{100 * r.min_direction_fraction:>10.1f}"
            f"{r.miss_error_p50:>10.3g}{r.miss_error_p95:>10.3g}"
            f"{100 * r.qp_agreement:>8.1f}{1e6 * r.time_per_call:>9.0f}")
    return "\n".join(lines)
