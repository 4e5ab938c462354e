"""The scenarios' tables beside the paper's, and their plots."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

import numpy as np

from adcs_common.exceptions import InvalidValueError
from .scenarios import (
    MASS,
    REORIENT_BOUNDS,
    ScenarioResult,
    TABLE2,
    TABLE3,
    TABLE5_ENGINES,
    TABLE5_GROUPS,
)

if TYPE_CHECKING:
    import pandas as pd



# ----------------------------------------------------------------------
# tables
def _row(quantity, paper, ours):
    diff = None if paper is None else ours - paper
    return (quantity, paper, float(ours), diff)


def burn_table(result: ScenarioResult) -> list[tuple]:
    """Table 3 of [4] beside ours: rows (quantity, paper, ours, diff).

    Yaw error is the rotation of the thrust axis (+Y) about body Z, pitch
    error about body X (for small errors these are the deviations of the
    thrust vector's yaw and pitch angles); statistics over the burn.
    Thrust deviation: per-cycle true mean thrust (transients included)
    minus P_T. Δv error: ``|Δv|`` at the end minus P_T T_imp / m0. Wheel
    momentum: at cycle starts (where the laws act), and its peak within
    the cycles, over the whole burn and after the first 8 cycles.
    """
    P_T = TABLE2["P_T"]
    dev = np.abs(result.net_thrust - P_T)
    burn = result.t <= TABLE2["T_imp"]
    yaw = np.rad2deg(np.abs(result.attitude_error[burn, 2]))
    pitch = np.rad2deg(np.abs(result.attitude_error[burn, 0]))
    dv_req = P_T * TABLE2["T_imp"] / MASS
    dv = float(np.linalg.norm(result.velocity[-1]))
    return [
        _row("thrust deviation max [N]", TABLE3["thrust_dev_max"],
             dev.max()),
        _row("thrust deviation max [%]", TABLE3["thrust_dev_max_pct"],
             100 * dev.max() / P_T),
        _row("thrust deviation mean [N]", TABLE3["thrust_dev_mean"],
             dev.mean()),
        _row("thrust deviation mean [%]", TABLE3["thrust_dev_mean_pct"],
             100 * dev.mean() / P_T),
        _row("yaw error max [deg]", TABLE3["yaw_err_max"], yaw.max()),
        _row("yaw error mean [deg]", TABLE3["yaw_err_mean"], yaw.mean()),
        _row("pitch error max [deg]", TABLE3["pitch_err_max"], pitch.max()),
        _row("pitch error mean [deg]", TABLE3["pitch_err_mean"],
             pitch.mean()),
        _row("dV error [m/s]", TABLE3["dV_err"], abs(dv - dv_req)),
        _row("dV error [%]", TABLE3["dV_err_pct"],
             100 * abs(dv - dv_req) / dv_req),
        _row("dV [m/s]", TABLE2["dV"], dv),
        _row("max |H_X|, |H_Z| at cycle starts [N·m·s]", TABLE2["H_max"],
             _cycle_start_momentum(result)),
        _row("max |H_X|, |H_Z| during the burn [N·m·s]", TABLE2["H_max"],
             np.abs(result.wheel_momentum[burn][:, [0, 2]]).max()),
        _row("same, steady state (t > 80 s) [N·m·s]", TABLE2["H_max"],
             np.abs(result.wheel_momentum[burn & (result.t > 80.0)][
                 :, [0, 2]]).max()),
    ]


def _cycle_start_momentum(result):
    idx = np.searchsorted(result.t, result.cycle_start[1:] - 1e-9)
    idx = np.append(idx, len(result.t) - 1)
    return float(np.max(np.abs(result.wheel_momentum[idx][:, [0, 2]])))


def reorientation_table(result: ScenarioResult) -> list[tuple]:
    """Table 5 of [4] beside ours, plus the text's bounds.

    Rows (quantity, paper, ours, diff). Group Δv: the group's impulse
    over the initial mass; group thrust: per-cycle mean thrust of the
    group; per engine: valve openings N_K, total, max and mean open time
    [ms] (commanded). Then: hold error (max over 0-70 s and 240-600 s),
    propellant, max valve open time, residual ``|Δv|``, peak ``|H_Y|``.
    """
    rows = []
    gt = result.group_thrust
    for gi, (gname, paper) in enumerate(TABLE5_GROUPS.items()):
        dv = gt[:, gi].sum() * result.cycle / MASS
        rows.append(_row(f"{gname} dV [m/s]", paper[0], dv))
        rows.append(_row(f"{gname} max thrust in a cycle [N]", paper[1],
                         gt[:, gi].max()))
        rows.append(_row(f"{gname} mean thrust [N]", paper[2],
                         gt[:, gi].mean()))
    ms = 1e3 * result.on_time
    for i, name in enumerate(result.unit.names):
        paper = TABLE5_ENGINES.get(name, (None,) * 4)
        opened = ms[:, i] > 0
        nk = int(opened.sum())
        rows.append(_row(f"{name} valve openings", paper[0], nk))
        rows.append(_row(f"{name} total open [ms]", paper[1],
                         ms[:, i].sum()))
        rows.append(_row(f"{name} max open [ms]", paper[2], ms[:, i].max()))
        rows.append(_row(f"{name} mean open [ms]", paper[3],
                         ms[opened, i].mean() if nk else 0.0))
    hold = (result.t <= 70.0) | (result.t >= 240.0)
    err = np.rad2deg(np.linalg.norm(result.attitude_error[hold], axis=1))
    rows += [
        _row("hold error max [deg] (bound)", REORIENT_BOUNDS[
            "hold_error_deg"], err.max()),
        _row("propellant [g] (bound)", REORIENT_BOUNDS["propellant_g"],
             1e3 * result.propellant),
        _row("max valve open per cycle [ms] (bound)",
             REORIENT_BOUNDS["max_open_ms"], ms.max()),
        _row("residual |dV| [m/s]", REORIENT_BOUNDS["residual_dv"],
             np.linalg.norm(result.velocity[-1])),
        _row("peak |H_Y| [N·m·s]", REORIENT_BOUNDS["H_y_peak"],
             np.abs(result.wheel_momentum[:, 1]).max()),
        _row("final X angle [deg]", 170.0,
             np.rad2deg(result.angle[-1, 0]) % 360),
    ]
    return rows


def format_table(rows: list[tuple], title: str = "") -> str:
    """Rows (quantity, paper, ours, diff) as a fixed-width text table."""
    def f(v):
        if v is None:
            return "-"
        return f"{v:.4g}"
    w = max(len(r[0]) for r in rows)
    lines = [title] if title else []
    lines.append(f"{'quantity':<{w}}  {'paper':>10}  {'ours':>10}  "
                 f"{'ours-paper':>10}")
    for q, p, o, d in rows:
        lines.append(f"{q:<{w}}  {f(p):>10}  {f(o):>10}  {f(d):>10}")
    return "\n".join(lines)


# ----------------------------------------------------------------------
# plots
def plot_scenario(result: ScenarioResult, path: Any) -> None:
    """Thrust, wheel momentum, valve on-times, Δv and attitude to ``path``.

    Parameters
    ----------
    result : ScenarioResult
    path : str or path-like
        Output file (format from the suffix, e.g. ``.png``, ``.pdf``).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(5, 1, figsize=(8, 13), sharex=True)
    tc = result.cycle_start
    gt = result.group_thrust
    ax[0].step(tc, gt[:, 0], where="post", label="group 1 (+Y)")
    ax[0].step(tc, gt[:, 1], where="post", label="group 2 (-Y)")
    ax[0].set_ylabel("mean thrust in cycle [N]")
    ax[0].legend()
    for j, lab in enumerate("XYZ"):
        ax[1].plot(result.t, result.wheel_momentum[:, j], label=f"H_{lab}")
    ax[1].set_ylabel("wheel momentum [N·m·s]")
    ax[1].legend()
    # one row per engine, a bar per opening (engines sharing a position,
    # e.g. D1 and D4, no longer hide each other's traces)
    for i in range(result.unit.n):
        bars = [(t, on) for t, on in zip(tc, result.on_time[:, i]) if on > 0]
        ax[2].broken_barh(bars, (i - 0.4, 0.8), color=f"C{i % 10}")
    ax[2].set_yticks(range(result.unit.n), result.unit.names)
    ax[2].set_ylim(-0.7, result.unit.n - 0.3)
    ax[2].invert_yaxis()
    ax[2].set_ylabel("valve open (bar = on-time)")
    ax[3].plot(result.t, np.linalg.norm(result.velocity, axis=1))
    ax[3].set_ylabel("|Δv| [m/s]")
    if result.name == "burn":
        for j, lab in enumerate("XYZ"):
            ax[4].plot(result.t, np.rad2deg(result.attitude_error[:, j]),
                       label=f"error about {lab}")
        ax[4].set_ylabel("attitude error [deg]")
    else:
        for j, lab in enumerate("XYZ"):
            ax[4].plot(result.t, np.rad2deg(result.angle[:, j]),
                       label=f"angle {lab}")
        ax[4].set_ylabel("attitude [deg]")
    ax[4].legend()
    ax[4].set_xlabel("t [s]")
    fig.suptitle(f"[4] {result.name} scenario")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def table_frame(rows: list[tuple]) -> pd.DataFrame:
    """Rows (quantity, paper, ours, diff) as a `pandas.DataFrame`."""
    import pandas as pd

    rows = list(rows) if isinstance(rows, (list, tuple)) else None
    if rows is None or not all(isinstance(r, tuple) and len(r) == 4
                               for r in rows):
        raise InvalidValueError(
            "rows must be a list of (quantity, paper, ours, diff) tuples, "
            "as burn_table / reorientation_table return")
    return pd.DataFrame(
        [{"quantity": q, "paper": np.nan if p is None else p, "ours": o,
          "difference": np.nan if d is None else d} for q, p, o, d in rows])
