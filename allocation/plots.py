"""Matplotlib figures of envelopes and accuracy studies (no pyplot state)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_array

from .envelope import Envelope

if TYPE_CHECKING:  # pragma: no cover
    from .accuracy import AccuracyResult

__all__ = ["facet_polygons", "plot_accuracy_histogram",
           "plot_error_histogram", "plot_envelope"]

_ON_FACET_TOL = 1e-9


def _new_axes(projection: str | None = None) -> Any:
    """Make a fresh axes on a pyplot-free Figure with an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0, 5.0))
    FigureCanvasAgg(fig)
    return fig.add_subplot(projection=projection)


def facet_polygons(env: Envelope) -> list[np.ndarray]:
    """Vertices of each facet, ordered around it.

    Parameters
    ----------
    env : Envelope

    Returns
    -------
    list of numpy.ndarray, each (k, 3)
        One polygon per facet (rhombi for the pyramid), counter-clockwise
        seen from outside [env units].
    """
    polys = []
    V = env.vertices
    scale = max(env.circumscribed_radius, 1.0)
    for n, d in zip(env.facets.normals, env.facets.offsets):
        on = V[np.abs(V @ n - d) <= _ON_FACET_TOL * scale * 10]
        c = on.mean(axis=0)
        e1 = on[0] - c
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        ang = np.arctan2((on - c) @ e2, (on - c) @ e1)
        polys.append(on[np.argsort(ang)])
    return polys


def plot_envelope(env: Envelope, ax: Any = None, *, color: str = "C0",
                  alpha: float = 0.35, show_spheres: bool = False) -> Any:
    """Draw the envelope polyhedron in 3-D.

    Parameters
    ----------
    env : Envelope
        From `allocation.envelope`.
    ax : mpl_toolkits.mplot3d.Axes3D, optional
        Axes with ``projection="3d"``; a new pyplot-free figure is made
        when omitted (``ax.figure.savefig(...)`` to save it).
    color : str
        Face colour.
    alpha : float
        Face opacity.
    show_spheres : bool
        Also draw the inscribed sphere as a wireframe.

    Returns
    -------
    mpl_toolkits.mplot3d.Axes3D
        The axes drawn on. Never calls ``plt.show``.
    """
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    if not isinstance(env, Envelope):
        raise InvalidValueError(
            f"env must be an Envelope, got {type(env).__name__}")
    if ax is None:
        ax = _new_axes("3d")
    elif getattr(ax, "name", "") != "3d":
        raise InvalidValueError(
            "ax must be a 3-D axes (add_subplot(projection='3d')), got "
            f"{getattr(ax, 'name', type(ax).__name__)!r}")
    ax.add_collection3d(Poly3DCollection(
        facet_polygons(env), facecolors=color, edgecolors="k",
        linewidths=0.6, alpha=alpha))
    ax.scatter(*env.vertices.T, color="k", s=6)
    if show_spheres:
        u, v = np.mgrid[0:2 * np.pi:24j, 0:np.pi:12j]
        r = env.inscribed_radius
        ax.plot_wireframe(r * np.cos(u) * np.sin(v), r * np.sin(u)
                          * np.sin(v), r * np.cos(v), color="C1",
                          linewidth=0.4)
    lim = env.circumscribed_radius * 1.05
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_zlim(-lim, lim)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel(f"x [{env.units}]")
    ax.set_ylabel(f"y [{env.units}]")
    ax.set_zlabel(f"z [{env.units}]")
    ax.set_title(f"{env.kind} envelope: {env.n_facets} facets, "
                 f"r = {env.inscribed_radius:.4g} {env.units}")
    return ax


def plot_accuracy_histogram(result: "AccuracyResult", ax: Any = None, *,
                            quantity: str = "relative_error",
                            bins: int = 60, label: str | None = None
                            ) -> Any:
    """Histogram of a Monte Carlo accuracy study ([1], theory §1.3).

    Parameters
    ----------
    result : AccuracyResult
        From `allocation.accuracy.monte_carlo_accuracy`.
    ax : matplotlib.axes.Axes, optional
        2-D axes; a new pyplot-free figure is made when omitted.
    quantity : {"relative_error", "angle"}
        ``|ΔM|/|M|`` in percent, or the cross-coupling angle Δα in degrees.
    bins : int
        Number of bins.
    label : str, optional
        Legend label (default: the law's axes, "nominal" or "measured").

    Returns
    -------
    matplotlib.axes.Axes
        The axes, with p95 and max marked by vertical lines.
    """
    # the result's arrays (result: any law-error result object)
    values: Any = {"relative_error": getattr(result, "relative_error", None),
                   "angle": getattr(result, "angle", None)}.get(quantity)
    return plot_error_histogram(
        values, ax, quantity=quantity, bins=bins,
        label=label or f"law with {result.law_axes} axes",
        title=f"{result.n_samples:,} samples ({result.distribution})")


def plot_error_histogram(values: ArrayLike, ax: Any = None, *,
                         quantity: str = "relative_error", bins: int = 60,
                         label: str | None = None, title: str | None = None
                         ) -> Any:
    """Histogram of Monte Carlo torque errors, p95 (dashed) and max (dotted).

    Parameters
    ----------
    values : array_like, shape (S,)
        ``|ΔM|/|M|`` [1] for ``quantity="relative_error"`` (plotted in
        percent), or Δα [rad] for ``"angle"`` (plotted in degrees).
    ax : matplotlib.axes.Axes, optional
        2-D axes; a new pyplot-free figure is made when omitted.
    quantity : {"relative_error", "angle"}
    bins : int
        Number of bins.
    label, title : str, optional
        Legend label and axes title.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if quantity == "relative_error":
        scale, xlabel = 100.0, "|ΔM| / |M| [%]"
    elif quantity == "angle":
        scale, xlabel = float(np.rad2deg(1.0)), "Δα [deg]"
    else:
        raise InvalidValueError(
            "quantity must be 'relative_error' or 'angle', got "
            f"{quantity!r}")
    data = scale * as_finite_array(values, "values").ravel()
    if data.size == 0:
        raise InvalidValueError("values must not be empty")
    if ax is None:
        ax = _new_axes()
    ax.hist(data, bins=bins, density=True, alpha=0.6, label=label)
    for q, style in ((np.percentile(data, 95), "--"), (data.max(), ":")):
        ax.axvline(q, color="k", linestyle=style, linewidth=0.8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("probability density")
    if title:
        ax.set_title(title, fontsize="medium")
    if label:
        ax.legend()
    return ax
