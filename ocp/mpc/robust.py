"""Robust (multi-stage) MPC: one plan per uncertainty scenario, one command.

`RobustMPC` is an `AttitudeMPC` whose plan holds one trajectory per
`Scenario` (inertia, wheel axes, disturbance, weight): every scenario
starts from the measured state and applies the same first command (the
tree branches at the first stage: robust horizon 1), its cost is the
weighted sum of the scenarios' costs, and every bound (torque, momentum,
rate, keep-out cones) holds in every scenario. The step is the
stage-wise SQP on the scenario tree (`ocp.mpc.robust_qp`); with one scenario, the nominal
craft, it is the nominal stage-wise MPC (a test holds them equal).
"""

from __future__ import annotations

from typing import Any, Sequence

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError
from ocp.models.rigid import SpacecraftModel
from ocp.spacecraft.definition import Spacecraft
from .condensed import ANDERSON_MEMORY, STEP_TOL, sqp_step_functions
from .controller import AttitudeMPC
from .keepout import cone_function, plan_cone_violation
from .plan import (bound_violation, nan_unless_finite, plan_bounds,
                   shift_function)
from .robust_qp import (param_rk4, per_stage, plan_stages,
                        robust_iteration, scenario_parameters,
                        stage_selections)
from .scenarios import Scenario
from .stagewise import check_stagewise_options
from .stagewise_ipm import IPM_MAX_ITER, IPM_TOL

__all__ = ["RobustMPC"]


class RobustMPC(AttitudeMPC):
    """Multi-stage robust MPC over scenarios of inertia and misalignment.

    Threads: as `AttitudeMPC` (one trajectory per thread).

    Parameters
    ----------
    model : SpacecraftModel or ocp.spacecraft.Spacecraft
        The nominal craft (wheel-only), e.g. from a TOML file.
    scenarios : sequence of Scenario
        The plants to plan for (`ocp.mpc.scenario_grid`,
        `ocp.mpc.inertia_corners`); their wheel axes, when given, must
        have the model's number of wheels.
    horizon, dt, rti, weights, rate_max, max_iter, keep_out
        As `AttitudeMPC`; the keep-out cones hold in every scenario.
    solver_options : dict, optional
        ``step_tol``, ``anderson``, ``ipm_tol``, ``ipm_max_iter`` (as the
        stage-wise solver's).

    Attributes
    ----------
    scenarios : tuple of Scenario
        As given; the weights are normalised to sum 1 in the cost.
    """

    def __init__(self, model: SpacecraftModel | Spacecraft,
                 scenarios: Sequence[Scenario], *, horizon: int = 20,
                 dt: float = 0.5, rti: bool = False, weights: Any = None,
                 rate_max: float | None = None, max_iter: int = 50,
                 solver_options: dict | None = None,
                 keep_out: Any = None) -> None:
        if isinstance(scenarios, Scenario) or not isinstance(
                scenarios, (list, tuple)) or not scenarios:
            raise InvalidValueError(
                "scenarios must be a non-empty list of Scenario")
        if not all(isinstance(s, Scenario) for s in scenarios):
            raise InvalidValueError(
                "scenarios must hold ocp.mpc.Scenario objects")
        self.scenarios = tuple(scenarios)
        super().__init__(model, horizon=horizon, dt=dt, solver="stagewise",
                         rti=rti, weights=weights, rate_max=rate_max,
                         max_iter=max_iter, solver_options=solver_options,
                         keep_out=keep_out)

    @property
    def name(self) -> str:
        """Label such as ``"robust stagewise, 9 scenarios (RTI)"``."""
        return (f"robust stagewise, {len(self.scenarios)} scenarios"
                + (" (RTI)" if self.rti else ""))

    def _build(self, user_options: dict) -> None:
        model, N = self.model, self.horizon
        if model.thrusters is not None:
            raise InvalidValueError(
                "RobustMPC handles wheel-only models")
        n = self.wheels.n_wheels
        for s in self.scenarios:
            if s.axes is not None and s.axes.shape[1] != n:
                raise InvalidValueError(
                    f"a scenario has {s.axes.shape[1]} wheel axes, the "
                    f"model {n}")
        nx, nu, S = model.nx, model.nu, len(self.scenarios)
        nz0 = (N + 1) * nx + N * nu
        self._nz, self._ng = S * nz0, S * (N + 1) * nx
        self._xs, self._us = self._stage_slices()
        self._nz = nz0     # plan_bounds and the residuals: one scenario
        lb, ub, scale = plan_bounds(self)
        z1 = ca.MX.sym("z", nz0)
        x_par, qf, tau = (ca.MX.sym(k, m) for k, m in
                          (("x", nx), ("qf", 4), ("tau", 3)))
        cost = ca.Function("rb_cost", [z1, ca.vertcat(x_par, qf, tau)],
                           [self._objective(z1, x_par, qf, tau)[2]])
        self._nz = S * nz0
        self.lbz, self.ubz = np.tile(lb, S), np.tile(ub, S)
        self._bound_scale = np.tile(scale, S)
        self.qp_kkt_function = self._residuals = None  # type: ignore
        self.nlpsol = self.fallback = None
        self.shift_function = _robust_shift(nx, nu, N, S)
        self.check_function = _robust_check(self, cost)
        opts = dict(user_options)
        check_stagewise_options(opts, "RobustMPC")
        it = robust_iteration(self, opts.get("ipm_tol", IPM_TOL),
                              opts.get("ipm_max_iter", IPM_MAX_ITER))
        self.rti_function, full = sqp_step_functions(
            self, it, "mpc_robust", opts.get("step_tol", STEP_TOL),
            opts.get("anderson", ANDERSON_MEMORY))
        self.step_function = self.rti_function if self.rti else full

    def initial_guess(self, x: Any) -> np.ndarray:
        """Every scenario's plan holding state ``x``, zero torques (nz,)."""
        S = len(self.scenarios)
        one = super().initial_guess(x)[:self.nz // S]
        return np.tile(one, S)

    def scenario_plans(self, plan: np.ndarray) -> list[np.ndarray]:
        """The plan split per scenario, each in `AttitudeMPC`'s layout."""
        plan = np.asarray(plan, dtype=float)
        return list(plan.reshape(len(self.scenarios), -1))


def _robust_shift(nx: int, nu: int, N: int, S: int) -> ca.Function:
    """`ocp.mpc.plan.shift_function` applied to every scenario's plan."""
    nz0, ng0 = (N + 1) * nx + N * nu, (N + 1) * nx
    one = shift_function(nx, nu, nz0, ng0)
    x = ca.MX.sym("x", nx)
    z = ca.MX.sym("z_prev", S * nz0)
    lx = ca.MX.sym("lam_x_prev", S * nz0)
    lg = ca.MX.sym("lam_g_prev", S * ng0)
    z0, lx0, lg0 = one.map(S)(x, ca.reshape(z, nz0, S),
                              ca.reshape(lx, nz0, S), ca.reshape(lg, ng0, S))
    return ca.Function("mpc_robust_shift", [x, z, lx, lg],
                       [ca.vec(z0), ca.vec(lx0), ca.vec(lg0)],
                       ["x", "z_prev", "lam_x_prev", "lam_g_prev"],
                       ["z0", "lam_x0", "lam_g0"])


def _robust_check(mpc: RobustMPC, cost: ca.Function) -> ca.Function:
    """``check(z, p) -> (cost, violation, first_violation, defect)``.

    Over every scenario: the weighted cost; the bounds' violation scaled
    by each bound; the applied command's and each scenario's x_1; the
    largest defect of each scenario's dynamics (its own inertia, axes and
    disturbance) [state units]; NaN when the plan is not finite
    (`plan.nan_unless_finite`).
    """
    nz, scale, S = mpc.nz, mpc._bound_scale, len(mpc.scenarios)
    nx, N = mpc.model.nx, mpc.horizon
    nz0 = nz // S
    z = ca.MX.sym("z", nz)
    p = ca.MX.sym("p", nx + 7)
    wts = np.array([s.weight for s in mpc.scenarios], float)
    c = ca.mtimes(cost.map(S)(ca.reshape(z, nz0, S), p),
                  ca.DM(wts / wts.sum()))
    viol = bound_violation(z, mpc.lbz, mpc.ubz, scale)
    idx = np.arange(nz0)
    one = np.r_[idx[mpc._us[0]], idx[mpc._xs[1]]]
    first = np.concatenate([one + s * nz0 for s in range(S)])
    viol1 = bound_violation(z, mpc.lbz, mpc.ubz, scale, first)
    sel0, sel1, sel_first = stage_selections(N, S, first=True)
    Xall, _, X, U, X1 = plan_stages(mpc, z, (sel0, sel1))
    tau = ca.repmat(p[nx + 4:], 1, S) + ca.DM(
        np.array([s.tau for s in mpc.scenarios]).T)
    if mpc.keep_out:
        cones = cone_function(mpc.keep_out, nx)
        viol = ca.fmax(viol, plan_cone_violation(cones, X1))
        viol1 = ca.fmax(viol1, plan_cone_violation(
            cones, X1[:, list(range(0, N * S, N))]))
    F = param_rk4(mpc).map(N).map(S)(
        X, U, per_stage(tau, N),
        per_stage(ca.DM(scenario_parameters(mpc)), N))
    x0 = ca.mtimes(Xall, sel_first) - ca.repmat(p[:nx], 1, S)
    defect = ca.mmax(ca.fabs(ca.vertcat(ca.vec(F - X1), ca.vec(x0))))
    viol, viol1, defect = nan_unless_finite(z, viol, viol1, defect)
    return ca.Function(
        "mpc_robust_check", [z, p], [c, viol, viol1, defect],
        ["z", "p"], ["cost", "violation", "first_violation", "defect"])
