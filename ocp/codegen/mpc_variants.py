"""The MPC steps `export_c` can write, and how each is built.

Each variant is an `ocp.mpc.AttitudeMPC` (or `RobustMPC`) step Function
under a C name: sqpmethod + qrqp to convergence (``mpc_step``) and its
RTI (``mpc_rti_step``); the condensed SQP (``mpc_cond_step``,
``mpc_cond_rti_step``); the stage-wise SQP (``mpc_sw_step``,
``mpc_sw_rti_step``, `ocp.mpc.stagewise`); the robust multi-stage MPC on
its scenario tree (``mpc_robust_step``, ``mpc_robust_rti_step``,
`ocp.mpc.robust`).
"""

from __future__ import annotations

from typing import Any, Sequence

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.quaternion import quat_from_axis_angle
from ocp.models.rigid import SpacecraftModel
from .precision import condensed_options, stagewise_options

#: MPC steps `export_c` can write (module doc).
MPC_VARIANTS = ("mpc_step", "mpc_rti_step", "mpc_cond_step",
                "mpc_cond_rti_step", "mpc_sw_step", "mpc_sw_rti_step",
                "mpc_robust_step", "mpc_robust_rti_step")


def check_variants(variants: Any) -> tuple[str, ...]:
    """Check the MPC variants asked for: known names only (no typo)."""
    if variants is None or isinstance(variants, str) or not all(
            isinstance(v, str) for v in variants):
        raise InvalidValueError(
            f"mpc_variants must be a sequence of names from {MPC_VARIANTS}"
            f", got {variants!r}")
    unknown = [v for v in variants if v not in MPC_VARIANTS]
    if unknown:
        raise InvalidValueError(
            f"unknown MPC variant(s) {unknown}; choose from {MPC_VARIANTS}")
    return tuple(variants)


def check_variant_options(variants: Sequence[str], *, move_blocks: Any,
                          scenarios: Any, keep_out: Any,
                          qp_cap: tuple[str, Any] = ("daqp", None),
                          stagewise: tuple[Any, Any] = (None, None)
                          ) -> None:
    """Refuse an MPC option that no exported variant takes, or a bad
    ``qp_cap``: ``(condensed QP, its cap)``, a positive int for pqp only
    (`ocp.mpc.condensed.condensed_step_functions`' ``qp_max_iter``), or
    a bad ``stagewise``: ``(stage-wise QP, its cap)``, None or ``"rqp"``,
    a cap for rqp only."""
    from ocp.mpc.condensed import check_qp_max_iter

    sw, robust, cond = (any(k in v for v in variants)
                        for k in ("_sw_", "robust", "_cond_"))
    qp_max_iter = qp_cap[1]
    check_qp_max_iter(*qp_cap)
    if stagewise[0] not in (None, "rqp"):
        raise InvalidValueError(
            "stagewise_qp_plugin must be None (the interior point) or "
            f"'rqp', got {stagewise[0]!r}")
    check_qp_max_iter(stagewise[0] or "the interior point", stagewise[1])
    for name, value, ok, which in (
            ("condensed_qp_max_iter", qp_max_iter, cond,
             "condensed MPC steps (mpc_cond_step, mpc_cond_rti_step)"),
            ("stagewise_qp_plugin", stagewise[0], sw,
             "stage-wise MPC steps (mpc_sw_step, mpc_sw_rti_step)"),
            ("mpc_move_blocks", move_blocks, sw,
             "stage-wise MPC steps (mpc_sw_step, mpc_sw_rti_step)"),
            ("mpc_scenarios", scenarios, robust,
             "robust MPC steps (mpc_robust_step, mpc_robust_rti_step)"),
            ("mpc_keep_out", keep_out, sw or robust,
             "stage-wise and robust MPC steps")):
        if value is not None and not ok:
            raise InvalidValueError(
                f"{name} applies to the {which}: export one of them")


def mpc_functions(model: SpacecraftModel, variants: Sequence[str], *,
                  horizon: int, dt: float, max_iter: int,
                  rate_max: float | None, condensed_plugin: str,
                  precision: str, move_blocks: Any = None,
                  scenarios: Any = None, keep_out: Any = None,
                  condensed_max_iter: int | None = None,
                  stagewise: tuple[str | None, int | None] = (None, None)
                  ) -> tuple[dict[str, ca.Function],
                             dict[str, list[np.ndarray]]]:
    """``(functions, samples)`` of the MPC variants asked for.

    The sample input of each is the demo slew's first step: 90° about
    (1, 1, 0) from rest, the controller's initial guess.
    ``condensed_max_iter``: the condensed steps' QP cap (pqp,
    `AttitudeMPC` ``solver_options`` ``qp_max_iter``); ``stagewise``:
    the stage-wise steps' QP (None or ``"rqp"``) and its cap.
    """
    from ocp.mpc import AttitudeMPC, RobustMPC, inertia_corners

    qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
    x0 = model.state([1.0, 0.0, 0.0, 0.0])
    fns: dict[str, ca.Function] = {}
    samples: dict[str, list[np.ndarray]] = {}
    for name in MPC_VARIANTS:
        if name not in variants:
            continue
        rti = "rti" in name
        common: dict[str, Any] = {"horizon": horizon, "dt": dt, "rti": rti,
                  "max_iter": max_iter, "rate_max": rate_max}
        if "robust" in name:
            ctl: Any = RobustMPC(model, list(scenarios) if scenarios
                                 else inertia_corners(model.inertia, 0.2),
                                 keep_out=keep_out, **common)
        else:
            cap = {} if condensed_max_iter is None else {
                "qp_max_iter": condensed_max_iter}
            kw = ({"solver": "condensed", "qp_solver": condensed_plugin,
                   "solver_options": {**condensed_options(precision), **cap}}
                  if "cond" in name else
                  {"solver": "stagewise", "move_blocks": move_blocks,
                   "keep_out": keep_out, "qp_solver": stagewise[0],
                   "solver_options": {**stagewise_options(precision), **(
                       {} if stagewise[1] is None else {
                           "qp_max_iter": stagewise[1]})}}
                  if "_sw_" in name else
                  {"solver": "sqpmethod", "expand": False})
            ctl = AttitudeMPC(model, **common, **kw)
        fns[name] = ctl.step_function
        samples[name] = [x0, qf, np.zeros(3), ctl.initial_guess(x0),
                         np.zeros(ctl.nz), np.zeros(ctl.ng)]
    return fns, samples
