"""Uncertainty scenarios of a robust (multi-stage) MPC.

A `Scenario` is one plant the robust MPC plans for: an inertia, wheel
spin axes (misaligned), an extra disturbance torque and a weight. The
builders make the sets a designer names: `scenario_grid` (the Cartesian
product of value sets per parameter, do-mpc's multi-stage scheme) and
`inertia_corners` (the nominal craft and the 8 corners of a box of
principal-inertia scale factors).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from adcs_common.rigid_body import check_inertia
from adcs_common.validation import as_finite_array, as_finite_scalar

__all__ = ["Scenario", "inertia_corners", "scenario_grid"]


@dataclass(frozen=True, eq=False)
class Scenario:
    """One plant of a robust MPC's scenario tree.

    Attributes
    ----------
    inertia : ndarray (3, 3)
        Inertia [kg·m²] (symmetric, positive definite).
    axes : ndarray (3, N) or None
        Wheel spin axes (unit columns); None: the model's.
    tau : ndarray (3,)
        Disturbance torque [N·m] added to the MPC's estimate over the
        horizon.
    weight : float
        Relative weight of the scenario's cost (> 0; the MPC normalises
        the weights to sum 1).
    label : str
        A name for reports.
    """

    inertia: np.ndarray
    axes: np.ndarray | None = None
    tau: np.ndarray = field(default_factory=lambda: np.zeros(3))
    weight: float = 1.0
    label: str = ""

    def __post_init__(self) -> None:
        """Check the fields (the toolbox's errors, not numpy's)."""
        J = as_finite_array(self.inertia, "inertia", (3, 3))
        check_inertia(J)
        object.__setattr__(self, "inertia", J)
        if self.axes is not None:
            A = np.array(self.axes, dtype=float)
            if A.ndim != 2 or A.shape[0] != 3 or not np.all(np.isfinite(A)):
                raise InvalidValueError(
                    f"axes must be a finite (3, N) array, got shape "
                    f"{A.shape}")
            norms = np.linalg.norm(A, axis=0)
            if np.any(np.abs(norms - 1.0) > 1e-9):
                raise InvalidValueError("axes must be unit columns")
            object.__setattr__(self, "axes", A)
        object.__setattr__(self, "tau", as_finite_array(self.tau, "tau",
                                                        (3,)))
        w = as_finite_scalar(self.weight, "weight")
        if w <= 0:
            raise InvalidValueError(f"weight must be > 0, got {w}")
        object.__setattr__(self, "weight", w)


def _principal(J: np.ndarray, factors: ArrayLike) -> np.ndarray:
    """J with its principal moments scaled by ``factors`` (3,)."""
    lam, V = np.linalg.eigh(J)
    return V @ np.diag(lam * np.asarray(factors, float)) @ V.T


def _products(J: np.ndarray, p: float) -> np.ndarray:
    """J with ``p`` times its largest moment added to each product."""
    off = p * np.max(np.diag(J)) * (np.ones((3, 3)) - np.eye(3))
    return J + off


def _tilted(axes: np.ndarray, angle: float) -> np.ndarray:
    """Each axis tilted by ``angle`` [rad] towards a fixed perpendicular.

    The perpendicular of axis a is a × e (e the body axis least aligned
    with a), so every wheel is misaligned by the same angle.
    """
    out = np.empty_like(axes)
    for i, a in enumerate(axes.T):
        e = np.eye(3)[int(np.argmin(np.abs(a)))]
        t = np.cross(a, e)
        t /= np.linalg.norm(t)
        out[:, i] = np.cos(angle) * a + np.sin(angle) * t
    return out


def _values(values: Any, name: str) -> list:
    try:
        vals = list(values)
    except TypeError:
        raise InvalidValueError(
            f"{name} must be a sequence of values, got {values!r}") from None
    if not vals:
        raise InvalidValueError(f"{name} must not be empty")
    return vals


def scenario_grid(inertia: ArrayLike, axes: ArrayLike | None = None, *,
                  inertia_scale: Iterable[float] = (1.0,),
                  products: Iterable[float] = (0.0,),
                  misalignment: Iterable[float] = (0.0,),
                  tau: Iterable[ArrayLike] = ((0.0, 0.0, 0.0),),
                  weights: Sequence[float] | None = None
                  ) -> list[Scenario]:
    """The Cartesian product of value sets per uncertain parameter.

    Parameters
    ----------
    inertia : array_like (3, 3)
        The nominal inertia [kg·m²].
    axes : array_like (3, N), optional
        The nominal wheel axes (needed with ``misalignment``).
    inertia_scale : sequence of float
        Values of each principal moment's scale factor [1]; the three
        principal axes take them independently (``{0.8, 1, 1.2}`` gives
        27 inertias).
    products : sequence of float
        Values of the products of inertia, as a fraction of the largest
        moment [1], added to all three.
    misalignment : sequence of float
        Values of every wheel axis's tilt [rad] (`_tilted`).
    tau : sequence of array_like (3,)
        Disturbance torques [N·m].
    weights : sequence of float, optional
        One per scenario of the product (default: equal).

    Returns
    -------
    list of Scenario
        In the order of ``itertools.product`` (scale x, y, z, products,
        misalignment, tau); the nominal values first when listed first.
    """
    J = as_finite_array(inertia, "inertia", (3, 3))
    check_inertia(J)
    A = None if axes is None else np.asarray(axes, dtype=float)
    scales = _values(inertia_scale, "inertia_scale")
    mis = _values(misalignment, "misalignment")
    if A is None and any(float(m) != 0.0 for m in mis):
        raise InvalidValueError("misalignment needs the nominal axes")
    combos = list(itertools.product(scales, scales, scales,
                                    _values(products, "products"), mis,
                                    _values(tau, "tau")))
    if weights is not None and len(weights) != len(combos):
        raise InvalidValueError(
            f"weights has {len(weights)} entries for {len(combos)} "
            "scenarios")
    out = []
    for i, (fx, fy, fz, p, m, t) in enumerate(combos):
        Js = _products(_principal(J, (fx, fy, fz)), float(p))
        out.append(Scenario(
            Js, None if A is None or float(m) == 0.0 else _tilted(A, float(m)),
            np.asarray(t, dtype=float), 1.0 if weights is None
            else weights[i], f"J×({fx:g}, {fy:g}, {fz:g}), p {p:g}, "
            f"tilt {m:g} rad"))
    return out


def inertia_corners(inertia: ArrayLike, spread: float = 0.2
                    ) -> list[Scenario]:
    """The nominal inertia and the 8 corners of ``1 ± spread`` (9).

    Each corner scales the three principal moments by ``1 ± spread``
    independently [1].
    """
    s = as_finite_scalar(spread, "spread")
    if not 0.0 < s < 1.0:
        raise InvalidValueError(f"spread must be in (0, 1), got {s}")
    J = as_finite_array(inertia, "inertia", (3, 3))
    check_inertia(J)
    out = [Scenario(J, label="nominal")]
    for f in itertools.product((1 - s, 1 + s), repeat=3):
        out.append(Scenario(_principal(J, f),
                            label=f"J×({f[0]:g}, {f[1]:g}, {f[2]:g})"))
    return out
