"""Study 6: slews, NLP vs eigenaxis vs quaternion feedback."""

from __future__ import annotations

from typing import Any

import numpy as np

from ocp.slews.compare import (
    SlewComparisonRow,
    compare_slews,
    meteor_m_spacecraft,
    four_wheel_slew_spacecraft,
)
from adcs.report import Figure, Section, StudyContext, Table


def settle_cell(r: Any) -> float | str:
    """Settle-time cell of a `ClosedLoopResult`: the time [s] or why not.

    The one definition of `ClosedLoopResult.settled`: within the band from
    the settle time to the end and over the whole hold window. A run that
    enters the band only inside the hold window is "not settled", with
    the time it entered the band.
    """
    if r.settled:
        return float(r.settle_time)
    band = np.rad2deg(r.settle_angle)
    if np.isfinite(r.settle_time):
        return (f"not settled (within {band:g}° only from "
                f"{r.settle_time:.4g} s)")
    return f"not settled (never within {band:g}°)"


def mpc_rows(results: list, t_final: float) -> tuple[Table, str]:
    """Table and summary phrase of the closed-loop slew comparison.

    ``results``: `ClosedLoopResult` s of `ocp.mpc.compare_slew` run for
    ``t_final`` [s]. The columns state the settle band and the hold
    window, and a row settles only by `ClosedLoopResult.settled`.
    """
    band = float(np.rad2deg(results[0].settle_angle))
    hold = max(r.hold for r in results)
    rows = [[r.name, settle_cell(r), r.energy, r.peak_torque,
             r.peak_momentum, r.torque_violation, r.momentum_violation,
             float(np.degrees(r.final_error)),
             float(np.degrees(r.hold_error)),
             1e3 * r.step_time_median] for r in results]
    flags = [r.torque_violation > 1e-6 or r.momentum_violation > 1e-6
             for r in results]
    phrases = []
    for r in results:
        if not r.name.startswith("MPC"):
            continue
        name = r.name.removeprefix("MPC ")
        phrases.append(f"{r.settle_time:.4g} s ({name})" if r.settled else
                       f"not settled in {t_final:.4g} s ({name}, hold "
                       f"error {np.rad2deg(r.hold_error):.2g}°)")
    table = Table(
        "",
        ["controller", f"settle to {band:g}° [s]", "Σ∫m² [N²·m²·s]",
         "peak |m_i| [N·m]", "peak |H_i| [N·m·s]", "m violation [N·m]",
         "H violation [N·m·s]", "final error [deg]",
         f"hold error, last {hold:g} s [deg]", "step median [ms]"],
        rows,
        f"Settled means: the error angle stays below {band:g}° from the "
        f"settle time to the end of the {t_final:g} s run and over the "
        f"whole hold window (its largest error, the hold error, is below "
        f"{band:g}° too); a run that enters the band only inside the hold "
        "window has not settled. The open-loop NLP's errors are those of "
        "its plan at its final time.", flags, digits=4)
    mpcs = [r for r in results if r.name.startswith("MPC")]
    lead = (f"MPC settles to {band:g}° (held over the last {hold:g} s) in "
            if all(r.settled for r in mpcs) else
            f"MPC settling to {band:g}° (held over the last {hold:g} s): ")
    return table, lead + ", ".join(phrases)


def mpc_table(ctx: StudyContext) -> tuple[Table, str]:
    """MPC in closed loop vs quaternion feedback vs the time-optimal NLP.

    Returns the table and the summary phrase (`mpc_rows`).
    """
    from allocation import WheelArray

    from adcs_common.quaternion import quat_from_axis_angle
    from ocp.guidance import eigenaxis_slew
    from ocp.models.rigid import rigid_spacecraft
    from ocp.mpc import compare_slew

    wheels = WheelArray.pyramid(np.deg2rad(55), np.deg2rad(45), h_max=0.2,
                                m_max=0.05)
    inertia = np.diag([3.0, 2.5, 3.5])
    model = rigid_spacecraft(inertia, wheels)
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle([1.0, -2.0, 3.0], np.deg2rad(150.0))
    solvers = ("sqpmethod-rti",) if ctx.quick else (
        "sqpmethod", "sqpmethod-rti", "ipopt")
    t_final = 60.0
    results = compare_slew(model, q0, qf, t_final=t_final, hold=15.0,
                           solvers=solvers)
    t_eig = eigenaxis_slew(inertia, q0, qf, wheels=wheels).T
    table, phrase = mpc_rows(results, t_final)
    table.title = ("MPC slew and hold in closed loop (horizon 20, dt "
                   "0.5 s): 150° about (1, −2, 3)")
    table.note = (
        "J = diag(3, 2.5, 3.5) kg·m², pyramid with m_max = 0.05 N·m, "
        f"h_max = 0.2 N·m·s; plant integrated by CVODES. Eigenaxis law: "
        f"{t_eig:.1f} s. Flagged rows exceed a wheel limit (the sampled "
        f"PD law can push a wheel past h_max). {table.note}")
    return table, phrase


def keep_out_table(ctx: StudyContext) -> Table:
    """Time-optimal slews around a Sun keep-out cone (Meteor-M, 90°)."""
    from adcs_common.quaternion import quat_from_axis_angle, quat_to_dcm
    from ocp.guidance import eigenaxis_slew
    from ocp.slews.nlp import KeepOut, time_optimal_slew

    inertia, wheels = meteor_m_spacecraft()
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle([1.0, 1.0, 1.0], np.deg2rad(90.0))
    eig = eigenaxis_slew(inertia, q0, qf, wheels=wheels)
    tracker = np.array([0.0, 0.0, 1.0])
    # the Sun where the tracker points halfway along the eigenaxis slew
    sun = quat_to_dcm(quat_from_axis_angle(eig.axis, eig.angle / 2)) @ tracker
    N = 40 if ctx.quick else 100
    free = time_optimal_slew(inertia, q0, qf, wheels=wheels, N=N)
    rows = []
    for cone in ((20.0,) if ctx.quick else (10.0, 20.0, 30.0)):
        ko = KeepOut(tracker, sun, np.deg2rad(cone))
        r = time_optimal_slew(inertia, q0, qf, wheels=wheels, N=N,
                              keep_out=ko)
        rows.append([cone, float(np.degrees(np.min(ko.margin(free.q)))),
                     r.T, 100.0 * (r.T / free.T - 1.0),
                     float(np.degrees(r.extras["keep_out_node_margin"])),
                     float(np.degrees(r.extras["keep_out_margin"])),
                     "yes" if r.success else "NO", r.solve_time])
    return Table(
        f"Time-optimal slew around a Sun keep-out cone (Meteor-M, 90° about "
        f"(1, 1, 1), N = {N}): star tracker along body z",
        ["cone half-angle [deg]", "free optimum's margin [deg]", "T [s]",
         "longer than free [%]", "margin at nodes [deg]",
         "margin simulated [deg]", "converged", "solve [s]"], rows,
        f"The Sun is where the tracker points halfway along the eigenaxis "
        f"slew; the free time-optimal slew takes {free.T:.2f} s (eigenaxis "
        f"{eig.T:.2f} s). The cone is imposed at the nodes; the simulated "
        "margin (8 points per interval) shows what the grid leaves between "
        "them.", [not r[6] == "yes" for r in rows], digits=4)


#: The slew-against-angle cases: label -> (inertia, wheels, body axis).
CASES = {"Meteor-M pyramid": (*meteor_m_spacecraft(), (1.0, 1.0, 1.0)),
         "[3]": (*four_wheel_slew_spacecraft(), (1.0, -0.5, 0.3))}
METHODS = ("eigenaxis", "time_optimal", "min_energy", "quaternion_feedback")
FIELDS = ("T", "energy", "peak_wheel_torque", "peak_wheel_momentum",
          "success", "solve_time")


def slew_case(case: str, angle_deg: float, N: int) -> dict:
    """Run one angle of `compare_slews` on a `CASES` craft (a sweep case).

    Returns ``{method}_{field}`` for every method and field of its rows.
    """
    inertia, wheels, axis = CASES[case]
    rows, _ = compare_slews(inertia, wheels, axis, [angle_deg], case=case,
                            N=N)
    return {f"{r.method}_{f}": float(getattr(r, f))
            for r in rows for f in FIELDS}


def slew_rows(ctx: StudyContext, angles, N: int) -> dict[str, list]:
    """Sweep `slew_case` over ``angles`` on ``ctx.client``.

    Returns, per case, its `SlewComparisonRow` rows.
    """
    ds = ctx.sweep(slew_case, [{"case": c, "angle_deg": a, "N": N}
                               for c in CASES for a in angles])
    results: dict[str, list] = {c: [] for c in CASES}
    for i in range(ds.sizes["case"]):
        case = str(ds["case"].values[i])
        for m in METHODS:
            if f"{m}_T" in ds:
                vals: dict[str, Any] = {
                    f: float(ds[f"{m}_{f}"].values[i]) for f in FIELDS}
                vals["success"] = bool(vals["success"])
                results[case].append(SlewComparisonRow(
                    case=case, angle_deg=float(ds["angle_deg"].values[i]),
                    method=m, **vals))
    return results


def run(ctx: StudyContext) -> Section:
    """Compute the study."""
    import matplotlib.pyplot as plt

    angles = (30.0, 90.0) if ctx.quick else (30.0, 60.0, 90.0, 120.0,
                                              150.0, 180.0)
    N = 30 if ctx.quick else 60
    results = slew_rows(ctx, angles, N)
    tables = []
    for label, rows in results.items():
        axis = CASES[label][2]
        tables.append(Table(
            f"{label}: slew about {tuple(axis)} (N = {N})",
            ["angle [deg]", "method", "T [s]", "Σ∫m² [N²·m²·s]",
             "peak |m_i| [N·m]", "peak |H_i| [N·m·s]", "converged",
             "solve [s]"],
            [[r.angle_deg, r.method, r.T, r.energy, r.peak_wheel_torque,
              r.peak_wheel_momentum, "yes" if r.success else "NO",
              r.solve_time] for r in rows],
            "Wheel limits through the array (|m_i| ≤ m_max, |H_i| ≤ "
            "h_max). The minimum-energy NLP runs at the eigenaxis time; the "
            "quaternion PD's time is its settling time to 0.1°. Each angle "
            "is one case of a sweep (in this process, or on the Dask "
            "workers of `adcs report --workers`).",
            [not r.success for r in rows], digits=4))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for ax, (label, rows) in zip(axes, results.items()):
        for method in ("eigenaxis", "time_optimal", "quaternion_feedback"):
            pts = [(r.angle_deg, r.T) for r in rows if r.method == method]
            if pts:
                ax.plot(*zip(*pts), "o-", label=method.replace("_", " "))
        ax.set_title(label)
        ax.set_xlabel("slew angle [deg]")
    axes[0].set_ylabel("time [s]")
    axes[0].legend()
    fig_name = ctx.savefig(fig, "slews_time_vs_angle.png")
    tables.append(keep_out_table(ctx))
    mpc, mpc_phrase = mpc_table(ctx)
    tables.append(mpc)
    gains = []
    for rows in results.values():
        for a in angles:
            eig = next(r.T for r in rows if r.angle_deg == a
                       and r.method == "eigenaxis")
            opt = next(r.T for r in rows if r.angle_deg == a
                       and r.method == "time_optimal")
            gains.append(100 * (1 - opt / eig))
    section = Section(
        "slews", "6. Slews: NLPs and MPC vs the closed-form laws",
        "Rest-to-rest slews with wheel-level limits: the eigenaxis "
        "bang–coast–bang law (flight software), quaternion PD feedback "
        "with minimum-norm allocation, the NLPs (IPOPT, multiple "
        "shooting), and the MPC in closed loop. Assumed Meteor-M "
        "inertia diag(3000, 2700, 2000) kg·m² with 25 N·m·s / 0.2 N·m "
        "wheels.", tables,
        [Figure(fig_name, "Slew time against angle")])
    section.summary = [f"time-optimal NLP saves {min(gains):.1f}–"
                       f"{max(gains):.1f} % of the eigenaxis time",
                       mpc_phrase]
    return section
