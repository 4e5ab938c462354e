"""Closed loops of the test driver from many initial states.

By default the driver of an export (``main.c``, and the bare-metal one of
a Cortex-M target, `ocp.codegen.target`) flies each exported MPC step in
one closed loop, the demo slew (`ocp.codegen.checks.loop_plan`).
`write_loop_starts` rewrites the drivers of an export to fly each MPC
step once per row of a ``(K, n_x)`` array of initial states instead, all
to one target attitude: the states are a static array of the driver (no
heap), the loop is the same (the MPC step, the generated RK4 as plant,
the solution fed back as warm start, a cold first step) and prints one
``STEPS``/``TIME``/``STATE``/``LOOP`` line per start, named
``closed_loop:<name>#<k>``, which `ocp.codegen.run_driver` and
`ocp.codegen.target.run_target` parse as any other loop (each is checked:
final error and bounds, `ocp.codegen.checks.LOOP_TOLERANCES`). It is what
`benchmarks.mpc_worst_case` flies on the emulated Cortex-M7: a subset of
the host's Monte Carlo from the same random states, counted in
instructions per step.

Usage::

    res = export_c(out, "demo", mpc_variants=("mpc_cond_rti_step",),
                   target="cortex-m7")          # not built yet
    res = write_loop_starts(res, starts, steps=120)
    times = run_target(build_target(res))
    times["closed_loop:mpc_cond_rti_step#0"]["steps"]   # instructions
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from .checks import check_loop_steps, plan_length
from .result import ExportResult

__all__ = ["loop_key", "loop_start_source", "write_loop_starts"]

#: Target attitude of the loops unless given: the identity quaternion
#: (scalar first), as `benchmarks.mpc_worst_case`.
IDENTITY = (1.0, 0.0, 0.0, 0.0)


def loop_key(name: str, k: int) -> str:
    """Key of start ``k``'s loop of MPC step ``name`` in the driver's
    parsed figures (`ocp.codegen.run_driver`, `run_target`)."""
    return f"closed_loop:{name}#{k}"


def _check_starts(starts: ArrayLike, qf: ArrayLike, nx: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``(starts (K, nx), qf (4,))`` as finite float arrays, or raise."""
    x = np.asarray(starts, dtype=float)
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] != nx:
        raise InvalidValueError(
            f"starts must be an array (K >= 1, {nx}), got shape {x.shape}")
    q = np.asarray(qf, dtype=float).ravel()
    if q.size != 4:
        raise InvalidValueError(f"qf must have 4 entries, got {q.size}")
    if not (np.isfinite(x).all() and np.isfinite(q).all()):
        raise InvalidValueError("starts and qf must be finite")
    return x, q


def loop_start_source(fns: dict[str, ca.Function], starts: np.ndarray,
                      qf: np.ndarray, loop: dict[str, Any],
                      precision: str = "double") -> tuple[str, str]:
    """C text of the multi-start loops: ``(declarations, calls)``.

    ``declarations``: the static arrays of the starts (``K × n_x``
    reals), the target quaternion and the loops' names; ``calls``: the
    lines of ``main`` calling ``closed_loop`` (`templates/closed_loop.c`)
    once per start for each MPC step of ``fns``, with ``loop``'s length
    ``steps``, sample time ``dt`` [s] and tolerances (`loop_plan`:
    ``final_error_tol`` [rad], ``violation_tol``).
    """
    from .driver import _c_array

    suffix = "f" if precision == "single" else ""
    k, nx = starts.shape
    decl = [_c_array("loop_starts", starts, suffix),
            _c_array("loop_target", qf, suffix)]
    calls = []
    for name, f in fns.items():
        if not name.startswith("mpc"):
            continue
        names = ", ".join(f'"{name}#{j}"' for j in range(k))
        decl.append(f"static const char* const {name}_loop_names[{k}] = "
                    f"{{{names}}};")
        calls.append(
            f"  {{ int s; for (s = 0; s < {k}; ++s)\n"
            f"    bad |= closed_loop({name}_loop_names[s], {name}, "
            f"{name}_work, {name}_checkout, {name}_release, loop_starts + "
            f"s * {nx}, loop_target, {f.nnz_in(0)}, {f.nnz_in(3)}, "
            f"{f.nnz_in(5)}, {f.nnz_out(0)}, {plan_length(f, loop)}, "
            f"{loop['dt']!r}, "
            f"{loop['steps']}, {math.degrees(loop['final_error_tol'])!r}, "
            f"{float(loop['violation_tol'])!r}); }}")
    return "\n".join(decl), "\n".join(calls)


def write_loop_starts(res: ExportResult, starts: ArrayLike,
                      qf: ArrayLike = IDENTITY, *, steps: int | None = None,
                      repeats: int = 10) -> ExportResult:
    """Rewrite an export's drivers to fly every MPC step from each start.

    Parameters
    ----------
    res : ExportResult
        An export with at least one MPC step (`export_c`; build it
        afterwards: `ocp.codegen.build_exported` for the host driver
        ``main.c``, `ocp.codegen.target.build_target` for a Cortex-M
        export's ``main_cortex_m.c``, which is rewritten too).
    starts : array_like (K, n_x)
        Initial states of the loops (attitude quaternion scalar first,
        body rates [rad/s], wheel momenta [N·m·s] or speeds as the
        model's state).
    qf : array_like (4,)
        Target attitude of every loop (default: the identity).
    steps : int, optional
        Steps of each loop (default: the export's, ``extras
        ["closed_loop"]["steps"]``); each step lasts the export's ``dt``.
    repeats : int
        Calls per function of the sample-input timings the drivers make
        first (a Cortex-M driver: a tenth, at least 3).

    Returns
    -------
    ExportResult
        ``res`` with ``extras["loop_starts"]`` (the starts), ``extras
        ["loop_target"]`` and ``extras["closed_loop"]`` of the new length;
        not built (``executable`` None).

    Raises
    ------
    InvalidValueError
        No MPC step, ``starts`` not (K, n_x) finite, ``qf`` not 4 finite
        numbers, ``steps`` not an integer >= 1 or ``repeats`` < 1.
    """
    from .driver import _driver_source
    from .target import CORES, TARGET_DRIVER, target_head

    mpc = [n for n in res.functions if n.startswith("mpc")]
    if not mpc:
        raise InvalidValueError("the export has no MPC step to fly")
    check_loop_steps(steps)
    if int(repeats) < 1:
        raise InvalidValueError(f"repeats must be >= 1, got {repeats!r}")
    x, q = _check_starts(starts, qf, res.functions[mpc[0]].nnz_in(0))
    loop = dict(res.extras["closed_loop"])
    if steps is not None:
        loop.update(steps=int(steps), seconds=int(steps) * loop["dt"])
    precision = res.extras.get("precision", "double")
    kw = dict(precision=precision, loop=loop, starts=(x, q))
    res.driver.write_text(_driver_source(
        res.functions, res.samples, int(repeats), None, loop["dt"], **kw))
    target = res.extras.get("target", "host")
    if target in CORES:
        (res.out_dir / TARGET_DRIVER).write_text(_driver_source(
            res.functions, res.samples, max(int(repeats) // 10, 3), None,
            loop["dt"], head=target_head(), **kw))
    extras = {**res.extras, "closed_loop": loop, "loop_starts": x,
              "loop_target": q}
    return ExportResult(**{**res.__dict__, "executable": None,
                           "shared_library": None, "extras": extras})
