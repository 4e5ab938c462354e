"""Reaction-wheel arrays: spin axes, limits, failures, mounting errors."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError, RankError, ShapeError
from adcs_common.validation import (
    as_angle,
    as_angles,
    as_index,
    as_finite_array,
    as_vector,
    check_positive,
)

#: Column signs of the Meteor-M No. 2 pyramid (theory §1.1, [1] eq. 6):
#: h_i = (-sin d cos g, SY_i sin d sin g, SZ_i cos d).
PYRAMID_SIGN_Y = np.array([1.0, -1.0, -1.0, 1.0])
PYRAMID_SIGN_Z = np.array([-1.0, -1.0, 1.0, 1.0])

#: Most wheels a `WheelArray` (and a spacecraft file) may hold: the
#: attainable-set geometry grows as N³ facets (10,000 wheels needed
#: 1.1 GiB before any answer), and no attitude system flies more.
MAX_WHEELS = 64
_UNIT_TOL = 1e-9
_RANK_TOL = 1e-9


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


def pyramid_axes(delta: ArrayLike, gamma: ArrayLike) -> np.ndarray:
    r"""Spin axes of the four-wheel pyramid, [1] eq. (6).

    .. math::
        h_i = (-\sin\delta_i\cos\gamma_i,\;
               \sigma^y_i\sin\delta_i\sin\gamma_i,\;
               \sigma^z_i\cos\delta_i)

    with :math:`\sigma^y = (+,-,-,+)`, :math:`\sigma^z = (-,-,+,+)`.

    Parameters
    ----------
    delta, gamma : float or array_like (4,)
        Mounting angles [rad]; scalars give the nominal pyramid, 4-vectors
        give per-wheel angles (mounting errors included).

    Returns
    -------
    numpy.ndarray, shape (3, 4)
        Unit spin axes as columns.
    """
    d = np.broadcast_to(np.asarray(delta, dtype=float), (4,))
    g = np.broadcast_to(np.asarray(gamma, dtype=float), (4,))
    return np.vstack([
        -np.sin(d) * np.cos(g),
        PYRAMID_SIGN_Y * np.sin(d) * np.sin(g),
        PYRAMID_SIGN_Z * np.cos(d),
    ])


@dataclass(frozen=True, eq=False)
class WheelArray:
    r"""A reaction-wheel array.

    Wheel ``i`` (0-based in code, named ``i + 1`` in reports) spins about
    the unit column ``axes[:, i]`` of the body frame. Motor torques ``m``
    (on the rotors, :math:`\dot H_i = m_i`) give the array torque
    :math:`M = A m` of [1] eq. (1); the reaction on the body is
    :math:`-M`.

    Attributes
    ----------
    axes : numpy.ndarray, shape (3, N)
        Unit spin axes (body frame), the matrix A; 1 <= N <= `MAX_WHEELS`
        (64).
    h_max : numpy.ndarray, shape (N,)
        Momentum capacity of each wheel [N·m·s].
    m_max : numpy.ndarray, shape (N,)
        Torque capacity of each wheel [N·m].
    failed : tuple of int
        0-based indices of failed wheels (their torque is held at zero).
    names : tuple of str
        Wheel names for reports (default ``"RW1"`` to ``"RWN"``).
    scale : numpy.ndarray, shape (N,)
        Actual / commanded torque of each wheel, ``1 + Δ_i`` (scale-factor
        errors, [1]); ones when ideal.
    """

    axes: np.ndarray
    h_max: np.ndarray
    m_max: np.ndarray
    failed: tuple[int, ...] = ()
    names: tuple[str, ...] = ()
    # None by default: __post_init__ stores ones(n)
    scale: np.ndarray = field(default=None)  # type: ignore[arg-type]

    def __post_init__(self) -> None:
        """Check the fields and store read-only copies."""
        axes = as_finite_array(self.axes, "axes", (3, None))
        n = axes.shape[1]
        if n == 0:
            raise ShapeError("axes must have at least one column, got 0")
        if n > MAX_WHEELS:
            raise InvalidValueError(
                f"a WheelArray holds at most {MAX_WHEELS} wheels "
                f"(MAX_WHEELS), got {n}")
        norms = np.linalg.norm(axes, axis=0)
        if np.any(norms < 1e-12):
            bad = [int(i) + 1 for i in np.flatnonzero(norms < 1e-12)]
            raise InvalidValueError(
                f"axes: wheel(s) {bad} have a zero-length spin axis")
        if np.any(np.abs(norms - 1.0) > _UNIT_TOL):
            raise InvalidValueError(
                "axes must be unit columns (use WheelArray.from_axes(..., "
                f"normalize=True)); column norms are {norms}")
        h_max = as_vector(self.h_max, n, "h_max")
        m_max = as_vector(self.m_max, n, "m_max")
        check_positive(h_max, "h_max")
        check_positive(m_max, "m_max")
        scale = np.ones(n) if self.scale is None else as_vector(
            self.scale, n, "scale")
        check_positive(scale, "scale")
        failed = tuple(sorted({as_index(i, n, 'failed wheel')
                               for i in self.failed}))
        for i in failed:
            if not 0 <= i < n:
                raise InvalidValueError(
                    f"failed wheel index {i} out of range 0..{n - 1} "
                    "(indices are 0-based)")
        names = tuple(self.names) if self.names else tuple(
            f"RW{i + 1}" for i in range(n))
        if len(names) != n:
            raise ShapeError(f"names must have {n} entries, got "
                             f"{len(names)}")
        object.__setattr__(self, "axes", _readonly(axes))
        object.__setattr__(self, "h_max", _readonly(h_max))
        object.__setattr__(self, "m_max", _readonly(m_max))
        object.__setattr__(self, "scale", _readonly(scale))
        object.__setattr__(self, "failed", failed)
        object.__setattr__(self, "names", names)

    # ----------------------------------------------------------------- views
    @property
    def n_wheels(self) -> int:
        """Number of wheels N, failed ones included."""
        return self.axes.shape[1]

    @property
    def active(self) -> np.ndarray:
        """Boolean mask (N,) of working wheels."""
        mask = np.ones(self.n_wheels, dtype=bool)
        mask[list(self.failed)] = False
        return mask

    @property
    def working_axes(self) -> np.ndarray:
        """Axes (3, N) with the columns of failed wheels zeroed.

        [1]: "the elements of the column of the failed wheel must be
        zeroed" so that the general law (5) still applies.
        """
        a = np.array(self.axes)
        a[:, list(self.failed)] = 0.0
        return a

    @property
    def rank(self) -> int:
        """Numerical rank of the working axes."""
        return int(np.linalg.matrix_rank(self.working_axes, tol=_RANK_TOL))

    def require_full_rank(self) -> None:
        """Raise `RankError` unless the working wheels span 3-D space."""
        r = self.rank
        if r < 3:
            raise RankError(
                f"array: the working wheels span rank {r} < 3 "
                f"(failed wheels {[i + 1 for i in self.failed]}); no law "
                "can produce an arbitrary torque", rank=r, required=3)

    def body_torque(self, m: ArrayLike) -> np.ndarray:
        r"""Torque the array actually produces for commanded ``m``.

        Parameters
        ----------
        m : array_like, shape (N,) or (N, K)
            Commanded motor torques [N·m].

        Returns
        -------
        numpy.ndarray, shape (3,) or (3, K)
            :math:`A\,\mathrm{diag}(s)\,m` with failed wheels giving no
            torque [N·m].
        """
        m = np.asarray(m, dtype=float)
        s = self.scale * self.active
        return self.working_axes @ (s[:, None] * m if m.ndim == 2 else s * m)

    # ------------------------------------------------------------- variants
    def with_failed(self, *indices: int) -> "WheelArray":
        """Return a copy with the wheels ``indices`` (0-based) failed too."""
        flat: list[int] = []
        for i in indices:
            flat.extend(i if isinstance(i, Iterable)
                        and not isinstance(i, str) else [i])
        return replace(self, failed=tuple(self.failed) + tuple(flat))

    def with_scale_errors(self, errors: ArrayLike) -> "WheelArray":
        """Return a copy whose actual torques are ``m_i (1 + errors_i)``."""
        errors = as_vector(errors, self.n_wheels, "errors")
        return replace(self, scale=1.0 + errors)

    def with_axes(self, axes: Any) -> "WheelArray":
        """Return a copy with other spin axes (same limits and failures)."""
        return replace(self, axes=axes)

    def with_mounting_errors(self, tilt_a: ArrayLike,
                             tilt_b: ArrayLike) -> "WheelArray":
        """Return a copy with every axis tilted by two small angles.

        Axis ``h_i`` is rotated by ``tilt_a[i]`` towards ``e1_i`` and then
        by ``tilt_b[i]`` towards ``e2_i``, where ``(e1_i, e2_i)`` complete
        ``h_i`` to a right-handed frame (``e1_i`` is horizontal when
        possible). For the pyramid the paper's angles are used instead by
        ``WheelArray.pyramid(..., d_delta=..., d_gamma=...)``.

        Parameters
        ----------
        tilt_a, tilt_b : array_like (N,)
            Tilt angles [rad].
        """
        n = self.n_wheels
        ta = as_angles(tilt_a, n, "tilt_a")
        tb = as_angles(tilt_b, n, "tilt_b")
        h = self.axes
        e1, e2 = perpendicular_frames(h)
        h1 = np.cos(ta) * h + np.sin(ta) * e1
        h2 = np.cos(tb) * h1 + np.sin(tb) * e2
        return replace(self, axes=h2 / np.linalg.norm(h2, axis=0))

    # ---------------------------------------------------------- constructors
    @classmethod
    def from_axes(cls, axes, h_max=1.0, m_max=1.0, *, normalize=False,
                  failed: Sequence[int] = (),
                  names: Sequence[str] = ()) -> "WheelArray":
        """Build an array from user-given axes.

        Parameters
        ----------
        axes : array_like, shape (3, N)
            Spin axes as columns (body frame).
        h_max, m_max : float or array_like (N,)
            Momentum [N·m·s] and torque [N·m] capacity of each wheel.
        normalize : bool
            Scale the columns to unit length instead of rejecting them.
        """
        axes = as_finite_array(axes, "axes", (3, None))
        if normalize:
            # scale first: a 1e200 axis must not overflow to inf (or look
            # zero-length after dividing by it)
            big = np.abs(axes).max(axis=0)
            axes = axes / np.where(big > 0, big, 1.0)
            norms = np.linalg.norm(axes, axis=0)
            if np.any(norms < 1e-12):
                bad = [int(i) + 1 for i in np.flatnonzero(norms < 1e-12)]
                raise InvalidValueError(
                    f"axes: wheel(s) {bad} have a zero-length spin axis")
            axes = axes / norms
        return cls(axes=axes, h_max=h_max, m_max=m_max,
                   failed=tuple(failed), names=tuple(names))

    @classmethod
    def pyramid(cls, delta: float = np.deg2rad(55.0),
                gamma: float = np.deg2rad(45.0), *, h_max=1.0, m_max=1.0,
                d_delta=None, d_gamma=None,
                failed: Sequence[int] = ()) -> "WheelArray":
        """Four-wheel pyramid of Meteor-M No. 2 ([1] eq. 6, theory §1.1).

        Parameters
        ----------
        delta, gamma : float
            Mounting angles [rad] (paper: 55°, 45°).
        h_max, m_max : float or array_like (4,)
            Wheel momentum [N·m·s] and torque [N·m] capacity.
        d_delta, d_gamma : array_like (4,), optional
            Per-wheel mounting errors [rad]: ``δ_i = δ + Δδ_i``,
            ``γ_i = γ + Δγ_i``.
        """
        delta = as_angle(delta, "delta")
        gamma = as_angle(gamma, "gamma")
        dd = np.zeros(4) if d_delta is None else as_angles(
            d_delta, 4, "d_delta")
        dg = np.zeros(4) if d_gamma is None else as_angles(
            d_gamma, 4, "d_gamma")
        return cls(axes=pyramid_axes(delta + dd, gamma + dg),
                   h_max=h_max, m_max=m_max, failed=tuple(failed))

    @classmethod
    def orthogonal_plus_skew(cls, *, skew: str = "paper",
                             phi2: float = np.pi / 4,
                             phi3: float = np.pi / 4, h_max=1.0, m_max=1.0,
                             failed: Sequence[int] = ()) -> "WheelArray":
        """Three wheels on the body axes plus one skewed ([3]).

        Parameters
        ----------
        skew : {"paper", "equal_angle"}
            ``"paper"``: the 4th axis is the first row of its
            direction-cosine matrix,
            ``(cos φ2 cos φ3, cos φ2 sin φ3, -sin φ2)``, which is
            ``(0.5, 0.5, -0.7071)`` for the paper's 45° angles;
            ``"equal_angle"``: the classic ``(1, 1, 1)/√3``.
        phi2, phi3 : float
            The paper's angles [rad] (used with ``skew="paper"``).
        """
        phi2 = as_angle(phi2, "phi2")
        phi3 = as_angle(phi3, "phi3")
        if skew == "paper":
            h4 = [np.cos(phi2) * np.cos(phi3), np.cos(phi2) * np.sin(phi3),
                  -np.sin(phi2)]
        elif skew == "equal_angle":
            h4 = np.ones(3) / np.sqrt(3.0)
        else:
            raise InvalidValueError(
                f"skew must be 'paper' or 'equal_angle', got {skew!r}")
        axes = np.column_stack([np.eye(3), h4])
        return cls(axes=axes, h_max=h_max, m_max=m_max, failed=tuple(failed))

    @classmethod
    def orthogonal_pairs(cls, *, h_max=1.0, m_max=1.0,
                         failed: Sequence[int] = ()) -> "WheelArray":
        """Three orthogonal pairs of wheels, six in all (Chibis-M, [2]).

        Wheels 1-2 spin about x, 3-4 about y, 5-6 about z.
        """
        axes = np.repeat(np.eye(3), 2, axis=1)
        names = ("RW1x", "RW2x", "RW3y", "RW4y", "RW5z", "RW6z")
        return cls(axes=axes, h_max=h_max, m_max=m_max, failed=tuple(failed),
                   names=names)


def perpendicular_frames(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing each column of ``h`` (3, N) to a frame."""
    h = np.asarray(h, dtype=float)
    ref = np.where(np.abs(h[2]) < 0.9, 1.0, 0.0)
    refv = np.vstack([1.0 - ref, np.zeros_like(ref), ref])
    e1 = np.cross(refv.T, h.T).T
    e1 /= np.linalg.norm(e1, axis=0)
    e2 = np.cross(h.T, e1.T).T
    return e1, e2

