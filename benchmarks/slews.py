"""Solve times of the slew NLPs per variant: solver, start, JIT (table).

Run from the repository root as ``python -m benchmarks.slews [--quick]``
(as a module, so that this file does not shadow a package). Each figure is
the median over ``--repeats`` solves of the wall time of the solver call,
for a time-optimal slew on N intervals:

* ``bw``: Bilimoria & Wie (1993), J = I, |u_i| <= 1, 180° about x (the
  torque-box model, 7 states);
* ``meteor``: the assumed Meteor-M No. 2 inertia with its wheel pyramid
  (m_max 0.2 N·m, h_max 25 N·m·s), 90° about (1, 1, 1) (11 states).

The built solver is cached per problem shape, so the first call of each
variant builds it (``build``, shown apart; with ``jit`` it includes the C
compile unless the library is already in the disk cache) and the repeats
time the solver alone. The baseline, measured in the same run, is the
previous default: IPOPT from the perturbed eigenaxis guess. ``coarse``
solves on N/5 intervals first (its time is included). The target is a
100-interval time-optimal slew under 0.2 s.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
from dataclasses import dataclass

import numpy as np

from ocp import (
    available_nlp_solvers,
    meteor_m_spacecraft,
    min_energy_slew,
    quat_from_axis_angle,
    slews,
    time_optimal_slew,
)


@dataclass(frozen=True)
class Case:
    """One benchmark problem."""

    name: str
    kwargs: dict


@dataclass(frozen=True)
class Variant:
    """One solver configuration."""

    label: str
    solver: str = "ipopt"
    transcription: str = "multiple_shooting"
    expand: bool = True
    initial_guess: str | None = None
    jit: bool = False


def cases() -> list[Case]:
    """Return the two benchmark problems of the module docstring."""
    J, arr = meteor_m_spacecraft()
    return [
        Case("bw", dict(inertia=np.eye(3), q0=[1, 0, 0, 0],
                        qf=[0, 1, 0, 0], torque_max=1.0)),
        Case("meteor", dict(inertia=J, q0=[1, 0, 0, 0],
                            qf=quat_from_axis_angle([1, 1, 1],
                                                    np.deg2rad(90.0)),
                            wheels=arr)),
    ]


def variants(solvers: list[str], jit: bool,
             collocation: bool) -> list[Variant]:
    """Variants to measure: the baseline first."""
    out = [Variant("ipopt, perturbed guess (baseline)",
                   initial_guess="perturbed_eigenaxis"),
           Variant("ipopt, coarse start (default)")]
    if "fatrop" in solvers:
        out.append(Variant("fatrop", solver="fatrop"))
    if jit:
        out.append(Variant("ipopt, coarse start, jit", jit=True))
        if "fatrop" in solvers:
            out.append(Variant("fatrop, jit", solver="fatrop", jit=True))
    if "sqpmethod" in solvers:
        out.append(Variant("sqpmethod", solver="sqpmethod"))
    out.append(Variant("ipopt, coarse start, MX graph", expand=False))
    if collocation:
        out.append(Variant("ipopt, collocation, coarse start",
                           transcription="collocation"))
    return out


def _options(solver: str, max_iter: int) -> dict:
    if solver in ("ipopt", "fatrop"):
        return {solver: {"max_iter": max_iter}}
    return {"max_iter": max_iter}


def run(case: Case, transcription: str, solver: str, expand: bool,
        N: int, repeats: int, max_iter: int,
        initial_guess: str | None = None, jit: bool = False) -> dict:
    """Median solve time [s] of one configuration and its first build [s].

    The solver cache is cleared first, so the first call builds the NLP.
    """
    slews.clear_solver_cache()
    solve, build = [], []
    r = None
    for _ in range(repeats + 1):
        r = time_optimal_slew(**case.kwargs, N=N,
                              transcription=transcription, solver=solver,
                              expand=expand, verify=False, jit=jit,
                              initial_guess=initial_guess,
                              solver_options=_options(solver, max_iter))
        solve.append(r.solve_time)
        build.append(r.extras["build_time"])
    timed = solve[1:] if repeats > 0 else solve
    its = r.iterations
    if "coarse_iterations" in r.extras:
        its = f"{r.extras['coarse_iterations']}+{r.iterations}"
    return {"case": case.name, "transcription": transcription,
            "solver": solver, "expand": expand, "N": N,
            "initial_guess": r.extras["initial_guess"], "jit": jit,
            "solve": statistics.median(timed), "build": build[0],
            "T": r.T, "iterations": its, "status": r.status}


def energy_rows(N: int, repeats: int, solvers: list[str]) -> list[dict]:
    """Minimum-energy Meteor-M slew (90° in 250 s) per NLP solver.

    The solvers that stall on time-optimal slews (sqpmethod) converge
    here; the first solve builds, the median is over the repeats.
    """
    J, arr = meteor_m_spacecraft()
    qf = quat_from_axis_angle([1, 1, 1], np.deg2rad(90.0))
    out = []
    for solver in solvers:
        slews.clear_solver_cache()
        times = []
        for _ in range(repeats + 1):
            r = min_energy_slew(J, [1, 0, 0, 0], qf, wheels=arr, T=250.0,
                                N=N, solver=solver, verify=False)
            times.append(r.solve_time)
        out.append({"solver": solver, "N": N,
                    "solve": statistics.median(times[1:] or times),
                    "iterations": r.iterations, "energy": r.energy,
                    "status": r.status})
    return out


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the benchmark and print a markdown table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true",
                   help="N = 30, one repeat, no JIT nor collocation "
                        "(CI smoke run)")
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--N", type=int, default=100)
    avail = available_nlp_solvers()
    p.add_argument("--solvers",
                   default=",".join(s for s in ("ipopt", "fatrop")
                                    if s in avail),
                   help=f"comma-separated NLP solvers, of {avail} "
                        "(sqpmethod stalls on time-optimal slews)")
    p.add_argument("--no-jit", action="store_true",
                   help="skip the compiled (jit) variants")
    p.add_argument("--collocation", action="store_true",
                   help="add the collocation transcription")
    p.add_argument("--max-iter", type=int, default=300,
                   help="iteration cap per solve (sqpmethod is slow)")
    a = p.parse_args(argv)
    N, repeats = (30, 1) if a.quick else (a.N, a.repeats)
    jit = not (a.quick or a.no_jit) and any(
        shutil.which(c) for c in ("gcc", "cc", "clang"))
    solvers = ["ipopt"] if a.quick else a.solvers.split(",")
    results = []
    print("| problem | variant | N | median solve [s] | build [s] | "
          "iterations | T | status |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for case in cases():
        for v in variants(solvers, jit, a.collocation and not a.quick):
            res = run(case, v.transcription, v.solver, v.expand, N,
                      repeats, a.max_iter, initial_guess=v.initial_guess,
                      jit=v.jit)
            res["variant"] = v.label
            results.append(res)
            print(f"| {case.name} | {v.label} | {N} | {res['solve']:.3f} "
                  f"| {res['build']:.2f} | {res['iterations']} | "
                  f"{res['T']:.10g} | {res['status']} |", flush=True)
    # sqpmethod with qpOASES takes minutes at N = 100: qrqp only
    e_solvers = [x for x in ("ipopt", "fatrop", "sqpmethod:qrqp")
                 if x in avail and (not a.quick or x == "ipopt")]
    print("\n| minimum energy, Meteor-M 90° in 250 s | N | median solve "
          "[s] | ratio to ipopt | iterations | Σ∫m² [N²·m²·s] | status |")
    print("|---|---:|---:|---:|---:|---:|---|")
    rows = energy_rows(N, repeats, e_solvers)
    base = rows[0]["solve"]
    for r in rows:
        print(f"| {r['solver']} | {r['N']} | {r['solve']:.3f} | "
              f"{r['solve'] / base:.2f} | {r['iterations']} | "
              f"{r['energy']:.8g} | {r['status']} |", flush=True)
    return results + rows


if __name__ == "__main__":
    main()
