"""Receding-horizon (MPC) attitude control with wheel-level limits (theory §4).

The optimal-control problem is formulated once, by multiple shooting over
``horizon`` RK4 intervals of length ``dt``, with the parameters
``p = (x, q_f, τ)``: current state, target quaternion and a disturbance
torque estimate held over the horizon. Decision vector (layout
``x_0, u_0, x_1, u_1, …, u_{N-1}, x_N``):

.. math::
    \\min\\ \\sum_{k=1}^{N} c_k\\big(w_q \\|\\mathrm{vec}(q_f^{*}\\otimes
    q_k)\\|^2 + w_ω \\|ω_k\\|^2\\big)
    + \\sum_{k=0}^{N-1} w_m \\|m_k / m_{max}\\|^2
    + w_H \\|H_k / h_{max}\\|^2 + w_p\\, p^T k_k

subject to :math:`x_0 = x`, :math:`x_{k+1} = \\mathrm{RK4}(x_k, m_k, τ)`,
:math:`|m_{k,i}| \\le m_{max,i}` (0 for a failed wheel),
:math:`|H_{k,i}| \\le h_{max,i}` and optionally :math:`|ω_{k,j}| \\le
ω_{max}`; :math:`c_N` is ``terminal`` and the other :math:`c_k` are 1.
With a thruster set in the model (``rigid_spacecraft(J, wheels,
thrusters=...)``) the controls are ``u = (m, k)``: duties
:math:`0 \\le k_{k,i} \\le 1` enter through their cycle-averaged torque
and the linear propellant term :math:`w_p\\, p^T k` (``p`` the engines'
propellant rates over the largest one), so the thrusters fire only when
the wheels alone cannot hold the attitude within their momentum bound
(unloading under a secular disturbance).
The cost is a sum of squares (the vector part of the quaternion error is
linear in q), so a Gauss–Newton Hessian :math:`2 J_r^T J_r` is positive
semi-definite: ``"sqpmethod"`` is CasADi's SQP with that Hessian and a
code-generatable conic (``"qrqp"`` default), and with ``rti=True`` makes
one SQP step per sample (real-time iteration).

Each MPC step is one call of `AttitudeMPC.step_function`, a CasADi
Function that shifts the previous solution (warm start), solves and
returns the first control; it exports to C with sqpmethod + qrqp.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Sequence

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import (
    ThreadOwnershipError,
    InvalidValueError,
    SolverError,
    SolverNotFound,
)
from adcs_common.buffers import BoundCall
from adcs_common.quaternion import as_unit_quaternion
from adcs_common.validation import (
    as_count,
    as_options,
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_positive,
)

from ocp.models.rigid import SpacecraftModel
from ocp.spacecraft.definition import Spacecraft
from adcs_common.options import merge_options
from adcs_common.solver_options import check_nlpsol_options
from adcs_common.threads import new_lock, synchronized
from .certificate import (default_mpc_solver, qp_kkt_function,
                          resolve_qp_solver)
from .condensed import check_condensed_options, condensed_step_functions
from .stagewise import (block_lengths, check_stagewise_options,
                        stagewise_step_functions)
from .keepout import KEEP_OUT_BACKOFF, as_keep_out
from .nlp_step import build_nlp_step
from .plan import (check_function, plan_bounds, residual_function,
                   shift_function)
from .problem import (
    BOUND_TOL,
    DEFECT_TOL,
    MPCStep,
    MPCWeights,
    QP_SOLVERS,
    MPC_SOLVERS,
    NLP_PLUGINS,
    OWN_SQP_SOLVERS,
    QP_KKT_TOL,
    available_mpc_solvers,
    check_reachable,
    dynamics_sign,
    momentum_residual,
    pointing_residuals,
    torque_residual,
)


__all__ = [
    "AttitudeMPC",
    "default_mpc_solver",
    "MPCStep",
    "MPCWeights",
    "QP_SOLVERS",
    "available_mpc_solvers",
]


class AttitudeMPC:
    """Receding-horizon attitude controller of a wheeled spacecraft.

    Threads: an MPC carries its plan (the warm start) from one step to the
    next, so it follows one trajectory in one thread. `step` from a second
    thread raises `ThreadOwnershipError` until that thread calls `reset`;
    build one MPC per thread to run several at once.

    Parameters
    ----------
    model : SpacecraftModel or ocp.spacecraft.Spacecraft
        Spacecraft with a wheel array (`ocp.rigid_spacecraft` with
        ``wheels``), optionally with a thruster set (duties in [0, 1],
        propellant in the cost); a `Spacecraft` gives its model and its
        ``rate_max`` (unless ``rate_max`` is given).
    horizon : int
        Number of intervals N (>= 2).
    dt : float
        Sample time and interval length [s].
    solver : {None, "condensed", "stagewise", "sqpmethod", "ipopt", "fatrop"}
        NLP solver. None (default): `default_mpc_solver`, which is
        ``"condensed"`` for wheel-only models up to 40 stages,
        ``"stagewise"`` beyond (``"condensed"`` with a rate bound), and
        ``"sqpmethod"`` with thrusters. ``"condensed"``: the toolbox's Gauss–Newton SQP whose
        QP keeps the controls only (`ocp.mpc.condensed`; wheel-only
        models), exact dense active set, each QP point certified by its
        KKT residual; its step Functions also return ``iterations``.
        ``"stagewise"``: the same SQP and QP, kept stage-wise and solved
        by a Riccati interior point (`ocp.mpc.stagewise`): cost and
        generated code linear in the horizon, for long horizons.
        ``"sqpmethod"``: CasADi's Gauss–Newton SQP with a
        code-generatable conic (qrqp by default); with ``rti`` its QP
        point is certified too and a step that fails goes to the full
        SQP.
    qp_solver : {"qrqp", "daqp", "pqp", "rqp"}, optional
        Conic of ``"sqpmethod"`` (default ``"qrqp"``) or of
        ``"condensed"`` (default daqp where the casadi wheel has it).
        ``"pqp"`` (``"condensed"`` only): the toolbox's primal active set
        in C (`ocp.mpc.primal_qp`), warm-started where the step starts;
        it needs a C compiler. ``"stagewise"`` takes None (its Riccati
        interior point) or ``"rqp"``: the Riccati active set in C
        (`ocp.mpc.riccati_qp`, memory linear in the horizon; no move
        blocks; needs a C compiler). With ``solver_options={"qp_max_iter":
        k}`` pqp or rqp is capped: a step may apply a feasible,
        cost-lowering point that is not its QP's optimum (status
        ``"...:qp_capped"``, `ocp.mpc.condensed`).
    rti : bool
        Real-time iteration: one full SQP step per sample (``"sqpmethod"``
        only). When that step leaves the applied command or the next
        state outside the bounds (qrqp can return such a step on
        degenerate active sets), the step falls back to the full SQP from
        the same warm start (status ``"rti_fallback:..."``); the exported
        step Function does the same. A checked RTI step is one call of
        `rti_function` through a bound buffer (status ``"rti_step"``, one
        iteration): no Python between the shift, the SQP step and the
        checks.
    weights : MPCWeights, optional
        Cost weights.
    rate_max : float, optional
        Bound on each body-rate component ``|ω_j|`` [rad/s].
    max_iter : int
        Iteration limit of the NLP solver (ignored with ``rti``).
    expand : bool
        Expand the NLP to SX (faster in Python; ``False`` gives ~5x
        smaller generated C, as RK4 and its derivatives stay functions
        called per interval).
    solver_options : dict, optional
        Options of the CasADi nlpsol, merged over the defaults and
        forwarded untouched; for ``"condensed"``: ``{"step_tol": ...,
        "anderson": m}`` (`ocp.mpc.condensed.STEP_TOL`, the memory of the
        Anderson acceleration, `ocp.mpc.condensed.ANDERSON_MEMORY`; 0
        turns it off; ``"qp_max_iter"``: the pqp QP's cap, default
        1000); ``"stagewise"`` takes those and ``"ipm_tol"``,
        ``"ipm_max_iter"`` (`ocp.mpc.stagewise_ipm.IPM_TOL`,
        `IPM_MAX_ITER`).
    move_blocks : int or sequence of int, optional
        Move blocking (``"stagewise"`` only): the control is held over
        blocks of stages, ``M`` blocks as even as possible (the shorter
        ones first) or the given block lengths (summing to the horizon).
        The number of free controls falls from N to M; the work per stage
        stays (`ocp.mpc.stagewise`).
    keep_out : KeepOut or sequence of KeepOut, optional
        Keep-out cones held at every planned state (``"stagewise"``
        only), linearised per SQP step as states of the QP
        (`ocp.mpc.keepout`), planned ``KEEP_OUT_BACKOFF`` inside.

    Raises
    ------
    SolverNotFound
        Unknown ``solver`` or ``qp_solver``, or its plugin is missing.
    InvalidValueError
        Bad horizon, dt, rate bound, a model without wheels, or an
        unknown solver option (the message lists the allowed ones).
    """

    def __init__(self, model: SpacecraftModel | Spacecraft, *, horizon: int = 20,
                 dt: float = 0.5, solver: str | None = None,
                 qp_solver: str | None = None, rti: bool = False,
                 weights: MPCWeights | None = None,
                 rate_max: float | None = None, max_iter: int = 50,
                 expand: bool = True,
                 solver_options: dict | None = None,
                 move_blocks: int | Sequence[int] | None = None,
                 keep_out: Any = None) -> None:
        self._lock = new_lock()
        self._owner: int | None = None
        if isinstance(model, Spacecraft):
            if rate_max is None:
                rate_max = model.rate_max
            model = model.model()
        if not isinstance(model, SpacecraftModel) or model.wheels is None:
            raise InvalidValueError(
                "model must be a SpacecraftModel with a wheel array "
                "(rigid_spacecraft(inertia, wheels))")
        if (not isinstance(horizon, (int, np.integer)) or isinstance(
                horizon, bool) or horizon < 2):
            raise InvalidValueError(
                f"horizon must be an integer >= 2, got {horizon!r}")
        if solver is None:
            solver = default_mpc_solver(model, horizon)
        self.dt = as_finite_scalar(dt, "dt")
        check_positive(self.dt, "dt")
        if not isinstance(solver, str) or solver not in MPC_SOLVERS:
            raise SolverNotFound(str(solver), available_mpc_solvers(),
                                 "MPC solvers: 'sqpmethod' or 'condensed' "
                                 "(with qp_solver 'qrqp' or 'daqp'), "
                                 "'ipopt', 'fatrop'")
        if solver not in available_mpc_solvers():
            raise SolverNotFound(solver, available_mpc_solvers(),
                                 f"the CasADi plugin {solver!r} is missing")
        if solver == "stagewise" and qp_solver not in (None, "rqp"):
            raise InvalidValueError(
                "solver='stagewise' solves its QP itself: qp_solver None "
                "(a Riccati interior point) or 'rqp' (the Riccati active "
                f"set in C), got {qp_solver!r}")
        qp_solver = resolve_qp_solver(solver, qp_solver)
        if rti and solver not in ("sqpmethod", *OWN_SQP_SOLVERS):
            raise InvalidValueError(
                "rti=True needs solver='sqpmethod', 'condensed' or "
                f"'stagewise', got {solver!r}")
        max_iter = as_count(max_iter, "max_iter")
        self.model = model
        self.wheels = model.wheels
        self.horizon = int(horizon)
        self.solver = solver
        self.qp_solver = qp_solver if solver in (
            "sqpmethod", "condensed") or qp_solver == "rqp" else ""
        self.rti = bool(rti)
        self.weights = weights if weights is not None else MPCWeights()
        if not isinstance(self.weights, MPCWeights):
            raise InvalidValueError(
                f"weights must be MPCWeights, got {type(weights).__name__}")
        self.rate_max = None
        if rate_max is not None:
            self.rate_max = as_finite_scalar(rate_max, "rate_max")
            check_positive(self.rate_max, "rate_max")
        self.max_iter = 1 if self.rti else int(max_iter)
        self.fallback_max_iter = int(max_iter)
        #: Lengths of the move blocks (stages per held control), or None.
        self.move_blocks = block_lengths(move_blocks, self.horizon, solver)
        self.keep_out = as_keep_out(keep_out, solver)
        self.keep_out_backoff = KEEP_OUT_BACKOFF
        self.expand = bool(expand)
        #: Levenberg–Marquardt term added to the Gauss–Newton Hessian: the
        #: GN Hessian is singular (no cost on ``|q|`` or on x_0), and qrqp
        #: then declares convergence on points violating the QP constraints.
        self.regularization = 1e-4
        t0 = time.perf_counter()
        self._build(as_options(solver_options) if solver in OWN_SQP_SOLVERS
                    else check_nlpsol_options(NLP_PLUGINS[solver],
                                              solver_options,
                                              self.qp_solver or "qrqp"))
        self.build_time = time.perf_counter() - t0
        self._plan: np.ndarray | None = None
        self._lam_x = np.zeros(self.nz)
        self._lam_g = np.zeros(self.ng)
        self._rti_buffer: BoundCall | None = None

    # ------------------------------------------------------------ layout
    @property
    def name(self) -> str:
        """Label such as ``"sqpmethod+qrqp (RTI)"``."""
        label = self.solver
        if self.qp_solver:
            label += f"+{self.qp_solver}"
        return label + (" (RTI)" if self.rti else "")

    @property
    def nz(self) -> int:
        """Length of the decision vector."""
        return self._nz

    @property
    def ng(self) -> int:
        """Number of equality constraints ((N + 1) · nx)."""
        return self._ng

    def _stage_slices(self) -> tuple[list[slice], list[slice]]:
        nx, nu = self.model.nx, self.model.nu
        xs, us = [], []
        for k in range(self.horizon + 1):
            start = k * (nx + nu)
            xs.append(slice(start, start + nx))
            if k < self.horizon:
                us.append(slice(start + nx, start + nx + nu))
        return xs, us

    def _build(self, user_options: dict) -> None:
        model, N = self.model, self.horizon
        nx, nu = model.nx, model.nu
        nz = (N + 1) * nx + N * nu
        self._nz, self._ng = nz, (N + 1) * nx
        self._xs, self._us = self._stage_slices()
        z = ca.MX.sym("z", nz)
        x_par = ca.MX.sym("x", nx)
        qf = ca.MX.sym("qf", 4)
        tau = ca.MX.sym("tau", 3)
        p = ca.vertcat(x_par, qf, tau)
        r, gv, f = self._objective(z, x_par, qf, tau)
        self.lbz, self.ubz, self._bound_scale = plan_bounds(self)
        self.qp_kkt_function = qp_kkt_function(self, z, p, r, gv, f)
        self._residuals = residual_function(self)
        self.shift_function = shift_function(nx, nu, nz, self._ng)
        self.check_function = check_function(self, p)
        self.nlpsol: ca.Function | None = None
        self.fallback: ca.Function | None = None
        if self.solver == "condensed":
            check_condensed_options(user_options)
            self.rti_function, full = condensed_step_functions(
                self, self.qp_solver, **user_options)
            self.step_function = self.rti_function if self.rti else full
            return
        if self.solver == "stagewise":
            check_stagewise_options(user_options, qp_solver=self.qp_solver)
            self.rti_function, full = stagewise_step_functions(
                self, **user_options)
            self.step_function = self.rti_function if self.rti else full
            return
        nlp = {"x": z, "p": p, "f": f, "g": gv}
        plugin = NLP_PLUGINS[self.solver]
        opts = merge_options(self._default_options(z, p, r, gv), user_options)
        self.nlpsol = ca.nlpsol("mpc_nlp", plugin, nlp, opts)
        #: RTI only: the full SQP, run from the same warm start when the
        #: single step leaves the applied command or x_1 outside the
        #: bounds (qrqp can return such a step on degenerate active sets).
        if self.rti:
            full = merge_options(opts, {"max_iter": self.fallback_max_iter,
                                 "max_iter_ls": 3})
            self.fallback = ca.nlpsol("mpc_nlp_full", plugin, nlp, full)
        build_nlp_step(self, x_par, qf, tau, p)

    def _objective(self, z, x_par, qf, tau):
        """Least-squares residuals ``r``, dynamics rows and the cost."""
        model, wh, N, w = self.model, self.wheels, self.horizon, self.weights
        xs, us = self._xs, self._us
        rk4 = model.rk4_step(1).expand()
        m_max = np.asarray(wh.m_max, dtype=float)
        h_max = np.asarray(wh.h_max, dtype=float)
        nw = wh.n_wheels
        prop = self._propellant_weights()
        lin = 0
        g = [z[xs[0]] - x_par]
        res = []
        sign = dynamics_sign(self.solver)
        for k in range(N):
            g.append(sign * (z[xs[k + 1]]
                             - rk4(z[xs[k]], z[us[k]], tau, self.dt)))
            res.append(torque_residual(z[us[k]], w, m_max))
            if prop.size:
                lin = lin + w.propellant * ca.dot(ca.DM(prop),
                                                  z[us[k]][nw:])
            res.append(momentum_residual(z[xs[k]], w, h_max))
        for k in range(1, N + 1):
            res.append(pointing_residuals(
                z[xs[k]], qf, w, w.terminal if k == N else 1.0))
        r = ca.vertcat(*res)
        # the linear propellant term has no curvature: the Gauss–Newton
        # Hessian of the squares is still the cost's Hessian
        return r, ca.vertcat(*g), ca.sumsqr(r) + lin

    def _propellant_weights(self) -> np.ndarray:
        """Propellant rate of each thruster over the largest (none: ())."""
        thr = self.model.thrusters
        prop = np.zeros(0) if thr is None else thr.propellant_rate()
        return prop / prop.max() if prop.size else prop

    def _default_options(self, z, p, r, g) -> dict:
        if self.solver == "ipopt":
            return {"expand": self.expand, "print_time": False,
                    "ipopt": {"print_level": 0, "sb": "yes",
                              "max_iter": self.max_iter, "tol": 1e-8}}
        if self.solver == "fatrop":
            return {"expand": self.expand, "print_time": False,
                    "structure_detection": "auto",
                    "equality": [True] * self._ng,
                    "fatrop": {"print_level": 0,
                               "max_iter": self.max_iter}}
        lf = ca.MX.sym("lam_f")
        lg = ca.MX.sym("lam_g", g.shape[0])
        Jr = ca.jacobian(r, z)
        hess = ca.Function("gn_hess", [z, p, lf, lg],
                           [2 * lf * ca.mtimes(Jr.T, Jr)
                            + self.regularization * ca.DM.eye(z.numel())],
                           ["x", "p", "lam_f", "lam_g"],
                           ["hess_gamma_x_x"])
        qp_opts: dict[str, Any] = {"error_on_fail": False}
        if self.qp_solver == "qrqp":
            qp_opts.update(print_iter=False, print_header=False,
                           print_info=False)
        opts: dict[str, Any] = {
            "expand": self.expand, "hess_lag": hess, "qpsol": self.qp_solver,
            "qpsol_options": qp_opts, "print_header": False,
            "print_iteration": False, "print_status": False,
            "print_time": False, "error_on_fail": False,
            "max_iter": self.max_iter, "tol_pr": 1e-9, "tol_du": 1e-7}
        if self.rti:
            opts["max_iter_ls"] = 0
        return opts

    # ------------------------------------------------------------ calls
    def initial_guess(self, x: ArrayLike) -> np.ndarray:
        """Decision vector holding state ``x`` with zero torques (nz,)."""
        x = as_vector(x, self.model.nx, "x")
        z = np.zeros(self.nz)
        for s in self._xs:
            z[s] = x
        return z

    @synchronized
    def reset(self) -> None:
        """Forget the warm start; the calling thread may now step it.

        An MPC carries its plan from one step to the next, so it follows
        one trajectory in one thread: `step` from another thread raises
        `ThreadOwnershipError` until that thread calls `reset`.
        """
        self._owner = threading.get_ident()
        self._plan = None
        self._lam_x = np.zeros(self.nz)
        self._lam_g = np.zeros(self.ng)

    def _solve_nlp(self, z0: Any, p: np.ndarray, lx0: Any, lg0: Any
                   ) -> tuple[dict[str, Any], dict[str, Any]]:
        """One call of the NLP solver: ``(solution, stats)``."""
        assert self.nlpsol is not None     # an NLP-solver MPC
        sol = self.nlpsol(x0=z0, p=p, lbx=self.lbz, ubx=self.ubz, lbg=0,
                          ubg=0, lam_x0=lx0, lam_g0=lg0)
        return sol, self.nlpsol.stats()

    @synchronized
    def step(self, x: ArrayLike, qf: ArrayLike, tau: ArrayLike | None = None,
             *, check: bool = True) -> MPCStep:
        """One MPC step from state ``x`` towards attitude ``qf``.

        Raises `ThreadOwnershipError` when another thread stepped this
        MPC since its last `reset` (see there).

        Parameters
        ----------
        x : array_like (7 + N,)
            Current state (q, ω [rad/s], H_w [N·m·s]).
        qf : array_like (4,)
            Target quaternion (scalar-first; normalised here).
        tau : array_like (3,), optional
            Disturbance torque estimate over the horizon [N·m].
        check : bool
            Raise when the plan violates its bounds.

        Returns
        -------
        MPCStep

        Raises
        ------
        ShapeError, InvalidValueError
            Bad ``x``, ``qf`` or ``tau`` (the message names it).
        InfeasibleError
            No plan meets the bounds over the horizon (e.g. a wheel
            momentum that cannot be brought inside ``h_max`` in one
            step, or a rate beyond ``rate_max``).
        SolverError
            The solver returned a plan that breaks its constraints.
        """
        me = threading.get_ident()
        if self._owner is None:
            self._owner = me
        elif self._owner != me:
            raise ThreadOwnershipError(
                "this AttitudeMPC follows a trajectory of another thread "
                "(its warm start): build one MPC per thread, or call "
                "reset() from this thread to take it over")
        nx = self.model.nx
        x = as_finite_array(x, "x", (nx,))
        nq = float(np.linalg.norm(x[:4]))
        if abs(nq - 1.0) > 1e-3:
            raise InvalidValueError(
                f"x[:4] must be a unit quaternion (the attitude), its norm "
                f"is {nq:.6g}")
        qf = as_unit_quaternion(qf, "qf")
        tau = np.zeros(3) if tau is None else as_vector(tau, 3, "tau")
        check_reachable(self, x)
        z_prev = self._plan if self._plan is not None else \
            self.initial_guess(x)
        p = np.r_[x, qf, tau]
        t0 = time.perf_counter()
        kkt = float("nan")
        own = self.solver in OWN_SQP_SOLVERS
        if self.rti or own:
            # one buffered call: shift, SQP step(s), checks
            z, lam_x, lam_g, u, cost, viol, viol1, defect, *n = \
                self._rti_call(x, qf, tau, z_prev)
            status, iters, kkt = "rti_step", 1, n[1 if own else 0]
            if own and not self.rti:
                iters = int(n[0])
                status = ("converged" if iters < self.fallback_max_iter
                          else "iteration_limit")
            if own and len(n) > 2 and n[2] > 0:
                status += ":qp_capped"      # the last QP's (pqp)
        else:
            z0, lx0, lg0 = self.shift_function(x, z_prev, self._lam_x,
                                               self._lam_g)
            sol, stats = self._solve_nlp(z0, p, lx0, lg0)
            z, lam_x, lam_g, u, cost, viol, viol1, defect = self._unpack(
                sol, p)
            status = str(stats.get("return_status", "unknown"))
            iters = int(stats.get("iter_count", -1))
        solve_time = time.perf_counter() - t0
        if self.fallback is not None and (viol1 > BOUND_TOL
                                          or not kkt <= QP_KKT_TOL):
            z0, lx0, lg0 = self.shift_function(x, z_prev, self._lam_x,
                                               self._lam_g)
            sol = self.fallback(x0=z0, p=p, lbx=self.lbz, ubx=self.ubz,
                                lbg=0, ubg=0, lam_x0=lx0, lam_g0=lg0)
            solve_time = time.perf_counter() - t0
            stats = self.fallback.stats()
            z, lam_x, lam_g, u, cost, viol, viol1, defect = self._unpack(
                sol, p)
            status = ("rti_fallback:"
                      + str(stats.get("return_status", "unknown")))
            iters = 1 + int(stats.get("iter_count", -1))
            kkt = float("nan")
        result = MPCStep(u=u, plan=z, cost=cost, violation=viol,
                         first_violation=viol1, defect=defect,
                         solve_time=solve_time, iterations=iters,
                         status=status, qp_kkt=kkt)
        if check and own and not kkt <= QP_KKT_TOL:
            self.reset()
            raise SolverError(
                f"MPC step ({self.name}): the QP's point fails its "
                f"optimality certificate (KKT residual {kkt:.3g} > "
                f"{QP_KKT_TOL:g})", solver=self.name, result=result)
        if check:
            bad = not (np.isfinite(cost) and np.all(np.isfinite(z)))
            # RTI: only the applied command and the state it leads to are
            # checked (qrqp can leave a bound violated far in the plan's
            # tail on degenerate active sets; the tail is a warm start)
            checked = viol1 if self.rti else viol
            if bad or checked > BOUND_TOL or (
                    not self.rti and defect > DEFECT_TOL):
                self.reset()
                raise SolverError(
                    f"MPC step ({self.name}): the plan breaks its "
                    f"constraints (bound violation {viol:.3g}, dynamics "
                    f"defect {defect:.3g}, status {status!r})",
                    solver=self.name, result=result)
        self._plan, self._lam_x, self._lam_g = z, lam_x, lam_g
        return result

    def _rti_call(self, x, qf, tau, z_prev) -> tuple:
        """Call `rti_function` (condensed: `step_function`) via a buffer."""
        call = self._rti_buffer
        if call is None:
            f = self.step_function if self.solver in OWN_SQP_SOLVERS \
                else self.rti_function
            call = self._rti_buffer = BoundCall(
                f, tuple(np.zeros(f.nnz_in(i)) for i in range(f.n_in())),
                tuple(np.zeros(f.nnz_out(i)) for i in range(f.n_out())))
        ins, outs = call.inputs, call.outputs
        ins[0][:], ins[1][:], ins[2][:], ins[3][:] = x, qf, tau, z_prev
        ins[4][:], ins[5][:] = self._lam_x, self._lam_g
        call.trigger()
        u, z, lam_x, lam_g = (o.copy() for o in outs[:4])
        return (z, lam_x, lam_g, u, *(float(o[0]) for o in outs[4:]))

    def _unpack(self, sol: dict, p: np.ndarray) -> tuple:
        """Plan, multipliers, command and the checks of one NLP solution."""
        z = np.asarray(sol["x"]).ravel()
        lam_x = np.asarray(sol["lam_x"]).ravel()
        lam_g = np.asarray(sol["lam_g"]).ravel()
        checks = (float(o) for o in self.check_function(z, p))
        return (z, lam_x, lam_g, z[self._us[0]].copy(), *checks)
