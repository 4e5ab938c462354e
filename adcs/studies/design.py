"""Study: which array should I fly? The trade of nominal against failure.

For 4, 5 and 6 wheels of unit capacity, the Pareto front of the nominal
inscribed radius of the momentum envelope against its worst radius after
any single wheel fails (`allocation.trade_curve`, every point certified
by the envelope code), beside the reference layouts.
"""

from __future__ import annotations

import math

import numpy as np

from allocation import certify_layout, reference_layouts, trade_curve

from adcs.report import Figure, Section, StudyContext, Table, verdict

#: Wheel counts of the study.
WHEELS = (4, 5, 6)


def _front_figure(curves, refs):
    import matplotlib.pyplot as plt

    fig, (ax, zoom) = plt.subplots(1, 2, figsize=(11.0, 4.6))
    for n, curve in curves.items():
        for a in (ax, zoom) if n == 5 else (ax,):
            color = f"C{n - WHEELS[0]}"
            a.plot(curve.worst_failure_radius, curve.radius, "o-", ms=4,
                   color=color, label=f"{n} wheels: Pareto front")
            a.plot(curve.worst_failure_radius[[0, -1]],
                   curve.radius[[0, -1]], "s", ms=8, mfc="none",
                   color=color)
    for i, (name, (axes, _, _)) in enumerate(refs.items()):
        nom, fail = certify_layout(axes)
        for a in (ax, zoom) if name.startswith("5") else (ax,):
            a.plot(fail, nom, "x", ms=7, color="k")
            a.annotate(name.split(" (")[0], (fail, nom), fontsize=7,
                       textcoords="offset points",
                       xytext=(5, -10 if i % 2 == 0 else 6))
    ax.set_title("Nominal against single-failure radius, unit wheels")
    zoom.set_title("5 wheels: the trade")
    for a in (ax, zoom):
        a.set_xlabel("worst inscribed radius, one wheel failed [h_max]")
        a.set_ylabel("nominal inscribed radius [h_max]")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    return fig


def _reference_table(refs) -> Table:
    rows = []
    for name, (axes, nominal, failed) in refs.items():
        nom, fail = certify_layout(axes)
        for what, ref, ours in (("nominal", nominal, nom),
                                ("one failed", failed, fail)):
            rows.append([name, what, ref, ours,
                         verdict(None if math.isnan(ref) else ref, ours,
                                 tol=1e-6)])
    return Table("Reference layouts, radii by the envelope code",
                 ["layout", "radius", "reference", "ours", "verdict"], rows,
                 "Unit capacity per wheel; the reference values from the "
                 "facet formula (— where the layout is not the reference "
                 "of that radius), ours from the exact envelope code.",
                 digits=7)


def _front_table(curves) -> Table:
    rows = []
    for n, curve in curves.items():
        for f, r, axes in zip(curve.worst_failure_radius, curve.radius,
                              curve.axes):
            z = np.degrees(np.arccos(np.clip(
                np.abs(axes.T @ axes)[np.triu_indices(n, 1)], 0, 1)))
            rows.append([n, float(f), float(r), float(z.min())])
    return Table("The Pareto fronts", ["wheels", "worst radius, one failed",
                                        "nominal radius",
                                        "smallest angle between axes [deg]"],
                 rows, "Each point maximises the nominal radius at a failure "
                 "radius at least its level (an epsilon-constraint), "
                 "certified by the envelope code; dominated points dropped.",
                 digits=7)


def run(ctx: StudyContext) -> Section:
    """Compute the study."""
    points, starts = (5, 4) if ctx.quick else (13, 20)
    curves = {n: trade_curve(n, points=points, starts=starts)
              for n in WHEELS}
    refs = reference_layouts()
    name = ctx.savefig(_front_figure(curves, refs), "design_fronts.png")
    five = curves[5]
    section = Section(
        "design", "Which array should I fly?",
        "The inscribed radius of the momentum envelope is the momentum "
        "available in every direction. For each wheel count the front "
        "trades it, nominal, against its worst value after one wheel "
        "fails. With 4 wheels (the tetrahedron) and 6 (the icosahedral "
        "axes) one layout is best on both counts, so the front is one "
        "point; with 5 wheels the two optima differ and the front is a "
        "real choice.",
        [_reference_table(refs), _front_table(curves)],
        [Figure(name, "Pareto fronts (squares: the two optima) and the "
                "reference layouts (crosses)")])
    section.summary = [
        f"{n} wheels: nominal {c.nominal_optimum:.6f}, one failed "
        f"{c.failure_optimum:.6f}, {c.n_points} front point(s)"
        for n, c in curves.items()]
    section.summary.append(
        f"5 wheels: from ({five.worst_failure_radius[0]:.4f}, "
        f"{five.radius[0]:.4f}) to ({five.worst_failure_radius[-1]:.4f}, "
        f"{five.radius[-1]:.4f}) (failed, nominal)")
    return section
