"""Study: any spacecraft through every tool (``--spacecraft NAME|FILE``).

Runs on the craft the user names (default: the built-in ``demo`` craft):
its momentum and torque envelopes, the share of the attainable torque set
each allocation law reaches (nominal and with each wheel failed), every
single-wheel failure, a 90° slew by the eigenaxis law, the time-optimal
NLP and the MPC in closed loop, and, where the craft has thrusters, the
duty-cycle QP on a few demands.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from adcs.report import Section, StudyContext, Table
from allocation import QPAllocator, WheelArray, envelope, reach_table
from ocp.spacecraft import Spacecraft, load_spacecraft

DEFAULT = "demo"
#: slew of the study: 90° about this body axis
SLEW_AXIS = (1.0, 1.0, 1.0)


def craft_table(sc: Spacecraft) -> Table:
    """Tabulate the craft: wheels, limits, thrusters, inertia."""
    w = sc.wheels
    rows: list[list[Any]]
    rows = [["wheels", w.n_wheels],
            ["wheel names", ", ".join(w.names)],
            ["failed wheels", ", ".join(str(i + 1) for i in w.failed)
             or "none"],
            ["h_max per wheel [N·m·s]", ", ".join(f"{v:g}" for v in
                                                 w.h_max)],
            ["m_max per wheel [N·m]", ", ".join(f"{v:g}" for v in w.m_max)],
            ["thrusters", f"{sc.thrusters.n} ({', '.join(sc.thrusters.names)})"
             if sc.thrusters is not None else "none"],
            ["inertia eigenvalues [kg·m²]", ", ".join(
                f"{v:.6g}" for v in np.linalg.eigvalsh(sc.inertia))],
            ["rate limit [deg/s]", float(np.rad2deg(sc.rate_max))
             if sc.rate_max is not None else "none"]]
    return Table(f"Spacecraft {sc.name!r}: {sc.description or 'user file'}",
                 ["item", "value"], rows)


def failed_label(failed) -> str:
    """``"wheel 2 failed"``, ``"wheels 1 and 3 failed"``: 1-based numbers.

    ``failed`` holds 0-based indices (`WheelArray.failed`).
    """
    nums = [str(i + 1) for i in sorted(failed)]
    if not nums:
        return "no wheel failed"
    if len(nums) == 1:
        return f"wheel {nums[0]} failed"
    return f"wheels {', '.join(nums[:-1])} and {nums[-1]} failed"


def failure_cases(wheels: WheelArray) -> list[tuple[str, WheelArray]]:
    """``(label, array)``: as given, then each working wheel failing too.

    Labels name every wheel failed in the case (the craft's own failures
    included), numbered 1..N.
    """
    given = "as given" + (f" ({failed_label(wheels.failed)})"
                          if wheels.failed else "")
    cases = [(given, wheels)]
    for i in range(wheels.n_wheels):
        if i not in wheels.failed:
            arr = wheels.with_failed(*wheels.failed, i)
            cases.append((failed_label(arr.failed), arr))
    return cases


def envelope_table(sc: Spacecraft) -> Table:
    """Momentum and torque envelopes of the array, nominal and failed."""
    rows = []
    cases = failure_cases(sc.wheels)
    for label, arr in cases:
        if arr.rank < 3:
            rows.append([label, "—", float("nan"), float("nan"),
                         float("nan"), "array no longer spans 3-D"])
            continue
        for kind in ("momentum", "torque"):
            env = envelope(arr, kind)
            rows.append([label, kind, env.inscribed_radius,
                         float(np.min(env.axis_max)), env.utilisation, ""])
    return Table("Envelopes: largest sphere inside, weakest body axis",
                 ["case", "envelope", "inscribed radius", "min axis extent",
                  "utilisation r/H_Σ", "note"], rows,
                 "Radii in N·m·s (momentum) or N·m (torque); utilisation "
                 "is the inscribed radius over the sum of the working "
                 "wheels' capacities.")


def reach_rows(sc: Spacecraft, n_directions: int) -> Table:
    """Share of the torque zonotope each law reaches, per failure case."""
    results = reach_table(
        sc.wheels, {"bounded QP": lambda a: QPAllocator(a)},
        n_directions=n_directions)
    rows = [[r.law, ", ".join(str(i + 1) for i in r.failed) or "none",
             100 * r.mean_direction_fraction, 100 * r.min_direction_fraction,
             100 * r.volume_fraction] for r in results]
    return Table("Attainable torque set reached by each law",
                 ["law", "failed", "mean over directions %",
                  "worst direction %", "volume %"], rows,
                 f"{n_directions} directions; the bounded QP keeps the "
                 "demanded direction and reaches the whole set.", digits=4)


def slew_setup(sc: Spacecraft) -> tuple:
    """The study's slew: ``(q0, qf, eigenaxis slew, MPC, dt [s])``.

    90° about `SLEW_AXIS` from rest; the eigenaxis law and the RTI MPC
    (horizon 20, dt = T/30 clipped to [0.1, 10] s) on the craft's inertia,
    wheels and rate limit.
    """
    from adcs_common.quaternion import quat_from_axis_angle
    from ocp.guidance import eigenaxis_slew
    from ocp.models import rigid_spacecraft
    from ocp.mpc import AttitudeMPC

    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle(SLEW_AXIS, np.pi / 2)
    eig = eigenaxis_slew(sc, q0, qf)
    dt = float(np.clip(eig.T / 30.0, 0.1, 10.0))
    ctl = AttitudeMPC(rigid_spacecraft(sc.inertia, sc.wheels), dt=dt,
                      rti=True, rate_max=sc.rate_max)
    return q0, qf, eig, ctl, dt


def mpc_row(mpc, dt: float, t_final: float) -> tuple[list, str]:
    """Table row and summary phrase of the closed-loop MPC slew.

    Settled means: within ``mpc.settle_angle`` from the settle time to
    the end of the run, and over the whole hold window (its hold error
    within the same band). A run that only dips into the band, or whose
    hold error exceeds it, is reported as not settled
    (`ClosedLoopResult.settled`, the definition of the slews study too).
    """
    band = float(np.rad2deg(mpc.settle_angle))
    hold = float(np.rad2deg(mpc.hold_error))
    settled = mpc.settled
    label = f"MPC, RTI (horizon 20, dt {dt:.3g} s)"
    note = (f"hold error {hold:.2g}° (band {band:g}°), peak |m_i| "
            f"{mpc.peak_torque:.3g} N·m")
    if settled:
        return ([label, mpc.settle_time, f"settled to {band:g}°", note],
                f"MPC settles to {band:g}° in {mpc.settle_time:.4g} s")
    return ([label, float("nan"), f"not settled to {band:g}° in "
             f"{t_final:.4g} s", note],
            f"MPC not settled to {band:g}° in {t_final:.4g} s (hold "
            f"error {hold:.2g}°)")


def slew_table(sc: Spacecraft, quick: bool) -> tuple[Table, list[str]]:
    """90° slew: eigenaxis law, time-optimal NLP and MPC in closed loop."""
    from ocp.mpc import simulate_mpc
    from ocp.slews import time_optimal_slew

    q0, qf, eig, ctl, dt = slew_setup(sc)
    opt = time_optimal_slew(sc, q0, qf, N=30 if quick else 60)
    err = np.rad2deg(opt.extras.get("simulated_final_error", np.nan))
    rows = [["eigenaxis (bang–coast–bang)", eig.T, "closed form", ""],
            ["time-optimal NLP", opt.T, opt.status,
             f"simulated final error {err:.2g}°"]]
    t_final, hold = 1.6 * eig.T, 0.3 * eig.T
    mpc = simulate_mpc(ctl, q0, qf, t_final=t_final, hold=hold)
    row, phrase = mpc_row(mpc, dt, t_final)
    rows.append(row)
    summary = [f"{sc.name}: 90° slew eigenaxis {eig.T:.4g} s, "
               f"time-optimal {opt.T:.4g} s, {phrase}"]
    band = np.rad2deg(mpc.settle_angle)
    return Table("90° slew about (1, 1, 1) from rest",
                 ["method", "time [s]", "status", "note"], rows,
                 "Time-optimal and eigenaxis under the wheels' torque and "
                 "momentum limits. The MPC (plant integrated by CVODES) "
                 f"runs {t_final:.4g} s; its time is the settling time: "
                 f"the error stays within {band:g}° from then to the end "
                 f"of the run, and its hold error (the largest error over "
                 f"the last {hold:.4g} s) is within {band:g}° too; "
                 "otherwise it has not settled ('—').",
                 digits=5), summary


def thruster_table(sc: Spacecraft) -> Table:
    """Run the duty-cycle QP on a few demands (2 s cycle, ``|H|`` ≤ 0.012)."""
    from thrusters import DutyCycleAllocator

    assert sc.thrusters is not None     # the study checks it first
    alloc = DutyCycleAllocator(sc.thrusters, 2.0, 0.012)
    rows = []
    for P_T, M in ((0.0, (0.002, -0.001)), (0.3, (0.0, 0.001)),
                   (0.0, (0.05, 0.0))):
        r = alloc.solve(P_T, M)
        rows.append([P_T, f"({M[0]:g}, {M[1]:g})", r.status,
                     ", ".join(f"{k:.3f}" for k in r.duty),
                     float(np.max(np.abs(r.tracking_error))),
                     1e3 * r.propellant])
    return Table("Thruster duty cycles (QP, 2 s cycle)",
                 ["thrust P_T [N]", "torque (M_X, M_Z) [N·m]", "status",
                  "duties", "max tracking error", "propellant [g]"], rows,
                 "The last demand is beyond the unit's reach: its status "
                 "says so rather than returning zeros.", digits=4)


def run(ctx: StudyContext) -> Section:
    """Run every generic study on ``ctx.spacecraft`` (default ``demo``)."""
    sc = load_spacecraft(ctx.spacecraft or DEFAULT)
    # the bench's message for an array that cannot steer (rank < 3)
    sc.wheels.require_full_rank()
    tables = [craft_table(sc), envelope_table(sc),
              reach_rows(sc, 200 if ctx.quick else 2000)]
    slews, summary = slew_table(sc, ctx.quick)
    tables.append(slews)
    if sc.thrusters is not None:
        tables.append(thruster_table(sc))
    else:
        summary.append(f"{sc.name}: no thrusters, duty-cycle study skipped")
    intro = (f"The generic studies on {sc.name!r} ({sc.summary()}); the "
             "other sections reproduce the papers on their own craft.")
    return Section("spacecraft", f"Spacecraft {sc.name}", intro, tables,
                   [], summary)
