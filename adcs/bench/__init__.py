"""Optimizer comparison: every installed backend, each answer certified.

Three problems, each solved by every backend installed here and checked
against an exact reference, so that a fast wrong answer shows as wrong:

* ``wheels``: the bounded 4-wheel allocation QP (`allocation.QPAllocator`,
  every name of `allocation.available_solvers`) on attainable demands
  ``M = A m`` with ``m`` near the torque box corners (bounds active);
* ``thrusters``: the duty-cycle QP (`thrusters.DutyCycleAllocator`,
  weighted tracking, momentum box) on random cycles;
* control row ``osqp@loose`` (OSQP at eps 1e-3, no polishing) in both
  QPs: its loose points go through the shared QP layer's optimality
  certificate (`adcs_common.qp.certify`), which polishes them on their
  active set: the row must show no wrong answer;
* ``methods`` (on request): the literature's allocation methods
  (`allocation.methods`, names ``method:pinv`` ... ``method:direct``) on
  the ``wheels`` demands, timed in Python and compared with the exact QP;
* ``slew``: the MPC slew NLP (`ocp.mpc.AttitudeMPC`, horizon 20) from rest,
  cold-started, by every NLP solver name.

QP answers are certified by their KKT residuals (primal feasibility, and
stationarity with sign-correct multipliers found by bounded least
squares) and compared with a reference backend's point; NLP answers are
compared with IPOPT at ``tol = 1e-12``.

Each backend has a time budget per problem (`run_bench`'s ``budget``): a
slow one is cut short and marked "too slow" rather than waited for.
"""

from __future__ import annotations

import os

from typing import Any, Sequence

from adcs_common.exceptions import InvalidValueError
from adcs_common.interrupts import interrupted
from adcs_common.paths import output_folder
from ocp.spacecraft import load_spacecraft
from adcs.provenance import provenance

from .core import (
    CONTROLS,
    DEFAULT_PROBLEMS,
    PROBLEMS,
    TOL,
    BenchRow,
    Progress,
    _check_backends,
    kkt_residual,
    known_backends,
)
from .output import format_table, plot, to_frame, write_json
from .methods import METHOD_NAMES, bench_methods
from .problems import BUDGET, bench_slew, bench_thrusters, bench_wheels

__all__ = [
    "BUDGET",
    "BenchRow",
    "CONTROLS",
    "PROBLEMS",
    "Progress",
    "TOL",
    "DEFAULT_PROBLEMS",
    "METHOD_NAMES",
    "bench_methods",
    "bench_slew",
    "bench_thrusters",
    "bench_wheels",
    "format_table",
    "kkt_residual",
    "known_backends",
    "run_bench",
    "to_frame",
]


def run_bench(out_dir: str | os.PathLike[str] | None = None, *,
              problems: Sequence[str] = DEFAULT_PROBLEMS,
              backends: Sequence[str] | None = None,
              repetitions: int | None = None, quick: bool = False,
              progress: bool = True, seed: int = 0,
              spacecraft: Any | None = None, budget: float | None = None
              ) -> list[BenchRow]:
    """Run the benchmark, print the table, write JSON and PNG.

    Parameters
    ----------
    out_dir : str or pathlib.Path, optional
        Folder for ``bench.json`` and ``bench.png`` (nothing written when
        None).
    problems : sequence of str
        Subset of `PROBLEMS` (default `DEFAULT_PROBLEMS`; ``"methods"``
        adds the literature's allocation methods).
    backends : sequence of str, optional
        Backend names (default every installed one); names a problem does
        not know are reported as not available for that problem.
    repetitions : int, optional
        Solves per backend for the QPs (default 200, 20 with ``quick``);
        the slew uses a fifth of it (at least 2).
    quick : bool
        Small settings.
    progress : bool
        Show one progress bar with ETA on stderr.
    seed : int
        Seed of the random problems.
    spacecraft : ocp.spacecraft.Spacecraft, str or pathlib.Path, optional
        The craft whose wheels, thrusters and inertia are benchmarked (a
        catalogue name or a TOML file); default: the pyramid, the
        six-thruster unit and the ``demo`` craft of earlier figures.
    budget : float, optional
        Seconds each backend may spend on one problem (default 8, 2 with
        ``quick``); a backend cut short is marked "too slow" in its note.

    Returns
    -------
    list of BenchRow

    Raises
    ------
    InvalidValueError
        Unknown problem or bad repetitions.
    """
    probs = list(problems)
    bad = [p for p in probs if p not in PROBLEMS]
    if bad or not probs:
        raise InvalidValueError(
            f"problems must be among {', '.join(PROBLEMS)}, got "
            f"{bad or probs}")
    reps = repetitions if repetitions is not None else (20 if quick
                                                        else 200)
    if int(reps) < 1:
        raise InvalidValueError(f"repetitions must be >= 1, got {reps!r}")
    reps = int(reps)
    _check_backends(backends)
    if spacecraft is not None:
        spacecraft = load_spacecraft(spacecraft)
    budget = (2.0 if quick else BUDGET) if budget is None else float(
        budget)
    if not budget > 0:
        raise InvalidValueError(f"budget must be positive, got {budget!r}")
    out = None if out_dir is None else output_folder(out_dir, "out")
    bar = Progress(progress)
    rows: list[BenchRow] = []
    stopped = None
    try:
        if "wheels" in probs:
            stopped = "wheels"
            rows += bench_wheels(backends, reps, seed, bar, spacecraft,
                                 budget)
        if "thrusters" in probs:
            stopped = "thrusters"
            rows += bench_thrusters(backends, reps, seed, bar, spacecraft,
                                    budget)
        if "methods" in probs:
            stopped = "methods"
            rows += bench_methods(backends, reps, seed, bar, spacecraft,
                                  budget)
        if "slew" in probs:
            stopped = "slew"
            rows += bench_slew(backends, max(reps // 5, 2) if not quick
                               else 2, bar, quick, spacecraft, budget)
        stopped = None
    except BaseException as exc:       # Ctrl-C, however it surfaced
        if not interrupted(exc):
            raise
        # the rows of the backends the problem had finished
        rows += getattr(exc, "partial", None) or []
    finally:
        bar.close()
    print(format_table(rows))
    if out is not None:
        write_json(out / "bench.json", rows, {
            "repetitions": reps, "budget_s": budget,
            "interrupted_during": stopped,
            "provenance": dict(provenance())})
        if rows:
            plot(rows, out / "bench.png")
        print(f"wrote {out / 'bench.json'}" + (
            f" and {out / 'bench.png'}" if rows else ""))
    if stopped is not None:
        raise KeyboardInterrupt(
            f"benchmark stopped during {stopped!r}; {len(rows)} finished "
            "rows kept" + (f" in {out / 'bench.json'}" if out else ""))
    return rows
