"""Study 3: the six-thruster unit in pulse-cycle mode ([4])."""

from __future__ import annotations

from thrusters import (
    burn_scenario,
    burn_table,
    plot_scenario,
    reorientation_scenario,
    reorientation_table,
)

from adcs.report import (
    PAPER_COLUMNS,
    Figure,
    Section,
    StudyContext,
    Table,
    paper_row,
    shared_reasons,
)


#: Why ours misses a figure of [4], where the cause is known or where
#: the paper lacks what would decide it (quantity prefix -> reason).
REASONS = {
    "yaw error": "[4] does not give its attitude controller: ours is a "
                 "soft PD (ω_n 0.3 rad/s); with 2.5 rad/s and 0.3 N·m every "
                 "attitude row of Table 3 is met (tests)",
    "pitch error": "[4] does not give its attitude controller: ours is a "
                   "soft PD (ω_n 0.3 rad/s); with 2.5 rad/s and 0.3 N·m "
                   "every attitude row of Table 3 is met (tests)",
    "max |H_X|, |H_Z| during": "the law acts at cycle starts, where the "
                               "bound holds (row above); within a 10 s "
                               "cycle the 0.0012 N·m disturbance alone "
                               "adds up to 0.012 N·m·s (tests)",
    "same, steady state": "as above: within the cycles",
    "group": "[4]'s groups each spent 8.6 N·s in balanced pairs, 20x "
             "the torque impulse the slew needs: its controller fired "
             "nearly every cycle, and the paper does not give it; a "
             "stiffer PID, attitude noise or a constant torque does not "
             "reproduce it within the 0.4° holds (docs/findings.md)",
    "D": "[4]'s groups each spent 8.6 N·s in balanced pairs, 20x the "
         "torque impulse the slew needs: its controller fired nearly "
         "every cycle, and the paper does not give it; a stiffer PID, "
         "attitude noise or a constant torque does not reproduce it "
         "within the 0.4° holds (docs/findings.md)",
    "peak |H_Y|": "[4] gives no inertia; with our diagonal J an X slew "
                  "does not couple into Y, while a product of inertia "
                  "J_xz = 0.39 kg·m² gives [4]'s 0.03 N·m·s (tests)",
}


def _judge(quantity: str, paper, ours) -> dict:
    """Tolerance or bound of one row of Tables 3 and 5 (see the notes)."""
    reason = next((v for k, v in REASONS.items()
                   if quantity.startswith(k)), "")
    if paper is None:
        return {}
    if ("(bound)" in quantity or "deviation" in quantity
            or "error" in quantity
            or quantity.startswith(("max |H", "same,"))):
        # a bound of the text, or the accuracy [4] achieved: ours must
        # be at least as good
        return {"bound": float(paper), "reason": reason}
    if quantity.startswith("dV ["):
        return {"tol": 0.025, "reason": reason}     # [4]'s own Δv error
    if quantity.startswith("final X angle"):
        return {"tol": 0.01, "reason": reason}
    return {"rel": 0.2, "reason": reason}


def _table(title: str, rows, note: str) -> Table:
    """Rows judged by `_judge`; a reason of several rows is a note."""
    judged = [_judge(quantity, paper, ours)
              for quantity, paper, ours, _ in rows]
    reasons, notes = shared_reasons([j.get("reason", "") for j in judged])
    out = []
    for (quantity, paper, ours, _), judge, why in zip(rows, judged,
                                                      reasons):
        if judge:
            judge = {**judge, "reason": why}
        out.append(paper_row(quantity.replace(" (bound)", ""),
                             None if paper is not None and "(bound)" in
                             quantity else paper, ours, "", **judge))
    return Table(title, PAPER_COLUMNS, out,
                 f"{note} {notes}" if notes else note, digits=4)


def mpc_hold_table(ctx: StudyContext) -> Table:
    """MPC hold under the paper's disturbance, with and without thrusters."""
    import numpy as np

    from allocation import WheelArray
    from thrusters import six_thruster_unit

    from ocp.models.rigid import rigid_spacecraft
    from ocp.mpc import AttitudeMPC, simulate_mpc

    J = np.diag([3.0, 2.5, 3.5])
    arr = WheelArray.pyramid(m_max=0.005, h_max=0.012)
    dist = np.array([0.0012, 0.0, 0.0])
    t_final = 60.0 if ctx.quick else 300.0
    rows = []
    for label, unit in (("wheels alone", None),
                        ("wheels + six-thruster unit", six_thruster_unit())):
        model = rigid_spacecraft(J, arr, thrusters=unit)
        # sqpmethod for both: the wheels alone saturate, and the condensed
        # SQP (the wheel-only default) stops at its iteration limit with a
        # dynamics defect of 5e-5 in the 300 s run
        r = simulate_mpc(AttitudeMPC(model, solver="sqpmethod"),
                         [1, 0, 0, 0], [1, 0, 0, 0],
                         t_final=t_final, disturbance=dist,
                         estimate_disturbance=True, hold=t_final / 2)
        rows.append([label, float(np.degrees(r.hold_error)),
                     r.peak_momentum, r.extras.get("thruster_on_time", 0.0),
                     1e3 * r.extras.get("propellant", 0.0),
                     1e3 * r.step_time_median])
    return Table(
        f"MPC attitude hold for {t_final:.0f} s under the 0.0012 N·m "
        "disturbance (horizon 20, dt 0.5 s)",
        ["actuators", "hold error, last half [deg]", "peak |H_i| [N·m·s]",
         "valve open [s]", "propellant [g]", "step median [ms]"], rows,
        "Pyramid wheels with |m_i| ≤ 0.005 N·m, |H_i| ≤ 0.012 N·m·s (the "
        "paper's momentum bound); duties 0 ≤ k ≤ 1 with the cycle-averaged "
        "torque and a linear propellant cost. The paper's hold bound is "
        "0.4°; the wheels alone saturate after about 10 s.",
        [rows[0][1] > 0.4, rows[1][1] > 0.4], digits=4)


def run(ctx: StudyContext) -> Section:
    """Compute the study."""
    burn = burn_scenario()
    reo = reorientation_scenario()
    plot_scenario(burn, ctx.out / "thrusters_burn.png")
    plot_scenario(reo, ctx.out / "thrusters_reorientation.png")
    t3 = _table("Burn (Table 2 inputs): the paper's Table 3 beside ours",
                burn_table(burn),
                "54 kg, J = diag(3.0, 2.5, 3.5) kg·m², R = 0.25 m, "
                "L = 0.3 m (assumed, the paper gives none), disturbance "
                "0.0012 N·m; duty cycles from eq. (2) with wheel unloading. "
                "Our thrust deviation is the per-cycle mean with the "
                "transient model and K_p calibrated from it; the paper's "
                "came from its firing-test spread. [4]'s achieved "
                "accuracy and its momentum bound are bounds ours must meet; "
                "Δv is compared to [4]'s own Δv error (0.025 m/s).")
    t5 = _table("Reorientation: the paper's Table 5 beside ours",
                reorientation_table(reo),
                "Hold 0-70 s, 170° about X in 70-240 s, hold to 600 s, "
                "T_T = 2 s, duty cycles from eqs. (8)-(9). Our smooth "
                "(cycloidal) slew and PD controller use far less propellant "
                "than the paper's. The text's limits are bounds; the table's "
                "figures, for which [4] states no tolerance, are compared "
                "at ±20 %.")
    section = Section(
        "thrusters", "3. Six-thruster unit in pulse-cycle mode ([4])",
        "The paper's two scenarios simulated cycle by cycle with the "
        "closed-form duty laws (the QP allocator gives the same duties "
        "where no bound is active, see the tests), and the MPC holding "
        "the attitude with wheels and the unit together.",
        [t3, t5, mpc_hold_table(ctx)],
        [Figure("thrusters_burn.png", "Burn: thrust, wheel momentum, valve "
                "on-times, Δv, attitude"),
         Figure("thrusters_reorientation.png", "Reorientation: thrust, "
                "wheel momentum, valve on-times, Δv, attitude")])
    bounds = [r for r in t5.rows if str(r[2]).startswith("≤")]
    hold = section.tables[-1].rows
    section.summary = [
        f"burn Δv {next(r[3] for r in t3.rows if r[0] == 'dV [m/s]'):.3f} "
        "m/s (paper 4.65)",
        "reorientation bounds: " + ", ".join(
            f"{r[0]} {r[3]:.3g} {r[2]}" for r in bounds),
        f"MPC hold with the unit {hold[1][1]:.3f}° (wheels alone "
        f"{hold[0][1]:.1f}°)",
    ]
    return section
