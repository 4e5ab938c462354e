"""One figure per built-in sweep (matplotlib, saved beside its dataset)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_sweep(name: str, ds, path: Path) -> Path:
    """Draw the result ``ds`` of built-in sweep ``name`` into ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = np.asarray(ds["error"]) == ""
    if not ok.any():
        from .engine import SweepError

        raise SweepError(
            f"every case of the {name} sweep failed (the dataset's 'error' "
            f"says why, e.g. {str(np.asarray(ds['error'])[0])!r})")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    if name == "geometry":
        for f in sorted(set(np.asarray(ds["failed"]).tolist())):
            sel = ok & (np.asarray(ds["failed"]) == f)
            ax.plot(np.asarray(ds["delta_deg"])[sel],
                    np.asarray(ds["utilisation"])[sel], "o",
                    label="nominal" if f == 0 else f"wheel {f} failed")
        ax.set_xlabel("δ [deg]")
        ax.set_ylabel("torque utilisation r/H_Σ")
    elif name == "accuracy":
        ax.plot(np.asarray(ds["seed"])[ok],
                np.asarray(ds["angle_p95_deg"])[ok], "o")
        ax.set_xlabel("Monte Carlo block")
        ax.set_ylabel("p95 torque direction error [deg]")
    elif name == "agility":
        for a in sorted(set(np.asarray(ds["axis"]).tolist())):
            sel = ok & (np.asarray(ds["axis"]) == a)
            ax.plot(np.asarray(ds["angle_deg"])[sel],
                    np.asarray(ds["time_optimal_T"])[sel], "o-",
                    label=f"axis {a}")
        ax.set_xlabel("slew angle [deg]")
        ax.set_ylabel("time-optimal slew time [s]")
    else:
        ax.bar(np.asarray(ds["wheel"])[ok],
               np.asarray(ds["settle_time"])[ok])
        ax.set_xlabel("failed wheel")
        ax.set_ylabel("settling time to 0.1° [s]")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"adcs sweep {name}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
