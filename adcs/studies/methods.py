"""Study: which allocation law should my flight software run?

The control-allocation literature's methods (`allocation.methods`) beside
the exact QP, the way the literature compares them (Bodson 2002;
Petersen & Bodson 2006; Johansen & Fossen 2013): on the toolbox's wheel
arrays, nominal and with a wheel failed, the share of the attainable
torque set each reaches (by volume and over directions), the error it
leaves on attainable demands beyond its reach, its agreement with the
QP, its time per call in Python, and how it handles the wheel momentum
bound.
"""

from __future__ import annotations

import numpy as np

from allocation import (
    compare_methods,
    comparison_arrays,
    momentum_handling,
)
from allocation.method_comparison import sample_attainable
from allocation.methods import METHODS

from adcs.report import Figure, Section, StudyContext, Table

#: Arrays of the study (keys of `allocation.comparison_arrays`).
ARRAYS = ("pyramid", "pyramid, wheel 2 failed", "3 + 1", "six, cone")

#: Array of the error distribution and the momentum table.
MAIN = "pyramid"


def _coverage_table(results) -> Table:
    rows = []
    for name, rs in results.items():
        for r in rs:
            rows.append([name, r.method, 100 * r.volume_fraction,
                         100 * r.mean_direction_fraction,
                         100 * r.min_direction_fraction, r.miss_error_p50,
                         r.miss_error_p95, 100 * r.qp_agreement,
                         1e6 * r.time_per_call])
    n = next(iter(results.values()))[0].n_samples
    return Table(
        "Reach, miss error and agreement with the exact QP",
        ["array", "method", "volume %", "directions: mean %",
         "directions: least %", "miss error p50", "miss error p95",
         "= QP %", "µs/call (Python)"], rows,
        f"{n} demands uniform in each attainable torque set (fixed seed); "
        "reached: |A m − M| ≤ 1e-3 |M| within the wheels' limits. "
        "Directions: the method's radial reach over the set's. Miss error: "
        "relative torque error on the attainable demands it missed (— none "
        "missed). = QP: share of reached demands with the QP's torques "
        "(direction-preserving QP for direct allocation, least-squares QP "
        "otherwise). C timings: benchmarks/alloc_methods.py and the docs.",
        digits=4)


def _momentum_table(rows) -> Table:
    out = [[r.method, 100 * r.violation_share,
            100 * max(r.worst_excess, 0.0), 100 * r.bounded_violation_share,
            100 * r.reach_share, r.miss_error_p95] for r in rows]
    return Table(
        f"Momentum bound, {MAIN} (dt = 0.5 s)",
        ["method", "limits only: steps beyond h_max %",
         "worst excess [% h_max]", "momentum in the box: beyond h_max %",
         "momentum in the box: reach %", "miss error p95"], out,
        f"{rows[0].n_cases} momentum states with wheels near their bound "
        f"({rows[0].n_exact} demands inside the momentum-limited set). "
        "Limits only: the method is told ±m_max; the exact QP keeps "
        "|h + m dt| ≤ h_max as a constraint. In the box: lo/hi from the "
        "momentum (the QP's own box); reach: share of the demands the QP "
        "meets exactly that the method meets.", digits=4)


def _coverage_figure(results):
    import matplotlib.pyplot as plt

    names = [r.method for r in next(iter(results.values()))]
    fig, ax = plt.subplots(figsize=(11.0, 4.4))
    width = 0.8 / len(results)
    x = np.arange(len(names))
    for k, (arr, rs) in enumerate(results.items()):
        ax.bar(x + k * width, [100 * r.volume_fraction for r in rs], width,
               label=arr, color=f"C{k}")
    ax.set_xticks(x + 0.4 - width / 2, names, rotation=25, ha="right",
                  fontsize=8)
    ax.set_ylabel("attainable set reached, by volume [%]")
    ax.set_ylim(0, 118)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=len(results), loc="upper center")
    return fig


def _error_figure(errors: dict[str, np.ndarray]):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9.0, 4.4))
    for k, (name, e) in enumerate(errors.items()):
        e = np.sort(np.maximum(e, 1e-16))
        ax.step(e, np.arange(1, e.size + 1) / e.size, where="post",
                label=name, color=f"C{k}", ls="-" if k < 10 else "--")
    ax.set_xscale("log")
    ax.set_xlim(1e-16, 2.0)
    ax.set_xlabel("relative torque error |A m − M| / |M| (floor 1e-16)")
    ax.set_ylabel("share of attainable demands")
    ax.set_title(f"{MAIN}: demands uniform in the attainable set")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fig


def _momentum_figure(rows):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9.0, 4.0))
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [100 * r.violation_share for r in rows], 0.4,
           label="limits only: steps leaving a wheel beyond h_max")
    ax.bar(x + 0.2, [100 * r.reach_share for r in rows], 0.4,
           label="momentum in the box: demands met of the QP's")
    ax.set_xticks(x, [r.method for r in rows], rotation=25, ha="right",
                  fontsize=8)
    ax.set_ylabel("%")
    ax.set_ylim(0, 125)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def demand_errors(array, n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Relative torque error (n,) [1] of each method on attainable demands.

    The demands are `sample_attainable` (uniform, seed ``seed``).
    """
    D = sample_attainable(array, n, seed)
    A = array.working_axes
    nM = np.linalg.norm(D, axis=1)
    return {k: np.linalg.norm(np.array([f(array, M) for M in D]) @ A.T - D,
                              axis=1) / nM for k, f in METHODS.items()}


def run(ctx: StudyContext) -> Section:
    """Compute the study."""
    samples, dirs, cases = (300, 20, 120) if ctx.quick else (2000, 100, 400)
    arrays = comparison_arrays()
    results = {k: compare_methods(arrays[k], n_samples=samples,
                                  n_directions=dirs) for k in ARRAYS}
    errors = demand_errors(arrays[MAIN], samples)
    mom = momentum_handling(arrays[MAIN], dt=0.5, n_cases=cases)
    figs = [
        Figure(ctx.savefig(_coverage_figure(results), "methods_reach.png"),
               "Share of the attainable torque set each method reaches, "
               "by volume, per array"),
        Figure(ctx.savefig(_error_figure(errors), "methods_errors.png"),
               "Distribution of the relative torque error on attainable "
               "demands (a curve at the left edge: exact; coinciding "
               "methods draw one curve)"),
        Figure(ctx.savefig(_momentum_figure(mom), "methods_momentum.png"),
               "Momentum bound: violations when told the torque limits "
               "only, reach with the momentum in the box")]
    section = Section(
        "methods", "Which allocation law should my flight software run?",
        "The literature's allocation methods beside the exact QP on the "
        "pyramid, the pyramid with wheel 2 failed, 3 + 1 and six wheels on "
        "a cone. A method that reaches less than the whole attainable set "
        "gives up torque the wheels have; one that ignores the momentum "
        "bound drives wheels past it.",
        [_coverage_table(results), _momentum_table(mom)], figs)
    section.summary = []
    for k, rs in results.items():
        full = [r.method for r in rs if r.volume_fraction >= 0.999
                and not r.method.startswith("exact")]
        section.summary.append(
            f"{k}: the whole set reached by {', '.join(full) or 'none'}")
    section.summary.append(
        f"{MAIN}, momentum: told the limits only, "
        f"{100 * min(r.violation_share for r in mom[1:]):.0f}–"
        f"{100 * max(r.violation_share for r in mom[1:]):.0f} % of steps "
        "leave a wheel beyond h_max (the QP: 0)")
    return section
