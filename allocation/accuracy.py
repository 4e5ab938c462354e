"""Torque accuracy under mounting and scale errors ([1], theory §1.3)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError, RankError, ShapeError
from adcs_common.results import ResultMixin
from adcs_common.validation import as_finite_array, as_finite_scalar

from .arrays import PYRAMID_SIGN_Y, PYRAMID_SIGN_Z, WheelArray
from .arrays import perpendicular_frames

__all__ = [
    "AccuracyResult",
    "ErrorSummary",
    "TorqueError",
    "actual_axes",
    "compare_law_axes",
    "gain_error_uniform",
    "gain_error_uniform_as_printed",
    "monte_carlo_accuracy",
    "monte_carlo_accuracy_array",
    "paper_actual_axes_as_printed",
    "tilted_axes",
    "torque_error",
]

_DELTA = np.deg2rad(55.0)
_GAMMA = np.deg2rad(45.0)
_DISTRIBUTIONS = ("uniform", "normal")
_LAW_AXES = ("nominal", "measured")


# ------------------------------------------------------------ axes
def actual_axes(delta_i: ArrayLike, gamma_i: ArrayLike) -> np.ndarray:
    r"""Actual spin axes of the pyramid for per-wheel angles, vectorised.

    [1], accuracy section ("actual matrix of direction cosines"),
    with the signs of the nominal A (eq. 6):

    .. math::
        A_1 = \begin{bmatrix}
        -s\delta_i c\gamma_i \\ \sigma^y_i s\delta_i s\gamma_i \\
        \sigma^z_i c\delta_i \end{bmatrix}_{i=1..4},
        \quad \sigma^y = (+,-,-,+),\ \sigma^z = (-,-,+,+)

    Parameters
    ----------
    delta_i, gamma_i : array_like, shape (4,) or (S, 4)
        Actual mounting angles δ_i = δ ± Δδ_i, γ_i = γ ± Δγ_i [rad].

    Returns
    -------
    numpy.ndarray, shape (3, 4) or (S, 3, 4)
        Unit axes as columns (one matrix per sample).
    """
    d = as_finite_array(delta_i, "delta_i")
    g = as_finite_array(gamma_i, "gamma_i")
    if d.shape[-1:] != (4,) or d.ndim > 2 or g.shape != d.shape:
        raise ShapeError(
            "delta_i and gamma_i must both have shape (4,) or (S, 4), got "
            f"{d.shape} and {g.shape}")
    sd = np.sin(d)
    return np.stack([-sd * np.cos(g), PYRAMID_SIGN_Y * sd * np.sin(g),
                     PYRAMID_SIGN_Z * np.cos(d)], axis=-2)


def paper_actual_axes_as_printed(delta_i: ArrayLike,
                                 gamma_i: ArrayLike) -> np.ndarray:
    """Return the paper's printed "actual" A: row 2 all positive (ERRATUM).

    Kept only to show the misprint (docs/errata.md): at zero error it is
    not the nominal A of eq. (6), whose row 2 has signs (+, -, -, +). Use
    `actual_axes`.

    Parameters
    ----------
    delta_i, gamma_i : array_like, shape (4,)
        Mounting angles [rad].

    Returns
    -------
    numpy.ndarray, shape (3, 4)
    """
    d = as_finite_array(delta_i, "delta_i", (4,))
    g = as_finite_array(gamma_i, "gamma_i", (4,))
    return np.vstack([-np.sin(d) * np.cos(g), np.sin(d) * np.sin(g),
                      PYRAMID_SIGN_Z * np.cos(d)])


# ----------------------------------------------------- analytic cases
def gain_error_uniform(d_delta: float, d_gamma: float, d_scale: float, *,
                       delta: float = _DELTA, gamma: float = _GAMMA
                       ) -> float:
    r"""Relative torque error of the paper's case (a), corrected.

    M = (Mx, 0, 0), every δ_i = δ − Δδ, γ_i = γ − Δγ, m̂ = m(1 − Δ),
    nominal law (5): the direction is kept and

    .. math::
        \frac{M_{1x} - M_x}{M_x} =
        \frac{\sin(\delta-\Delta\delta)\cos(\gamma-\Delta\gamma)(1-\Delta)
              - \sin\delta\cos\gamma}{\sin\delta\cos\gamma}

    (ERRATUM, theory §1.3: the paper prints the numerator only, without the
    division by sδcγ; see `gain_error_uniform_as_printed`.)

    Parameters
    ----------
    d_delta, d_gamma : float
        Common mounting errors Δδ, Δγ [rad].
    d_scale : float
        Common scale-factor error Δ [1].
    delta, gamma : float
        Nominal angles [rad] (default 55°, 45°).

    Returns
    -------
    float
        (M1x − Mx)/Mx [1], e.g. −0.02094 for 0.5°, 0.3°, 0.02.
    """
    num, den = _case_a_terms(d_delta, d_gamma, d_scale, delta, gamma)
    return num / den


def gain_error_uniform_as_printed(d_delta: float, d_gamma: float,
                                  d_scale: float, *, delta: float = _DELTA,
                                  gamma: float = _GAMMA) -> float:
    """Return the paper's printed case-(a) ΔMx/Mx, lacking 1/(sδcγ).

    ERRATUM (theory §1.3): this is the bracket
    ``sin(δ−Δδ)cos(γ−Δγ)(1−Δ) − sδcγ`` [1] that the paper multiplies by
    Mx; it is not the relative error (see `gain_error_uniform`). Kept to
    show the misprint.
    """
    num, _ = _case_a_terms(d_delta, d_gamma, d_scale, delta, gamma)
    return num


def _case_a_terms(d_delta, d_gamma, d_scale, delta, gamma
                  ) -> tuple[float, float]:
    dd = as_finite_scalar(d_delta, "d_delta")
    dg = as_finite_scalar(d_gamma, "d_gamma")
    ds = as_finite_scalar(d_scale, "d_scale")
    d = as_finite_scalar(delta, "delta")
    g = as_finite_scalar(gamma, "gamma")
    nominal = np.sin(d) * np.cos(g)
    return (float(np.sin(d - dd) * np.cos(g - dg) * (1.0 - ds) - nominal),
            float(nominal))


# ------------------------------------------------------ torque error
@dataclass(frozen=True, eq=False)
class TorqueError:
    r"""Error of the realised torque ([1], accuracy section).

    Attributes
    ----------
    actual : numpy.ndarray, shape (..., 3)
        :math:`M_1 = A_1 \hat m` [N·m].
    error : numpy.ndarray, shape (..., 3)
        :math:`\Delta M = M - M_1` [N·m].
    relative_error : numpy.ndarray, shape (...)
        :math:`|\Delta M| / |M|` [1].
    magnitude_error : numpy.ndarray, shape (...)
        :math:`(|M_1| - |M|)/|M|` [1], the gain-like part.
    angle : numpy.ndarray, shape (...)
        Cross-coupling angle
        :math:`\Delta\alpha = \arccos(M\cdot M_1/(|M||M_1|))` [rad],
        computed as ``atan2(|M × M1|, M·M1)`` (same value, accurate for
        small angles).
    """

    actual: np.ndarray
    error: np.ndarray
    relative_error: np.ndarray
    magnitude_error: np.ndarray
    angle: np.ndarray


def torque_error(demand: ArrayLike, actual: ArrayLike) -> TorqueError:
    """Compare demanded and realised torques, vectorised.

    Parameters
    ----------
    demand : array_like, shape (..., 3)
        Demanded torque(s) M [N·m], non-zero.
    actual : array_like, shape (..., 3)
        Realised torque(s) M1 = A_1 m̂ [N·m].

    Returns
    -------
    TorqueError
    """
    M = as_finite_array(demand, "demand")
    M1 = as_finite_array(actual, "actual")
    if M.shape[-1:] != (3,) or M1.shape != M.shape:
        raise ShapeError(
            "demand and actual must have the same shape (..., 3), got "
            f"{M.shape} and {M1.shape}")
    norm = np.linalg.norm(M, axis=-1)
    if np.any(norm == 0.0):
        raise InvalidValueError("demand must be non-zero")
    err = M - M1
    return TorqueError(
        actual=M1, error=err,
        relative_error=np.linalg.norm(err, axis=-1) / norm,
        magnitude_error=(np.linalg.norm(M1, axis=-1) - norm) / norm,
        angle=np.arctan2(np.linalg.norm(np.cross(M, M1), axis=-1),
                         np.sum(M * M1, axis=-1)))


# ------------------------------------------------------- Monte Carlo
@dataclass(frozen=True)
class ErrorSummary:
    """Summary statistics of one error quantity over the samples."""

    mean: float
    p95: float
    max: float

    @classmethod
    def of(cls, x: np.ndarray) -> "ErrorSummary":
        """Mean, 95th percentile and maximum of ``x``."""
        return cls(float(np.mean(x)), float(np.percentile(x, 95.0)),
                   float(np.max(x)))


@dataclass(frozen=True, eq=False, repr=False)
class AccuracyResult(ResultMixin):
    """Monte Carlo of the torque accuracy of the pyramid (theory §1.3).

    Attributes
    ----------
    law_axes : {"nominal", "measured"}
        Axes the law (5) was built with.
    distribution : {"uniform", "normal"}
        Error distribution (uniform within ±tol, or normal, 3σ = tol).
    n_samples : int
        Number of samples S.
    tolerances : dict of str to float
        ``d_delta``, ``d_gamma`` (or ``tilt_a``, ``tilt_b``) [rad],
        ``scale`` [1] and, for measured axes, ``measure_delta``,
        ``measure_gamma`` (or ``measure_tilt_a``, ``measure_tilt_b``)
        [rad].
    mounting : {"pyramid angles", "tilts"}
        What the mounting errors are.
    d_delta, d_gamma : numpy.ndarray, shape (S, N)
        Mounting errors drawn [rad]: Δδ_i, Δγ_i of the pyramid, or the two
        tilts of each axis (`monte_carlo_accuracy_array`).
    d_scale : numpy.ndarray, shape (S, N)
        Scale-factor errors Δ_i [1]: m̂_i = m_i(1 + Δ_i).
    demands : numpy.ndarray, shape (S, 3)
        Demanded torques M (unit vectors when drawn at random) [N·m].
    relative_error, magnitude_error, angle : numpy.ndarray, shape (S,)
        ``|ΔM|/|M|`` [1], ``(|M1|−|M|)/|M|`` [1], Δα [rad]; see
        `TorqueError`.
    relative_error_stats, magnitude_error_stats, angle_stats : ErrorSummary
        Mean, p95, max (of ``|magnitude_error|`` for the magnitude).
    """

    law_axes: str
    distribution: str
    n_samples: int
    tolerances: dict
    mounting: str
    d_delta: np.ndarray
    d_gamma: np.ndarray
    d_scale: np.ndarray
    demands: np.ndarray
    relative_error: np.ndarray
    magnitude_error: np.ndarray
    angle: np.ndarray
    relative_error_stats: ErrorSummary
    magnitude_error_stats: ErrorSummary
    angle_stats: ErrorSummary


def _draw(rng: np.random.Generator, tol: float, shape, distribution: str
          ) -> np.ndarray:
    # always draw, so that a zero tolerance does not shift later draws
    if distribution == "uniform":
        return tol * rng.uniform(-1.0, 1.0, shape)
    return tol / 3.0 * rng.standard_normal(shape)


def _tolerance(value, name: str) -> float:
    v = as_finite_scalar(value, name)
    if v < 0.0:
        raise InvalidValueError(f"{name} must be >= 0, got {v!r}")
    return v


def _demands(demand, n: int, rng: np.random.Generator) -> np.ndarray:
    if demand is None:
        M = rng.normal(size=(n, 3))
        return M / np.linalg.norm(M, axis=1)[:, None]
    M = as_finite_array(demand, "demand")
    if M.shape == (3,):
        M = np.broadcast_to(M, (n, 3))
    elif M.shape == (3, n):
        M = M.T
    else:
        raise ShapeError(
            f"demand must have shape (3,) or (3, {n}) (n_samples), got "
            f"{M.shape}")
    if np.any(np.linalg.norm(M, axis=1) == 0.0):
        raise InvalidValueError("demand must be non-zero")
    return np.ascontiguousarray(M)


def monte_carlo_accuracy(*, d_delta_tol: float, d_gamma_tol: float,
                         scale_tol: float, delta: float = _DELTA,
                         gamma: float = _GAMMA, n_samples: int = 100_000,
                         distribution: str = "uniform",
                         demand: ArrayLike | None = None,
                         law_axes: str = "nominal",
                         measure_delta_tol: float | None = None,
                         measure_gamma_tol: float | None = None,
                         failed: Sequence[int] = (), seed: int = 0
                         ) -> AccuracyResult:
    r"""Monte Carlo of the realised torque of the four-wheel pyramid.

    Per sample s and wheel i: δ_i = δ + Δδ_i, γ_i = γ + Δγ_i (actual
    axes A_1, `actual_axes`), m̂_i = m_i(1 + Δ_i) with m from law (5),

    .. math::
        m = A_L^T (A_L A_L^T)^{-1} M,\quad M_1 = A_1 \hat m,\quad
        \Delta M = M - M_1,\quad
        \Delta\alpha = \arccos\frac{M\cdot M_1}{|M||M_1|}

    where A_L is the nominal A (``law_axes="nominal"``) or the measured
    axes, the actual angles plus measurement errors of tolerance
    ``measure_*_tol`` (``law_axes="measured"``; [1]: then the
    measurement errors take the place of the mounting tolerances). Failed
    wheels have their columns zeroed in A_L and A_1. Vectorised over
    samples: (S, 3, 4) stacks and a batched 3×3 solve.

    Random streams: mounting, scale, demand and measurement errors come
    from four independent children of ``seed``, so runs with the same
    seed and S share their mounting errors (common random numbers) and
    differ only in the law (`compare_law_axes`).

    Parameters
    ----------
    d_delta_tol, d_gamma_tol : float
        Mounting tolerances on δ_i, γ_i [rad].
    scale_tol : float
        Scale-factor tolerance Δ [1].
    delta, gamma : float
        Nominal pyramid angles [rad] (default 55°, 45°).
    n_samples : int
        Number of samples S.
    distribution : {"uniform", "normal"}
        Uniform on ±tol, or normal with 3σ = tol.
    demand : array_like, shape (3,) or (3, S), optional
        Demanded torque(s) M [N·m]; default one random unit direction per
        sample (the errors are relative, so ``|M|`` does not matter).
    law_axes : {"nominal", "measured"}
        Axes used in the law.
    measure_delta_tol, measure_gamma_tol : float, optional
        Measurement tolerances [rad]; required with ``"measured"`` only.
    failed : sequence of int
        0-based failed wheels.
    seed : int
        Seed of the generator.

    Returns
    -------
    AccuracyResult
    """
    tol_d = _tolerance(d_delta_tol, "d_delta_tol")
    tol_g = _tolerance(d_gamma_tol, "d_gamma_tol")
    measure = _measure_tolerances(
        law_axes, {"measure_delta_tol": measure_delta_tol,
                   "measure_gamma_tol": measure_gamma_tol})
    d0 = as_finite_scalar(delta, "delta")
    g0 = as_finite_scalar(gamma, "gamma")
    active = np.ones(4, dtype=bool)
    for i in failed:
        if not 0 <= int(i) < 4:
            raise InvalidValueError(
                f"failed wheel index {i} out of range 0..3 (0-based)")
        active[int(i)] = False
    return _simulate(
        nominal=actual_axes(np.full(4, d0), np.full(4, g0)),
        perturbed=lambda a, b: actual_axes(d0 + a, g0 + b),
        mount_tol={"d_delta": tol_d, "d_gamma": tol_g},
        measure_tol=measure, scale_tol=scale_tol, active=active,
        n_samples=n_samples, distribution=distribution, demand=demand,
        law_axes=law_axes, seed=seed, mounting="pyramid angles")


def _measure_tolerances(law_axes: str, given: dict) -> dict | None:
    if law_axes not in _LAW_AXES:
        raise InvalidValueError(
            f"law_axes must be 'nominal' or 'measured', got {law_axes!r}")
    names = " and ".join(given)
    if law_axes == "measured":
        if any(v is None for v in given.values()):
            raise InvalidValueError(
                f"law_axes='measured' needs {names} (the measurement "
                "tolerances [rad])")
        return {k: _tolerance(v, k) for k, v in given.items()}
    if any(v is not None for v in given.values()):
        raise InvalidValueError(
            f"{names} apply only with law_axes='measured'")
    return None


def _simulate(*, nominal: np.ndarray, perturbed, mount_tol: dict,
              measure_tol: dict | None, scale_tol, active: np.ndarray,
              n_samples, distribution: str, demand, law_axes: str,
              seed: int, mounting: str) -> AccuracyResult:
    """Monte Carlo core shared by the pyramid and general arrays.

    ``perturbed(a, b)`` maps two (S, N) mounting-error arrays to the
    actual axes (S, 3, N); the law uses ``nominal`` (3, N) or the axes
    perturbed by mounting plus measurement errors.
    """
    tol_s = _tolerance(scale_tol, "scale_tol")
    if isinstance(n_samples, bool) or not isinstance(
            n_samples, (int, np.integer)) or n_samples < 1:
        raise InvalidValueError(
            f"n_samples must be a positive int, got {n_samples!r}")
    if distribution not in _DISTRIBUTIONS:
        raise InvalidValueError(
            "distribution must be 'uniform' or 'normal', got "
            f"{distribution!r}")
    n = nominal.shape[1]
    A_nom = nominal * active
    rank = int(np.linalg.matrix_rank(A_nom))
    if rank < 3:
        raise RankError(
            f"failed wheels {[int(i) + 1 for i in np.flatnonzero(~active)]}"
            f" leave rank {rank} < 3: no law can produce an arbitrary "
            "torque", rank=rank, required=3)

    if isinstance(seed, bool) or not isinstance(
            seed, (int, np.integer)) or seed < 0:
        raise InvalidValueError(
            f"seed must be a non-negative int, got {seed!r}")
    S = int(n_samples)
    streams = [np.random.default_rng(s)
               for s in np.random.SeedSequence(seed).spawn(4)]
    tol_a, tol_b = mount_tol.values()
    da = _draw(streams[0], tol_a, (S, n), distribution)
    db = _draw(streams[0], tol_b, (S, n), distribution)
    ds = _draw(streams[1], tol_s, (S, n), distribution)
    M = _demands(demand, S, streams[2])

    A1 = perturbed(da, db) * active                      # (S, 3, N)
    tolerances = dict(mount_tol, scale=tol_s)
    if measure_tol is not None:
        tol_ma, tol_mb = measure_tol.values()
        tolerances |= {k.removesuffix("_tol"): v
                       for k, v in measure_tol.items()}
        AL = perturbed(da + _draw(streams[3], tol_ma, (S, n), distribution),
                       db + _draw(streams[3], tol_mb, (S, n), distribution)
                       ) * active
        AAT = AL @ np.swapaxes(AL, 1, 2)                     # (S, 3, 3)
        y = np.linalg.solve(AAT, M[:, :, None])               # (S, 3, 1)
        m = (np.swapaxes(AL, 1, 2) @ y)[:, :, 0]              # (S, N)
    else:
        G = A_nom.T @ np.linalg.inv(A_nom @ A_nom.T)          # (N, 3)
        m = M @ G.T
    M1 = (A1 @ ((1.0 + ds) * m)[:, :, None])[:, :, 0]
    te = torque_error(M, M1)
    return AccuracyResult(
        law_axes=law_axes, distribution=distribution, n_samples=S,
        tolerances=tolerances, mounting=mounting, d_delta=da, d_gamma=db,
        d_scale=ds, demands=M, relative_error=te.relative_error,
        magnitude_error=te.magnitude_error, angle=te.angle,
        relative_error_stats=ErrorSummary.of(te.relative_error),
        magnitude_error_stats=ErrorSummary.of(np.abs(te.magnitude_error)),
        angle_stats=ErrorSummary.of(te.angle))


def tilted_axes(axes: ArrayLike, tilt_a: ArrayLike,
                tilt_b: ArrayLike) -> np.ndarray:
    """Axes tilted by two small angles each, vectorised over samples.

    The same construction as `WheelArray.with_mounting_errors`: axis
    ``h_i`` is turned by ``tilt_a`` towards ``e1_i`` and then by
    ``tilt_b`` towards ``e2_i``, ``(h_i, e1_i, e2_i)`` a right-handed
    frame (`allocation.arrays.perpendicular_frames`).

    Parameters
    ----------
    axes : array_like, shape (3, N)
        Nominal unit axes.
    tilt_a, tilt_b : array_like, shape (N,) or (S, N)
        Tilt angles [rad].

    Returns
    -------
    numpy.ndarray, shape (3, N) or (S, 3, N)
        Unit axes.
    """
    h = as_finite_array(axes, "axes", (3, None))
    ta = as_finite_array(tilt_a, "tilt_a")
    tb = as_finite_array(tilt_b, "tilt_b")
    if ta.shape[-1:] != h.shape[1:] or ta.ndim > 2 or tb.shape != ta.shape:
        raise ShapeError(
            f"tilt_a and tilt_b must both have shape ({h.shape[1]},) or "
            f"(S, {h.shape[1]}), got {ta.shape} and {tb.shape}")
    e1, e2 = perpendicular_frames(h)
    ta, tb = ta[..., None, :], tb[..., None, :]
    h1 = np.cos(ta) * h + np.sin(ta) * e1
    h2 = np.cos(tb) * h1 + np.sin(tb) * e2
    # (N,) tilts broadcast to (3, N), (S, N) ones to (S, 3, N)
    return h2 / np.linalg.norm(h2, axis=-2, keepdims=True)


def monte_carlo_accuracy_array(array: WheelArray, *, tilt_tol: float,
                               scale_tol: float, n_samples: int = 100_000,
                               distribution: str = "uniform",
                               demand: ArrayLike | None = None,
                               law_axes: str = "nominal",
                               measure_tol: float | None = None,
                               seed: int = 0) -> AccuracyResult:
    """Monte Carlo of the realised torque of any wheel array.

    As `monte_carlo_accuracy`, with each axis tilted by two independent
    angles within ``tilt_tol`` (`tilted_axes`) instead of the pyramid's
    δ_i, γ_i; the result's ``d_delta``/``d_gamma`` hold the two tilts.
    The law is eq. (5) with the array's nominal axes or the measured ones
    (actual tilts plus measurement errors within ``measure_tol``); failed
    wheels of ``array`` are left out. Scale errors of ``array.scale`` are
    not used: ``scale_tol`` draws them.

    Parameters
    ----------
    array : WheelArray
        Nominal axes and failed wheels.
    tilt_tol : float
        Mounting tolerance of each tilt [rad].
    scale_tol : float
        Scale-factor tolerance Δ [1].
    n_samples, distribution, demand, law_axes, seed
        As in `monte_carlo_accuracy`.
    measure_tol : float, optional
        Measurement tolerance of each tilt [rad]; with ``"measured"``
        only.

    Returns
    -------
    AccuracyResult
    """
    if not isinstance(array, WheelArray):
        raise InvalidValueError(
            f"array must be a WheelArray, got {type(array).__name__}")
    tol = _tolerance(tilt_tol, "tilt_tol")
    measure = _measure_tolerances(
        law_axes, {"measure_tol": measure_tol})
    if measure is not None:
        measure = {"measure_tilt_a_tol": measure["measure_tol"],
                   "measure_tilt_b_tol": measure["measure_tol"]}
    h = np.array(array.axes)
    return _simulate(
        nominal=h, perturbed=lambda a, b: tilted_axes(h, a, b),
        mount_tol={"tilt_a": tol, "tilt_b": tol}, measure_tol=measure,
        scale_tol=scale_tol, active=array.active, n_samples=n_samples,
        distribution=distribution, demand=demand, law_axes=law_axes,
        seed=seed, mounting="tilts")


def compare_law_axes(*, measure_delta_tol: float, measure_gamma_tol: float,
                     **options) -> tuple[AccuracyResult, AccuracyResult]:
    """Run `monte_carlo_accuracy` with nominal and with measured axes.

    Both runs share their mounting, scale and demand samples (same seed),
    so the difference is the law alone.

    Parameters
    ----------
    measure_delta_tol, measure_gamma_tol : float
        Measurement tolerances [rad] of the measured-axes run.
    **options
        Other keyword arguments of `monte_carlo_accuracy` (not
        ``law_axes``).

    Returns
    -------
    (AccuracyResult, AccuracyResult)
        Nominal-axes result, measured-axes result.
    """
    if "law_axes" in options:
        raise InvalidValueError(
            "compare_law_axes runs both law_axes; do not pass law_axes")
    nominal = monte_carlo_accuracy(law_axes="nominal", **options)
    measured = monte_carlo_accuracy(
        law_axes="measured", measure_delta_tol=measure_delta_tol,
        measure_gamma_tol=measure_gamma_tol, **options)
    return nominal, measured
