"""One figure per built-in sweep (matplotlib, saved beside its dataset)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


#: line styles and markers cycled with the colours, so that no two of
#: the plot's lines look the same
LINESTYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D", "v", "P")


def line_styles(n: int) -> list[dict]:
    """``n`` distinct line styles: colour, linestyle and marker each.

    Colours are spread over the ``turbo`` colour map (no repeats), and
    linestyle and marker cycle too, so lines stay apart in grey.
    """
    import matplotlib

    cmap = matplotlib.colormaps["turbo"]
    return [{"color": cmap(0.05 + 0.9 * i / max(n - 1, 1)),
             "linestyle": LINESTYLES[i % len(LINESTYLES)],
             "marker": MARKERS[i % len(MARKERS)]} for i in range(n)]


def axis_label(index: int, direction) -> str:
    """``"axis 3 (+0.41, -0.50, +0.76)"``: numbered 1..N, with direction.

    ``index`` is the 0-based index of the sweep's ``axis`` parameter.
    """
    x, y, z = (float(v) for v in direction)
    return f"axis {index + 1} ({x:+.2f}, {y:+.2f}, {z:+.2f})"


def _agility(ax, ds, ok) -> None:
    """Slew time against angle, one line per axis (1..N, with direction)."""
    from .builtin import fibonacci_axes

    axes = sorted(set(np.asarray(ds["axis"]).tolist()))
    known = fibonacci_axes()
    for a, style in zip(axes, line_styles(len(axes))):
        sel = ok & (np.asarray(ds["axis"]) == a)
        direction = ([float(np.asarray(ds[f"axis_{c}"])[sel][0])
                      for c in "xyz"] if "axis_x" in ds and sel.any()
                     else known[int(a)])
        ax.plot(np.asarray(ds["angle_deg"])[sel],
                np.asarray(ds["time_optimal_T"])[sel],
                label=axis_label(int(a), direction), **style)
    ax.set_xlabel("slew angle [deg]")
    ax.set_ylabel("time-optimal slew time [s]")


def _robust(ax, ds, ok) -> None:
    """Energy of each draw, nominal against robust MPC."""
    styles = line_styles(2)
    for c, style in zip(("nominal", "robust"), styles):
        ax.plot(np.asarray(ds["draw"])[ok], np.asarray(ds[f"{c}_energy"])[ok],
                linestyle="none", marker=style["marker"],
                color=style["color"], label=f"{c} MPC")
    ax.set_xlabel("Monte Carlo draw")
    ax.set_ylabel("energy ∑∫m² dt [N²·m²·s]")


def sweep_figure(name: str, ds):
    """The figure of built-in sweep ``name``'s result ``ds`` (matplotlib)."""
    import matplotlib.pyplot as plt

    ok = np.asarray(ds["error"]) == ""
    if not ok.any():
        from .engine import SweepError

        raise SweepError(
            f"every case of the {name} sweep failed (the dataset's 'error' "
            f"says why, e.g. {str(np.asarray(ds['error'])[0])!r})")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    if name == "geometry":
        cases = sorted(set(np.asarray(ds["failed"]).tolist()))
        for f, style in zip(cases, line_styles(len(cases))):
            sel = ok & (np.asarray(ds["failed"]) == f)
            ax.plot(np.asarray(ds["delta_deg"])[sel],
                    np.asarray(ds["utilisation"])[sel], linestyle="none",
                    marker=style["marker"], color=style["color"],
                    label="nominal" if f == 0 else f"wheel {f} failed")
        ax.set_xlabel("δ [deg]")
        ax.set_ylabel("torque utilisation r/H_Σ")
    elif name == "accuracy":
        ax.plot(np.asarray(ds["seed"])[ok],
                np.asarray(ds["angle_p95_deg"])[ok], "o")
        ax.set_xlabel("Monte Carlo block")
        ax.set_ylabel("p95 torque direction error [deg]")
    elif name == "agility":
        _agility(ax, ds, ok)
    elif name in ("robust", "robust-basilisk"):
        _robust(ax, ds, ok)
    else:
        ax.bar(np.asarray(ds["wheel"])[ok],
               np.asarray(ds["settle_time"])[ok])
        ax.set_xlabel("failed wheel")
        ax.set_ylabel("settling time to 0.1° [s]")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, ncol=2 if len(ax.get_lines()) > 6 else 1)
    ax.grid(alpha=0.3)
    craft = ds.attrs.get("spacecraft_name")
    ax.set_title(f"adcs sweep {name}" + (f" ({craft})" if craft else ""))
    fig.tight_layout()
    return fig


def plot_sweep(name: str, ds, path: Path) -> Path:
    """Draw the result ``ds`` of built-in sweep ``name`` into ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = sweep_figure(name, ds)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
