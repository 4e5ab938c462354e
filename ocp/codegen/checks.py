"""The driver's closed-loop check: its length, its tolerances, its verdict.

The test driver of an export (``main.c``, and the bare-metal driver of a
Cortex-M target) flies each exported MPC step in a closed loop on the
generated RK4 (`ocp.codegen.driver`): the demo slew, 90° about (1, 1, 0)
from rest. `loop_plan` sizes that loop from the craft:
`LOOP_SLEW_FACTOR` times the eigenaxis slew time of the slew under the
craft's wheels and rate limit (`ocp.guidance.eigenaxis_slew`), so a large
craft gets a loop long enough to arrive. The driver then checks each
loop (`LOOP_TOLERANCES`): the final error angle within tolerance, no
applied step beyond a bound, nothing NaN, every step returning 0. A loop
that fails prints a ``FAIL`` line and the driver exits 1;
`ocp.codegen.run_driver` and `ocp.codegen.target.run_target` then raise
`DriverCheckError`, which carries the driver's figures.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from adcs_common.exceptions import AdcsError, InvalidValueError

__all__ = [
    "DriverCheckError",
    "check_loop_steps",
    "LOOP_MIN_STEPS",
    "LOOP_SLEW_FACTOR",
    "LOOP_TOLERANCES",
    "driver_failures",
    "driver_verdict",
    "loop_failures",
    "loop_line",
    "loop_plan",
    "parse_loop_line",
    "parse_series_line",
]

#: Loop length over the eigenaxis slew time of the driver's slew. The
#: MPC's loop (horizon 20) settles to 1e-3° in about 1.85 slew times
#: (measured: demo 31.5 s for a 17.2 s slew; meteor-m at dt 6 s, 430 s
#: for 234 s), so 2.5 leaves a third more.
LOOP_SLEW_FACTOR = 2.5

#: Fewest steps of a loop (a slew shorter than a few samples).
LOOP_MIN_STEPS = 20

#: Loop length when the slew time cannot be found (no MPC, no wheels
#: able to turn the body about the eigenaxis).
LOOP_DEFAULT_STEPS = 80

#: Tolerances of the loop check, per precision: ``final_error`` [rad] of
#: the attitude at the end of the loop, ``violation`` the largest scaled
#: bound violation of an applied step (the MPC's ``first_violation``:
#: torque over m_max, momentum over h_max). Double: measured 2.4e-6°
#: (4e-8 rad) and 1.8e-13 on the demo craft; single (`benchmarks.embedded`, the M4F):
#: 3.5e-4 rad and 4.7e-5 (tests/ocp/test_targets.py).
LOOP_TOLERANCES: dict[str, dict[str, float]] = {
    "double": {"final_error": math.radians(0.01), "violation": 1e-6},
    "single": {"final_error": 1e-3, "violation": 1e-4},
}


class DriverCheckError(AdcsError):
    """The driver ran, but a closed loop failed its check.

    Attributes
    ----------
    times : dict
        Everything the driver printed, parsed (`ocp.codegen.run_driver`
        or `ocp.codegen.target.run_target`): its timings, and for each
        ``closed_loop:<name>`` the check's figures.
    failures : list of str
        One sentence per failed loop.
    """

    def __init__(self, message: str, times: dict, failures: list[str]
                 ) -> None:
        super().__init__(message)
        self.times = times
        self.failures = failures


def check_loop_steps(steps: Any) -> None:
    """Raise `InvalidValueError` unless ``steps`` is None or an integer
    >= 1 (a loop length)."""
    if steps is not None and (isinstance(steps, bool) or not isinstance(
            steps, (int, np.integer)) or steps < 1):
        raise InvalidValueError(
            f"loop_steps must be an integer >= 1, got {steps!r}")


def loop_plan(model: Any, samples: dict[str, list[np.ndarray]], dt: float,
              *, rate_max: float | None = None, horizon: int = 20,
              steps: int | None = None, precision: str = "double"
              ) -> dict[str, Any]:
    """Size the driver's closed loop and state its check.

    Parameters
    ----------
    model : ocp.models.rigid.SpacecraftModel
        The exported model (its inertia and wheels).
    samples : dict
        The driver's inputs (`ocp.codegen.default_functions`): an MPC
        step's first two give the start state and the target.
    dt : float
        Sample time [s].
    rate_max : float, optional
        Body-rate limit of the MPC [rad/s].
    horizon : int
        MPC horizon (intervals), for the failure's hint.
    steps : int, optional
        Loop length in steps (default: `LOOP_SLEW_FACTOR` times the
        eigenaxis slew time, at least `LOOP_MIN_STEPS`).
    precision : {"double", "single"}
        Picks `LOOP_TOLERANCES`.

    Returns
    -------
    dict
        ``steps``, ``dt`` [s], ``seconds`` (their product), ``slew_time``
        (eigenaxis [s], NaN when not found), ``horizon``,
        ``final_error_tol`` [rad], ``violation_tol``.

    Raises
    ------
    InvalidValueError
        ``steps`` is not an integer >= 1.
    """
    from ocp.guidance import eigenaxis_slew

    slew_time = math.nan
    mpc = [k for k in samples if k.startswith("mpc") and ":" not in k]
    if mpc and model.wheels is not None:
        x0, qf = samples[mpc[0]][:2]
        try:
            slew_time = float(eigenaxis_slew(
                model.inertia, np.asarray(x0)[:4], qf, wheels=model.wheels,
                rate_max=rate_max).T)
        except AdcsError:
            pass
    check_loop_steps(steps)
    if steps is None:
        steps = LOOP_DEFAULT_STEPS if not math.isfinite(slew_time) else max(
            LOOP_MIN_STEPS, math.ceil(LOOP_SLEW_FACTOR * slew_time / dt))
    tol = LOOP_TOLERANCES[precision]
    return {"steps": int(steps), "dt": float(dt),
            "seconds": int(steps) * float(dt), "slew_time": slew_time,
            "horizon": int(horizon), "final_error_tol": tol["final_error"],
            "violation_tol": tol["violation"]}


def _hint(plan: dict[str, Any]) -> str:
    """Why a loop of ``plan`` may not arrive, or ""."""
    look = plan["horizon"] * plan["dt"]
    if plan["seconds"] < plan["slew_time"]:
        return (f"; the loop is shorter than the craft's eigenaxis slew, "
                f"{plan['slew_time']:.3g} s")
    if look < 0.5 * plan["slew_time"]:
        return (f"; the MPC looks {plan['horizon']} × {plan['dt']:g} s = "
                f"{look:g} s ahead, the craft's eigenaxis slew takes "
                f"{plan['slew_time']:.3g} s: try a longer dt or horizon")
    return ""


_LOOP = re.compile(r"^LOOP (\S+) (.*)$")


def parse_loop_line(line: str, out: dict[str, dict]) -> bool:
    """Add a driver's ``LOOP closed_loop:<name> key=value ...`` line to
    ``out[name]``; False when ``line`` is not one."""
    m = _LOOP.match(line)
    if not m:
        return False
    rec = out.setdefault(m[1], {})
    for kv in m[2].split():
        key, value = kv.split("=", 1)
        rec[f"loop_{key}"] = float(value)
    return True


def parse_series_line(line: str, out: dict[str, dict], steps_key: str,
                      scale: float = 1.0) -> bool:
    """Add a driver's ``STEPS closed_loop:<name>: v…`` line (each step's
    figure in step order, times ``scale``, under ``steps_key``) or
    ``STATE closed_loop:<name>: x…`` line (the loop's final state, under
    ``"state"``) to ``out[name]``; False when ``line`` is neither."""
    if line.startswith("STEPS "):
        key, factor = steps_key, scale
    elif line.startswith("STATE "):
        key, factor = "state", 1.0
    else:
        return False
    name, vals = line[6:].rsplit(":", 1)
    out.setdefault(name, {})[key] = [factor * float(v) for v in vals.split()]
    return True


def loop_failures(times: dict[str, dict], plan: dict[str, Any] | None = None
                  ) -> list[str]:
    """One phrase per closed loop of ``times`` that failed its check.

    The last phrase ends with the loops' length and tolerance and, with
    ``plan`` (`loop_plan`, an export's ``extras["closed_loop"]``), a hint
    when the loop or the MPC horizon is short of the craft's slew.
    """
    failed, last = [], None
    for name, t in times.items():
        if "loop_ok" not in t or t["loop_ok"]:
            continue
        why = []
        if not t["loop_finite"]:
            why.append("goes NaN")
        else:
            if not t["loop_final_error_deg"] <= t["loop_tolerance_deg"]:
                why.append(f"ends {t['loop_final_error_deg']:.3g}° from "
                           "the target")
            if not t["loop_worst_violation"] <= t[
                    "loop_violation_tolerance"]:
                why.append(f"breaks a bound (worst applied-step violation "
                           f"{t['loop_worst_violation']:.3g} > "
                           f"{t['loop_violation_tolerance']:.3g})")
        if t.get("loop_flag"):
            why.append(f"has a step returning {int(t['loop_flag'])}")
        failed.append(f"{name.split(':', 1)[-1]} "
                      + ", ".join(why or ["fails"]))
        last = t
    if last is not None:
        hint = _hint(plan) if plan and math.isfinite(
            plan.get("slew_time", math.nan)) else ""
        failed[-1] += (
            f" after {int(last['loop_steps'])} steps × "
            f"{last['loop_dt']:g} s = {last['loop_seconds']:g} s (tolerance "
            f"{last['loop_tolerance_deg']:.3g}°{hint})")
    return failed


def driver_failures(times: dict[str, dict], plan: dict[str, Any] | None
                    = None) -> list[str]:
    """Every failed check of a driver's figures: calls that returned
    nonzero (``flag``), then the closed loops (`loop_failures`)."""
    calls = [name for name, t in times.items() if not name.startswith("_")
             and "loop_ok" not in t and t.get("flag", 0)]
    found = [f"nonzero return from {', '.join(calls)}"] if calls else []
    loops = loop_failures(times, plan)
    if loops:
        found.append("closed loop " + "; ".join(loops))
    return found


def loop_line(t: dict) -> str:
    """A closed loop's length, final error and tolerance, as a sentence."""
    if "loop_steps" not in t:
        return (f"closed loop of {t['calls']} steps ends "
                f"{t['final_error_deg']:.2e}° from the target")
    return (f"closed loop of {int(t['loop_steps'])} steps × "
            f"{t['loop_dt']:g} s = {t['loop_seconds']:g} s ends "
            f"{t['loop_final_error_deg']:.2e}° from the target (tolerance "
            f"{t['loop_tolerance_deg']:.2g}°)")


def driver_verdict(times: dict[str, dict], plan: dict[str, Any] | None
                   = None) -> tuple[bool, str]:
    """``(passed, line)``: the last line of a driver's table.

    ``"driver checks: every call returned 0, every closed loop reached
    its target"``, or ``"driver checks FAILED: "`` and every failure
    (`driver_failures`).
    """
    failed = driver_failures(times, plan)
    if not failed:
        return True, ("driver checks: every call returned 0, every closed "
                      "loop reached its target")
    return False, "driver checks FAILED: " + "; ".join(failed)


def plan_length(f: Any, loop: dict[str, Any]) -> int:
    """Reals in one plan of the MPC step ``f`` (the driver's cold start):
    ``(N + 1) n_x + N n_u``, N ``loop["horizon"]``; a robust step's z
    holds one plan per scenario. The whole z when it is not a multiple."""
    nx, nu, N = f.nnz_in(0), f.nnz_out(0), int(loop["horizon"])
    n = (N + 1) * nx + N * nu
    return n if f.nnz_in(3) % n == 0 else int(f.nnz_in(3))
