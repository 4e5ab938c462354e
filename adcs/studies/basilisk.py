"""Study 7: the wheel allocators in Basilisk's closed loop."""

from __future__ import annotations

import numpy as np

from adcs.basilisk import INSTALL_HINT, basilisk_available
from adcs.report import Figure, Section, StudyContext, Table

TITLE = "7. In Basilisk: rwMotorTorque vs the bounded QP"


def _table(title: str, runs: dict) -> Table:
    rows = []
    for name, r in runs.items():
        s = r.summary()
        rows.append([name, s["max direction error [deg]"],
                     s["final pointing error [deg]"], s["peak |u| [N·m]"]])
    return Table(title, ["allocator", "max direction error [deg]",
                         "final pointing error [deg]", "peak |u| [N·m]"],
                 rows, "Direction error: the angle between the torque "
                 "mrpFeedback asked for and the torque the wheels put on "
                 "the body over the next step.", digits=4)


def run(ctx: StudyContext) -> Section:
    """Compute the study (skipped, and saying why, without Basilisk)."""
    if not basilisk_available():
        section = Section("basilisk", TITLE, "Skipped: Basilisk is not "
                          f"installed ({INSTALL_HINT}). The README's first "
                          "command installs it; docs/basilisk.md lists "
                          "the versions it pins.")
        section.summary = [f"skipped: Basilisk not installed; {INSTALL_HINT}"]
        return section
    from adcs.basilisk.plots import plot_loops
    from adcs.basilisk.scenarios import compare_loops

    t_final = 200.0 if ctx.quick else 400.0
    nominal = compare_loops(t_final=t_final)
    failed = compare_loops(t_final=t_final, fail_wheel=1, t_fail=10.0)
    f1 = ctx.savefig(plot_loops(nominal), "basilisk_saturated.png")
    f2 = ctx.savefig(plot_loops(failed, "Wheel 2 reported unavailable at "
                                "10 s, mid-slew"), "basilisk_failure.png")
    from adcs.basilisk.mpc_scenario import mpc_slew

    mpc = mpc_slew(t_final=40.0 if ctx.quick else 60.0).summary()
    mpc_table = Table(
        "The report's MPC slew (150° about (1, −2, 3), RTI, horizon 20) "
        "in Basilisk's dynamics and in ours",
        ["quantity", "value"], [[k, v] for k, v in mpc.items()],
        "AttitudeMPCModule reads Basilisk's navigation and wheel speeds "
        "and writes the wheel torques; Basilisk integrates by RK4 at "
        "0.1 s, ours by CVODES.", digits=4)
    from adcs.basilisk.thruster_scenario import compare_reorientation

    thr = compare_reorientation(t_final=60.0 if ctx.quick else 120.0)
    thr_table = Table(
        "[4]'s six-thruster unit reorienting 30° in Basilisk: "
        "thrForceMapping + thrFiringRemainder vs the duty-cycle QP",
        ["chain", *next(iter(thr.values())).summary()],
        [[k, *r.summary().values()] for k, r in thr.items()],
        "54 kg, J = diag(3.0, 2.5, 3.5) kg·m², T_T = 2 s, mrpFeedback "
        "K = 0.3, P = 1.5; the unit cannot torque about Y. The QP asks for "
        "zero net thrust every cycle; the mapping does not.", digits=4)
    section = Section(
        "basilisk", TITLE,
        "The Meteor-M pyramid in Basilisk (spacecraft hub, "
        "reactionWheelStateEffector with u_max = 0.2 N·m clipping each "
        "wheel, simpleNav, inertial3D, attTrackingError, mrpFeedback with "
        "K = 20, P = 500) slewing 40° from rest, so mrpFeedback asks for "
        "several times what the wheels give. Loop 1: Basilisk's "
        "rwMotorTorque (minimum norm, no limits), clipped by the effector. "
        "Loop 2: the toolbox's QPAllocator as a Basilisk module "
        "(adcs.basilisk.WheelQPAllocatorModule): bounded, the largest "
        "torque along the commanded direction.",
        [_table(f"Saturated 40° slew, {t_final:.0f} s", nominal),
         _table("Wheel 2 unavailable from 10 s (availability message to "
                "both allocators)", failed), mpc_table, thr_table],
        [Figure(f1, "Saturated slew: pointing error, direction error of "
                "the delivered torque, wheel torques"),
         Figure(f2, "The same slew with wheel 2 failing at 10 s")])
    d = {k: np.degrees(r.direction_error.max()) for k, r in nominal.items()}
    section.summary = [
        f"saturated slew: torque direction error {d['rwMotorTorque']:.1f}° "
        f"(rwMotorTorque, clipped) vs {d['QPAllocator']:.1e}° (QP)"]
    return section
