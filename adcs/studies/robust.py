"""Study: what does robustness cost, and what does it buy?

A Monte Carlo of plants from the demo craft's uncertainty set
(`adcs.robust_mc`: principal moments ±20 %, products up to 5 % of the
largest moment, wheel axes tilted within ±0.5°), each flown, a 90° slew
and the hold after it, by the nominal stage-wise MPC and by the robust
multi-stage MPC over the nominal inertia and its 8 corners. The counts
of bound violations and broken loops, and the rate overshoot under a
body-rate bound (with a keep-out cone across the slew), say what
robustness buys; the settling time, the
energy and the step time what it costs.
"""

from __future__ import annotations

import numpy as np

from adcs.report import Figure, Section, StudyContext, Table
from adcs.robust_mc import CONTROLLERS, robust_mc_params, summarise

TITLE = "What does robustness cost, and what does it buy?"
#: Body-rate bound of the study's second Monte Carlo [rad/s] (below the
#: demo slew's unbounded peak rate).
RATE_BOUND = 0.04
#: Half-angle of the keep-out cone across the slew in the second Monte
#: Carlo [deg] (`adcs.robust_mc.slew_keep_out`).
KEEP_OUT_DEG = 20.0


def _figure(ds):
    import matplotlib.pyplot as plt

    from adcs.sweep.plots import line_styles

    fig, (a, b) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    styles = line_styles(2)
    for c, st in zip(CONTROLLERS, styles):
        e = np.asarray(ds[f"{c}_energy"], float)
        a.plot(np.sort(e), np.linspace(0, 1, e.size), color=st["color"],
               linestyle=st["linestyle"], label=f"{c} MPC")
        s = np.asarray(ds[f"{c}_settle_time"], float)
        b.plot(np.asarray(ds["draw"]), s, linestyle="none",
               marker=st["marker"], color=st["color"], label=f"{c} MPC")
    a.set_xlabel("energy ∑∫m² dt [N²·m²·s]")
    a.set_ylabel("fraction of the draws")
    b.set_xlabel("Monte Carlo draw")
    b.set_ylabel("settling time to 0.1° [s]")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return fig


def _table(ds, rate_max: float = 0.0) -> Table:
    nom, rob = summarise(ds)
    rows = []
    for label, key, scale in (
            ("loops broken", "failed", 1), ("momentum violations",
                                            "momentum", 1),
            ("torque violations", "torque", 1),
            ("rate violations", "rate", 1),
            ("keep-out violations", "keep_out", 1),
            ("rate overshoot, median [% of bound]", "rate_over_median",
             100.0),
            ("rate overshoot, largest [% of bound]", "rate_over_max",
             100.0),
            ("settled (0.1°)", "settled", 1),
            ("settling time, median [s]", "settle_median", 1.0),
            ("settling time, worst [s]", "settle_worst", 1.0),
            ("final error, largest [deg]", "final_error_max",
             float(np.rad2deg(1.0))),
            ("energy, median [N²·m²·s]", "energy_median", 1.0),
            ("step time, median [ms]", "step_time_median", 1e3)):
        a, b = getattr(nom, key) * scale, getattr(rob, key) * scale
        ratio = (b / a if isinstance(scale, float) and a > 0
                 else float("nan"))
        rows.append([label, a, b, "—" if np.isnan(ratio) else ratio])
    bound = (f"both bound the body rate at {rate_max:g} rad/s, and a rate "
             "violation is the plant's rate at a sample above it; both hold "
             f"a {KEEP_OUT_DEG:g}° keep-out cone across the slew, checked "
             "on the path between the samples"
             if rate_max > 0 else
             "no rate bound is set (dH/dt = m, so the wheel momentum and "
             "torque of every plant stay in the plans' bounds)")
    return Table(
        f"{nom.draws} draws, nominal against robust MPC"
        + (f", rate bound {rate_max:g} rad/s, keep-out cone"
           if rate_max > 0 else ""),
        ["", "nominal MPC", "robust MPC", "robust / nominal"], rows,
        "Both stage-wise RTI, horizon 20, 0.5 s, on the nominal craft; "
        "the robust MPC over the nominal inertia and the 8 corners of "
        "1 ± 0.2 (9 scenarios). A violation counts above 1e-6 of the "
        f"bound; {bound}. Step times on this machine, both in Python.",
        digits=4)


def run(ctx: StudyContext) -> Section:
    """Compute the study (2 draws of 30 s quick, 20 of 50 s full; the
    200-draw figures are `benchmarks.robust_mc`'s)."""
    draws, t_final = (2, 30.0) if ctx.quick else (20, 50.0)
    ds = ctx.sweep(*_case_and_params(draws, t_final))
    ds_rate = ctx.sweep(*_case_and_params(
        draws, t_final if ctx.quick else 60.0, RATE_BOUND))
    nom_r, rob_r = summarise(ds_rate)
    name = ctx.savefig(_figure(ds), "robust_mc.png")
    nom, rob = summarise(ds)
    section = Section(
        "robust", TITLE,
        "A robust (multi-stage) MPC plans one trajectory per scenario of "
        "the plant, all sharing the first command, and keeps every bound "
        "in every scenario. The question is whether that buys anything on "
        "plants drawn from the uncertainty set, and at what price in "
        "settling time, energy and computation. Each draw is a plant "
        "(principal moments ±20 %, products of inertia up to 5 % of the "
        "largest moment, wheel axes tilted within ±0.5°, the accuracy "
        "study's mounting model) flying a 90° slew about (1, 1, 0) from "
        f"rest and holding, {t_final:g} s, by both controllers. Without a "
        "rate bound no plant can break the wheel bounds; the second table "
        f"bounds the body rate at {RATE_BOUND:g} rad/s, where a plant "
        "lighter than planned turns faster than its plan, and both "
        f"controllers hold a {KEEP_OUT_DEG:g}° keep-out cone (a star "
        "tracker's Sun cone) that the unconstrained slew crosses.",
        [_table(ds), _table(ds_rate, RATE_BOUND)],
        [Figure(name, "Energy (distribution over the draws) and settling "
                "time of each draw")])
    section.summary = [
        f"{nom.draws} draws: broken loops {nom.failed} / {rob.failed}, "
        f"violations {nom.momentum + nom.torque + nom.rate} / "
        f"{rob.momentum + rob.torque + rob.rate} (nominal / robust)",
        f"robust / nominal: energy {rob.energy_median / nom.energy_median:.2f}"
        f", settling {rob.settle_median / nom.settle_median:.2f}, step "
        f"time {rob.step_time_median / nom.step_time_median:.1f}",
        f"rate bound {RATE_BOUND:g} rad/s: loops over it {nom_r.rate} / "
        f"{rob_r.rate}, median overshoot "
        f"{100 * nom_r.rate_over_median:.2f} % / "
        f"{100 * rob_r.rate_over_median:.2f} % of the bound, broken loops "
        f"{nom_r.failed} / {rob_r.failed}, loops into the keep-out cone "
        f"{nom_r.keep_out} / {rob_r.keep_out} (nominal / robust)"]
    return section


def _case_and_params(draws: int, t_final: float,
                     rate_max: float = 0.0) -> tuple:
    from adcs.robust_mc import robust_mc_case

    return robust_mc_case, robust_mc_params(
        draws, t_final=t_final, rate_max=rate_max,
        keep_out_deg=KEEP_OUT_DEG if rate_max > 0 else 0.0)
