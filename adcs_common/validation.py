"""Input checks that turn bad arguments into the toolbox's exceptions."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .exceptions import InvalidValueError, ShapeError


def as_finite_array(value, name: str,
                    shape: Sequence[int | None] | None = None
                    ) -> np.ndarray:
    """Return ``value`` as a float array, checking shape and finiteness.

    Parameters
    ----------
    value : array_like
        The argument.
    name : str
        Argument name used in error messages.
    shape : sequence of int or None, optional
        Expected shape; ``None`` entries accept any length.

    Raises
    ------
    ShapeError
        The shape differs from ``shape``.
    InvalidValueError
        The array holds NaN or inf, or cannot be read as numbers.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidValueError(
            f"{name} must be numeric, got {value!r}") from exc
    if shape is not None:
        ok = arr.ndim == len(shape) and all(
            want is None or got == want
            for got, want in zip(arr.shape, shape))
        if not ok:
            want = "(" + ", ".join(
                "n" if s is None else str(s) for s in shape) + ")"
            raise ShapeError(
                f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidValueError(f"{name} must be finite, got {arr!r}")
    return arr


def as_vector(value, n: int | None, name: str) -> np.ndarray:
    """Return ``value`` as a finite 1-D float vector of length ``n``.

    A scalar is broadcast to length ``n`` when ``n`` is given.
    """
    arr = np.array(value, dtype=float) if np.ndim(value) == 0 else value
    if np.ndim(arr) == 0 and n is not None:
        arr = np.full(n, float(arr))
    return as_finite_array(arr, name, (n,))


def as_finite_scalar(value, name: str) -> float:
    """Return ``value`` as a finite float."""
    arr = as_finite_array(value, name, ())
    return float(arr)


def check_positive(arr, name: str) -> None:
    """Raise `InvalidValueError` unless every entry is > 0."""
    if np.any(np.asarray(arr) <= 0):
        raise InvalidValueError(f"{name} must be positive, got {arr!r}")


def check_nonnegative(arr, name: str) -> None:
    """Raise `InvalidValueError` unless every entry is >= 0."""
    if np.any(np.asarray(arr) < 0):
        raise InvalidValueError(
            f"{name} must be non-negative, got {arr!r}")
