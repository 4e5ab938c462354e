"""Study 5: Chibis-M actuator failures and the gravity boom ([2])."""

from __future__ import annotations

import numpy as np

from ocp.missions.magnetic_boom import (
    ChibisConfig,
    CircularOrbit,
    MAX_DIPOLE,
    deployed_inertia,
    dipole_scale_gain,
    initial_state,
    pitch_offset_eq37,
    planar_critical_dipole,
    planar_model_critical_dipole,
    simulate,
)
from adcs.report import (
    PAPER_COLUMNS,
    Figure,
    Section,
    StudyContext,
    Table,
    paper_row,
    verdict,
)

#: -Bdot gain of the detumbling runs [A·m²·s/T] (saturates at 3.2 A·m²).
DETUMBLE_GAIN = 5e5
SETTLED = np.deg2rad(1.0)
#: [2]'s pitch offset at k = 0.1 A·m² [deg], printed to the degree, and
#: the tolerance that printing gives it [deg]
PITCH_PAPER_DEG, PITCH_TOL_DEG = 6.0, 0.5


def _settle_time(t: np.ndarray, rate: np.ndarray) -> float:
    """First time after which ``|rate|`` stays below 1°/s [s] (NaN: never)."""
    above = np.flatnonzero(np.abs(rate) >= SETTLED)
    if above.size == 0:
        return 0.0
    if above[-1] == len(t) - 1:
        return float("nan")
    return float(t[above[-1] + 1])


def detumble(ctx: StudyContext, orbit: CircularOrbit):
    """-Bdot from 10°/s per axis, all coils and coil 1 off (paper Fig. 2)."""
    import matplotlib.pyplot as plt

    n_orbits = 3 if ctx.quick else 5
    runs = {}
    for label, coils in (("all coils", (1, 1, 1)),
                         ("coil 1 off", (0, 1, 1))):
        cfg = ChibisConfig(bdot_gain=DETUMBLE_GAIN, coils=coils)
        x0 = initial_state(cfg, (5, 5, 5), (10, 10, 10))
        runs[label] = simulate(cfg, x0, n_orbits * orbit.period, n_out=800)
    rows = []
    for label, r in runs.items():
        rows.append([label] + [_settle_time(r.t, r.w_rel[:, i]) / 60
                               for i in range(3)]
                    + [float(np.degrees(np.abs(r.w_rel[-1]).max()))])
    slow = rows[1][1:4]
    slowest = int(np.nanargmax(np.nan_to_num(slow, nan=np.inf))) + 1
    table = Table(
        "Detumbling by -Bdot (eq. 1.7) from 10°/s per axis, 3.2 A·m² coils",
        ["coils", "ω1 < 1°/s after [min]", "ω2 [min]", "ω3 [min]",
         f"max |ω| after {n_orbits} orbits [deg/s]"], rows,
        f"Stowed inertia diag(1.02, 1.51, 1.73) kg·m², gain "
        f"{DETUMBLE_GAIN:.0e} A·m²·s/T, 6850 km, 51.7°. Paper (Fig. 2): "
        "with coil 1 off the system still damps the rate, the third "
        f"component more slowly. Ours: axis {slowest} is the slowest with "
        "coil 1 off ('—' = not below 1°/s within the run).", digits=3)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), sharey=True)
    for ax, (label, r) in zip(axes, runs.items()):
        for i in range(3):
            ax.plot(r.t / 60, np.degrees(r.w_rel[:, i]), label=f"ω{i + 1}")
        ax.set_title(label)
        ax.set_xlabel("time [min]")
    axes[0].set_ylabel("rate relative to the orbit frame [deg/s]")
    axes[0].legend()
    fig_ = Figure(ctx.savefig(fig, "chibis_detumble.png"),
                  "-Bdot detumbling, all coils and with coil 1 off")
    return table, fig_, slowest


def pitch_offset(ctx: StudyContext, orbit: CircularOrbit, inertia):
    """Boom + pitch wheel + -Bdot: the offset of eq. (3.7)."""
    import matplotlib.pyplot as plt

    dipoles = (0.05, 0.1, 0.2) if ctx.quick else (0.025, 0.05, 0.1, 0.15,
                                                  0.2, 0.3)
    n_orbits = 8 if ctx.quick else 12
    rows, sims, theory = [], [], []
    for k in dipoles:
        cfg = ChibisConfig(inertia=inertia,
                           bdot_gain=dipole_scale_gain(orbit, k))
        r = simulate(cfg, initial_state(cfg, H0=(0, 0.05, 0)),
                     n_orbits * orbit.period, n_out=1500)
        late = r.t > n_orbits / 2 * orbit.period
        sim = float(np.degrees(r.angles[late, 0].mean()))
        eq = float(np.degrees(pitch_offset_eq37(orbit, inertia, k)))
        paper = PITCH_PAPER_DEG if k == 0.1 else "—"
        judged = (verdict(paper, sim, tol=PITCH_TOL_DEG) if k == 0.1
                  else "—")
        rows.append([f"k = {k} A·m²", paper,
                     f"±{PITCH_TOL_DEG:g}" if k == 0.1 else "—", eq, sim,
                     sim - eq, judged])
        sims.append(sim)
        theory.append(eq)
    table = Table(
        "Pitch offset with the boom, a 0.05 N·m·s pitch wheel and -Bdot "
        "(eq. 3.7)", ["dipole scale", "paper [deg]", "tolerance [deg]",
                      "eq. (3.7) [deg]", "simulation, mean α [deg]",
                      "sim − eq. (3.7)", "verdict"], rows,
        "k in eq. (3.7) is the -Bdot dipole scale (gain × B0 ω0), not a "
        "constant dipole along the boom: held in the orbit frame the "
        "field turns at ω0 and -Bdot then gives a constant pitch torque "
        "2 k B0 sin² i. Deployed inertia inferred from the paper's ε = 0.16 "
        "and 6° (A, B, C) = ("
        + ", ".join(f"{v:.2f}" for v in inertia) + ") kg·m², "
        "so the 6° row checks the inference; the others test eq. (3.7) "
        "against the nonlinear 3-D model. The paper prints 6° to the "
        f"degree: the simulation is judged to ±{PITCH_TOL_DEG:g}°, the "
        "rounding of that figure.", digits=3)
    fig, ax = plt.subplots(figsize=(5, 3.6))
    ax.plot(dipoles, theory, "k-", label="eq. (3.7)")
    ax.plot(dipoles, sims, "o", label="simulation")
    ax.set_xlabel("dipole scale k [A·m²]")
    ax.set_ylabel("pitch offset [deg]")
    ax.legend()
    return table, Figure(ctx.savefig(fig, "chibis_pitch_offset.png"),
                         "Pitch offset vs dipole: eq. (3.7) and the 3-D "
                         "simulation"), max(abs(s - t) for s, t in
                                            zip(sims, theory))


def boundary(ctx: StudyContext, orbit: CircularOrbit, inertia) -> Table:
    """Largest dipole that keeps the boom vertical (paper: 0.35 / 0.41)."""
    rate0 = 0.6 * orbit.rate
    n_phases, n_orbits = (4, 3.0) if ctx.quick else (8, 5.0)
    worst = planar_critical_dipole(inertia, orbit, rate0, phase="worst",
                                   n_phases=n_phases, n_orbits=n_orbits)
    best = planar_critical_dipole(inertia, orbit, rate0, phase="best",
                                  n_phases=n_phases, n_orbits=n_orbits)
    rows = [
        paper_row("linear model (α = 90° forcing), α̇0 = 0.6 ω0", 0.35,
                  planar_model_critical_dipole(inertia, orbit, rate0),
                  "the paper's model, our inferred inertia", rel=0.05),
        paper_row("nonlinear eq. (3.4), worst phase", 0.41, worst,
                  "", rel=0.05, reason="the paper's 0.41 is its 3-D run "
                  "with damping; ours is planar and undamped"),
        paper_row("nonlinear eq. (3.4), best phase", 0.41, best, "",
                  rel=0.05, reason="as above"),
    ]
    return Table("Oscillation/rotation boundary: largest dipole along the "
                 "boom [A·m²], α0 = 0, α̇0 = 0.6 ω0", PAPER_COLUMNS, rows,
                 f"Polar orbit, constant dipole along the boom, no damping, "
                 f"{n_orbits:g} orbits, {n_phases} initial phases. Without "
                 "damping the orbital-rate forcing pumps the softening "
                 "pendulum over the top at smaller dipoles than the linear "
                 "model predicts. Compared to ±5 % (the inertia is "
                 "inferred, [2] does not give it).", digits=3)


def _reach_time(t: np.ndarray, h: np.ndarray, limit: float) -> float:
    """Time the ramp ``h(t)`` reaches ``limit`` [s] (NaN: never).

    Extrapolated along the ramp from the last output sample below the
    limit (its slope from that sample and the one before), so the time
    is not rounded up to the output grid.
    """
    at = np.flatnonzero(np.abs(h) >= limit - 1e-9)
    if at.size == 0:
        return float("nan")
    k = int(at[0])
    if k == 0:
        return float(t[0])
    j = max(k - 2, 0)
    slope = (abs(h[k - 1]) - abs(h[j])) / (t[k - 1] - t[j]) if k > 1 \
        else (abs(h[k]) - abs(h[k - 1])) / (t[k] - t[k - 1])
    if not slope > 0:
        return float(t[k])
    return float(t[k - 1] + (limit - abs(h[k - 1])) / slope)


#: pitch-wheel spin-up of Fig. 8: torque [N·m] and momentum limit [N·m·s]
SPIN_TORQUE, SPIN_LIMIT = 2.2e-4, 0.05


def spin_up(ctx: StudyContext, orbit: CircularOrbit, inertia):
    """Pitch-wheel spin-up with -Bdot at full dipole (paper Fig. 8)."""
    n_orbits = 4 if ctx.quick else 8
    cfg = ChibisConfig(inertia=inertia, bdot_gain=1e7,
                       spin_torque=(0, SPIN_TORQUE, 0),
                       spin_limit=SPIN_LIMIT)
    r = simulate(cfg, initial_state(cfg, (5, 5, 5), (0.15, 0.15, 0.15)),
                 n_orbits * orbit.period, n_out=1200)
    tilt = np.degrees(np.arccos(np.clip(
        np.cos(r.angles[:, 1]) * np.cos(r.angles[:, 2]), -1, 1)))
    t_full = _reach_time(r.t, r.H[:, 1], SPIN_LIMIT)
    step = float(r.t[1] - r.t[0])
    rows = [
        paper_row("wheel momentum reached [N·m·s]", SPIN_LIMIT,
                  float(r.H[-1, 1]), f"{SPIN_TORQUE:g} N·m, limit "
                  f"{SPIN_LIMIT:g}", rel=1e-3, reason="the torque stops "
                  "at the limit within one integrator step"),
        paper_row("time to reach it [s]", SPIN_LIMIT / SPIN_TORQUE, t_full,
                  "paper: limit / torque; ours: the simulated ramp, "
                  f"output every {step:.1f} s", rel=0.01,
                  reason="the wheel torque is not the constant "
                  f"{SPIN_TORQUE:g} N·m of Fig. 8"),
        paper_row(f"wheel-axis tilt from the orbit normal after "
                  f"{n_orbits} orbits [deg]", "→ 0", float(tilt[-1]),
                  f"-Bdot saturating at {MAX_DIPOLE} A·m²",
                  reason="[2] shows a trend towards 0, not a figure")]
    return Table("Pitch-wheel spin-up with the boom deployed (Fig. 8)",
                 PAPER_COLUMNS, rows,
                 "The momentum is compared to ±0.1 % of the limit and the "
                 "time to ±1 %: with a constant torque both follow from "
                 "Fig. 8's torque and limit. The time is read off the "
                 "simulated ramp (extrapolated from the last output "
                 "sample below the limit, not rounded up to the "
                 f"{step:.1f} s output grid).", digits=4), float(tilt[-1])


def failure_table(ctx: StudyContext, orbit: CircularOrbit, inertia) -> Table:
    """Which actuators remain -> strategy, each row a simulation."""
    n = 3 if ctx.quick else 6
    T = n * orbit.period
    rows = []

    cfg = ChibisConfig(bdot_gain=DETUMBLE_GAIN, wheel_gains=(0.02, 2e-4))
    r = simulate(cfg, initial_state(cfg, (20, 20, 20), (0.5, 0.5, 0.5)), T)
    err = np.degrees(np.abs(r.angles[-200:]).max())
    rows.append(["all coils and wheel pairs", "no", "wheel law (1.8) with "
                 "-Bdot damping", f"all angles within {err:.2f}°"])

    cfg = ChibisConfig(bdot_gain=DETUMBLE_GAIN, coils=(0, 1, 1),
                       wheel_gains=(0.02, 2e-4))
    r = simulate(cfg, initial_state(cfg, (20, 20, 20), (0.5, 0.5, 0.5)), T)
    err = np.degrees(np.abs(r.angles[-200:]).max())
    rows.append(["coil 1 failed", "no", "wheel law (1.8), -Bdot on two "
                 "coils", f"all angles within {err:.2f}°"])

    cfg = ChibisConfig(bdot_gain=DETUMBLE_GAIN, coils=(0, 1, 1))
    r = simulate(cfg, initial_state(cfg, (5, 5, 5), (10, 10, 10)), T)
    rate = np.degrees(np.abs(r.w_rel[-1]).max())
    rows.append(["coil 1 failed, all wheels failed (zero momentum)", "no",
                 "detumble with two coils only", f"rates down to "
                 f"{rate:.2f}°/s from 10°/s (no attitude hold)"])

    cfg = ChibisConfig(inertia=inertia, bdot_gain=dipole_scale_gain(
        orbit, 0.1), wheel_pairs=(0, 0, 0))
    r = simulate(cfg, initial_state(cfg, (10, 10, 10), (0.03, 0.03, 0.03)),
                 T)
    a, b, g = r.angles[-200:].T
    cos_tilt = -np.sin(a) * np.sin(b) * np.sin(g) + np.cos(a) * np.cos(g)
    line = np.degrees(np.arccos(np.abs(cos_tilt))).max()
    side = "inverted" if np.mean(cos_tilt) < 0 else "upright"
    rows.append(["all wheels failed", "yes", "gravity boom + -Bdot at "
                 "0.1 A·m² (from 10°, 0.03°/s ≈ 0.5 ω0)",
                 f"boom within {line:.1f}° of the vertical ({side}), "
                 "yaw free"])

    cfg = ChibisConfig(inertia=inertia, bdot_gain=dipole_scale_gain(
        orbit, 0.1), wheel_pairs=(0, 0, 0))
    r = simulate(cfg, initial_state(cfg, (2, 2, 2), (0.0, 0.0, 0.0),
                                    H0=(0, 0.05, 0)), T)
    late = r.angles[-200:]
    pitch_sim = np.degrees(late[:, 0].mean())
    pitch_eq = np.degrees(pitch_offset_eq37(orbit, inertia, 0.1))
    roll_yaw = np.degrees(np.abs(late[:, 1:]).max())
    rows.append(["only the pitch pair (held at 0.05 N·m·s)", "yes",
                 "boom + pitch wheel + -Bdot",
                 f"pitch {pitch_sim:.1f}° (eq. 3.7: {pitch_eq:.1f}°), "
                 f"roll/yaw within {roll_yaw:.1f}°"])
    return Table("Failure table: what remains → strategy (simulated)",
                 ["working actuators", "boom", "strategy", f"result after "
                  f"{n} orbits"], rows,
                 "The paper's failure table is a design output; each row "
                 "here is a run of the closed-loop model. Wheel-law gains "
                 "k_ω = 0.02 N·m·s, k_a = 2e-4 N·m (our choice).")


def run(ctx: StudyContext) -> Section:
    """Compute the study."""
    orbit = CircularOrbit()
    inertia = deployed_inertia(orbit)
    det, det_fig, slowest = detumble(ctx, orbit)
    pitch, pitch_fig, pitch_err = pitch_offset(ctx, orbit, inertia)
    bound = boundary(ctx, orbit, inertia)
    spin, tilt = spin_up(ctx, orbit, inertia)
    section = Section(
        "chibis", "5. Chibis-M: coil and wheel failures, gravity boom "
        "([2])",
        "Closed-loop simulations (CVODES) of the Chibis-M microsatellite on "
        "a 6850 km, 51.7° circular orbit with the direct-dipole field: "
        "-Bdot with a coil off, the gravity boom with a pitch wheel, the "
        "oscillation/rotation boundary, the pitch-wheel spin-up, and a "
        "failure table computed from simulations.",
        [det, pitch, bound, spin, failure_table(ctx, orbit, inertia)],
        [det_fig, pitch_fig])
    section.summary = [
        f"-Bdot with coil 1 off: axis {slowest} damps slowest (paper: "
        "the third)",
        f"eq. (3.7) pitch offset matched by the 3-D model within "
        f"{pitch_err:.2f}°",
        f"boom boundary: linear model {bound.rows[0][3]:.3f} A·m² (paper "
        f"0.35); undamped nonlinear {bound.rows[1][3]:.3f}–"
        f"{bound.rows[2][3]:.3f}",
        f"pitch-wheel spin-up: wheel axis {tilt:.1f}° from the orbit normal",
    ]
    return section
