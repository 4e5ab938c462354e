"""Solve times of the slew NLPs per transcription and solver (table).

Run from the repository root as ``python -m benchmarks.slews [--quick]``
(as a module, so that this file does not shadow a package). Each figure is
the median over ``--repeats`` solves of the wall time of the solver call
(the NLP is built anew for each solve; its build time is shown apart),
for a time-optimal slew on N intervals:

* ``bw``: Bilimoria & Wie (1993), J = I, |u_i| <= 1, 180° about x (the
  torque-box model, 7 states);
* ``meteor``: the assumed Meteor-M No. 2 inertia with its wheel pyramid
  (m_max 0.2 N·m, h_max 25 N·m·s), 90° about (1, 1, 1) (11 states).

``expand=True`` builds the NLP as SX (what CasADi's ``expand`` gives);
``expand=False`` keeps an MX graph of mapped Function calls. The target
is a 100-interval time-optimal slew under 0.2 s.
"""

from __future__ import annotations

import argparse
import statistics
from dataclasses import dataclass

import numpy as np

from ocp import (
    available_nlp_solvers,
    meteor_m_spacecraft,
    quat_from_axis_angle,
    time_optimal_slew,
)


@dataclass(frozen=True)
class Case:
    """One benchmark problem."""

    name: str
    kwargs: dict


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


def run(case: Case, transcription: str, solver: str, expand: bool,
        N: int, repeats: int, max_iter: int) -> dict:
    """Median solve and build times [s] of one configuration."""
    solve, build = [], []
    r = None
    opts = ({"ipopt": {"max_iter": max_iter}} if solver == "ipopt"
            else {"max_iter": max_iter})
    for _ in range(repeats):
        r = time_optimal_slew(**case.kwargs, N=N,
                              transcription=transcription, solver=solver,
                              expand=expand, verify=False,
                              solver_options=opts)
        solve.append(r.solve_time)
        build.append(r.extras["build_time"])
    return {"case": case.name, "transcription": transcription,
            "solver": solver, "expand": expand, "N": N,
            "solve": statistics.median(solve),
            "build": statistics.median(build), "T": r.T,
            "iterations": r.iterations, "status": r.status}


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the benchmark and print a markdown table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true",
                   help="N = 30, one repeat, ipopt only (CI smoke run)")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--N", type=int, default=100)
    p.add_argument("--solvers", default="ipopt",
                   help="comma-separated NLP solvers, of "
                        f"{available_nlp_solvers()} (sqpmethod stalls on "
                        "time-optimal slews)")
    p.add_argument("--max-iter", type=int, default=300,
                   help="iteration cap per solve (sqpmethod is slow)")
    a = p.parse_args(argv)
    N, repeats = (30, 1) if a.quick else (a.N, a.repeats)
    solvers = ["ipopt"] if a.quick else a.solvers.split(",")
    results = []
    print("| problem | transcription | solver | expand | N | median solve "
          "[s] | build [s] | iterations | T | status |")
    print("|---|---|---|---|---:|---:|---:|---:|---:|---|")
    for case in cases():
        for transcription in ("multiple_shooting", "collocation"):
            for solver in solvers:
                for expand in (True, False):
                    res = run(case, transcription, solver, expand, N,
                              repeats, a.max_iter)
                    results.append(res)
                    print(f"| {res['case']} | {transcription} | {solver} | "
                          f"{expand} | {N} | {res['solve']:.3f} | "
                          f"{res['build']:.2f} | {res['iterations']} | "
                          f"{res['T']:.4f} | {res['status']} |",
                          flush=True)
    return results


if __name__ == "__main__":
    main()
