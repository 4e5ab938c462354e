"""Figures of the Basilisk scenarios."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .scenarios import LoopRun


def plot_loops(runs: Mapping[str, LoopRun], title: str = "") -> Any:
    """Pointing error, torque direction error and wheel torques, by loop.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    (ax_p, ax_d), (ax_a, ax_b) = axes
    for name, r in runs.items():
        ax_p.semilogy(r.t, np.degrees(r.pointing_error), label=name)
        ax_d.plot(r.t[1:], np.degrees(r.direction_error), label=name)
    ax_p.set_ylabel("pointing error [deg]")
    ax_d.set_ylabel("commanded vs delivered torque [deg]")
    for ax, (name, r) in zip((ax_a, ax_b), runs.items()):
        for i in range(r.wheel_torque.shape[1]):
            ax.plot(r.t, r.wheel_torque[:, i], label=f"wheel {i + 1}")
        ax.set_ylabel(f"{name}: motor torque [N·m]")
        ax.set_xlabel("time [s]")
    for ax in (ax_p, ax_d, ax_a):
        ax.legend(fontsize=8)
    fail = next(iter(runs.values())).extras.get("t_fail")
    if fail is not None:
        for ax in axes.ravel():
            ax.axvline(fail, color="0.5", ls=":", lw=1)
    fig.suptitle(title or "Basilisk closed loop: rwMotorTorque (clipped "
                 "by the wheel effector) vs QPAllocator")
    fig.tight_layout()
    return fig
