"""Input checks that turn bad arguments into the toolbox's exceptions."""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .exceptions import InvalidValueError, ShapeError


def as_finite_array(value: ArrayLike, name: str,
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
        The array holds NaN or inf, cannot be read as numbers, or is a
        bool or a string (even "1e-4": a number is passed as a number).
    """
    if isinstance(value, (bool, np.bool_, str, bytes)) or (
            isinstance(value, np.ndarray) and value.dtype.kind in "bSU"):
        raise InvalidValueError(f"{name} must be a number, got {value!r}")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
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
        got = float(arr) if arr.ndim == 0 else np.array2string(
            arr, threshold=12)
        raise InvalidValueError(f"{name} must be finite, got {got}")
    return arr


def as_vector(value: ArrayLike, n: int | None, name: str) -> np.ndarray:
    """Return ``value`` as a finite 1-D float vector of length ``n``.

    A scalar is broadcast to length ``n`` when ``n`` is given.
    """
    if np.ndim(value) == 0 and n is not None:
        return np.full(n, as_finite_scalar(value, name))
    return as_finite_array(value, name, (n,))


def as_finite_scalar(value: ArrayLike, name: str) -> float:
    """Return ``value`` as a finite float."""
    arr = as_finite_array(value, name, ())
    return float(arr)


def check_positive(arr: ArrayLike, name: str) -> None:
    """Raise `InvalidValueError` unless every entry is > 0."""
    if np.any(np.asarray(arr) <= 0):
        raise InvalidValueError(f"{name} must be positive, got {arr!r}")


def check_nonnegative(arr: ArrayLike, name: str) -> None:
    """Raise `InvalidValueError` unless every entry is >= 0."""
    if np.any(np.asarray(arr) < 0):
        raise InvalidValueError(
            f"{name} must be non-negative, got {arr!r}")


def as_index(value, n: int, name: str) -> int:
    """Return ``value`` as an integer index in ``0..n-1``.

    Only integers are indices: a bool, a float (even ``1.0``), None or a
    string raises, so ``1.5`` never silently becomes ``1``.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(
            value, (int, np.integer)):
        raise InvalidValueError(
            f"{name} must be an integer index, got {value!r}")
    if not 0 <= int(value) < n:
        raise InvalidValueError(
            f"{name} {int(value)} is out of range 0..{n - 1} (indices are "
            "0-based)")
    return int(value)


def as_count(value, name: str, minimum: int = 1) -> int:
    """Return ``value`` as an integer >= ``minimum`` (no bool, no float)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
            value, (int, np.integer)) or value < minimum:
        raise InvalidValueError(
            f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def as_options(value, name: str = "solver_options") -> dict:
    """Return a copy of an options dict (None: empty); else raise."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise InvalidValueError(
            f"{name} must be a dict of solver options, got "
            f"{type(value).__name__}")
    return dict(value)


def check_instance(value, cls: type, name: str) -> None:
    """Raise `InvalidValueError` unless ``value`` is a ``cls``."""
    if not isinstance(value, cls):
        raise InvalidValueError(
            f"{name} must be a {cls.__name__}, got {type(value).__name__}")


def check_items(values, cls: type, name: str) -> list:
    """Return ``values`` as a list, each a ``cls`` (else `InvalidValueError`).

    For the functions that tabulate result objects.
    """
    if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
        raise InvalidValueError(
            f"{name} must be a sequence of {cls.__name__}, got "
            f"{type(values).__name__}")
    items = list(values)
    for i, v in enumerate(items):
        if not isinstance(v, cls):
            raise InvalidValueError(
                f"{name}[{i}] must be a {cls.__name__}, got "
                f"{type(v).__name__}")
    return items


def as_angle(value, name: str, limit: float = 2.0 * np.pi) -> float:
    """Return ``value`` as a finite angle [rad] with ``|value| <= limit``.

    A larger value is almost always degrees given where radians are
    expected (``WheelArray.pyramid(55, 45)``): the error says so and
    suggests ``np.deg2rad``.

    Raises
    ------
    InvalidValueError
        Not a finite number, or beyond ``limit``.
    """
    v = as_finite_scalar(value, name)
    if abs(v) > limit:
        raise InvalidValueError(
            f"{name} = {v:g} rad is beyond {limit:.4g} rad: angles are in "
            f"radians; for degrees pass np.deg2rad({v:g})")
    return v


def as_angles(value, n: int | None, name: str,
              limit: float = 2.0 * np.pi) -> np.ndarray:
    """Return ``value`` as a vector of angles [rad], each within ``limit``.

    Raises
    ------
    ShapeError, InvalidValueError
        Wrong length, not finite, or an angle beyond ``limit`` (degrees
        given for radians: the error suggests ``np.deg2rad``).
    """
    v = as_vector(value, n, name)
    big = np.abs(v) > limit
    if big.any():
        i = int(np.argmax(big))
        raise InvalidValueError(
            f"{name}[{i}] = {v[i]:g} rad is beyond {limit:.4g} rad: angles "
            f"are in radians; for degrees pass np.deg2rad(...)")
    return v
