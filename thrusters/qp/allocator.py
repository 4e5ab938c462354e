"""Duty-cycle QP allocator (build once, solve many) and min on-time carry."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from adcs_common.results import ResultMixin
from scipy.optimize import linprog

from adcs_common.exceptions import InvalidValueError, ShapeError
from adcs_common.validation import (
    as_finite_array,
    as_finite_scalar,
    as_options,
    check_instance,
    check_positive,
)

from adcs_common.qp import QP
from adcs_common.threads import new_lock, synchronized

from ..laws import THRUST_AXIS, TORQUE_AXES
from ..unit import ThrusterSet
from .casadi_functions import infinite_bounds
from .problem import N_THETA, build_qp
from .solvers import make_backend

#: Largest scaled constraint violation accepted from a backend.
RESIDUAL_TOL = 1e-6
#: The exact backend: the default, and the one a failed iterative backend
#: hands its cycle to (the result's ``extras["fallback"]`` says so).
EXACT_SOLVER = "daqp"
#: Slack (scaled by h_max) below which the momentum bound counts as met.
SLACK_TOL = 1e-7


@dataclass(frozen=True, eq=False, repr=False)
class DutyAllocation(ResultMixin):
    """One cycle of the duty-cycle QP (`DutyCycleAllocator.solve`).

    Attributes
    ----------
    duty : numpy.ndarray, shape (n,)
        Duty fractions in [0, 1] (D1..Dn). Zeros when ``success`` is
        False.
    status : str
        ``"optimal"``: every constraint met; ``"bound_relaxed"``: no duty
        cycle keeps the momentum inside the bound, the returned cycle
        exceeds it by the least amount (``momentum_excess``);
        ``"infeasible"``: the hard tracking demand is outside what the
        thrusters can give (duty zeros, never NaN); ``"failed"``: the
        backend returned no point or one failing the residual check
        while the problem is feasible (duty zeros).
    success : bool
        True for ``"optimal"`` and ``"bound_relaxed"`` (a checked point).
    demand : numpy.ndarray, shape (3,)
        ``(P_T [N], M_X [N·m], M_Z [N·m])``.
    achieved : numpy.ndarray, shape (3,)
        What ``duty`` gives (linear cycle model).
    tracking_error : numpy.ndarray, shape (3,)
        ``achieved - demand``.
    momentum_after : numpy.ndarray, shape (3,)
        :math:`H + T_T(\\tau_{thr} + \\tau_{dist})` [N·m·s].
    momentum_excess : float
        How far the bound had to be relaxed [N·m·s] (0 when met).
    residual : float
        Largest scaled constraint violation of the backend's point.
    propellant : float
        Propellant of the cycle :math:`\\sum k_i T_T P_i / (I_{sp} g_0)`
        [kg].
    solve_time : float
        Wall time of the backend call [s].
    solver : str
        Backend name.
    iterations : int
        Iterations the backend reports (-1 if it does not say).
    extras : dict
        The backend's own status text and anything else it reports.
    """

    duty: np.ndarray
    status: str
    success: bool
    demand: np.ndarray
    achieved: np.ndarray
    tracking_error: np.ndarray
    momentum_after: np.ndarray
    momentum_excess: float
    residual: float
    propellant: float
    solve_time: float
    solver: str
    iterations: int = -1
    extras: dict[str, Any] = field(default_factory=dict)


_NUMBERS = (int, float, np.integer, np.floating)


def _fill_theta(th: np.ndarray, P_T, M, H, tau_dist) -> bool:
    """Write (P_T, M, H, tau_dist) into ``th`` (9,); False if they misfit.

    Shapes must match exactly: a scalar is never broadcast to a vector.
    """
    if isinstance(P_T, bool) or not isinstance(P_T, _NUMBERS):
        return False        # (a 0-d array goes the slow way)
    try:
        if len(M) != 2 or len(H) != 3 or len(tau_dist) != 3:
            return False
        th[0] = P_T
        th[1:3] = M
        th[3:6] = H
        th[6:9] = tau_dist
    except (TypeError, ValueError):
        return False
    return True


class DutyCycleAllocator:
    """Duty-cycle QP of a thruster set, built once and solved per cycle.

    Safe to share between threads: each call holds the allocator's lock
    (backend, fast-path buffers and warm start are per object).

    Per cycle, with demand :math:`(P_T, M_X, M_Z)`, wheel momentum H and
    disturbance torque estimate :math:`\\tau_{dist}`:

    .. math::
        \\min_{k\\in[0,1]^n}\\ \\sum_i \\frac{k_i T_T P_i}{I_{sp} g_0}
        \\ (+\\ \\text{tracking})\\quad
        \\text{s.t.}\\ \\ \\sum_i k_i P_{y,i} = P_T,\\ \\
        H + T_T(M_{thr} k + \\tau_{dist}) \\in \\mathcal{B}(h_{max})

    (theory §2; details and scaling in `build_qp`). It generalises
    eq. (2) (``P_T != 0``, ``M = -K_{unl} H / T_T``) and eqs. (8)-(9)
    (``P_T = 0``): where they stay inside [0, 1] the hard-tracking QP
    returns the same duties; where they must clip, the QP returns the
    best cycle that keeps the momentum bound. The duties it returns are
    continuous; pass them through `MinOnTimeCarry` to respect the valves'
    minimum on-time without losing impulse (the remainder is carried to
    the next cycle).

    Parameters
    ----------
    unit : ThrusterSet
        The thrusters (uses its K_p, pressure and Isp at build time).
    cycle : float
        Cycle length T_T [s] (>= ``unit.min_on_time``).
    h_max : float
        Momentum bound [N·m·s] (0.012 in [4]'s Table 2).
    solver : str
        Backend name (default ``"daqp"``: DAQP called directly, exact);
        see `available_solvers`. When another backend fails on a feasible
        cycle, DAQP answers it and the result's ``extras`` say so
        (``"fallback"``, ``"failed_backend"``), never all-zero duties.
        Tolerances per backend are in `thrusters.qp.solvers` (OSQP:
        eps_abs = eps_rel = 1e-6 with polishing, exact to the reference;
        qrqp: defaults, residuals checked; piqp 1e-12; clarabel 1e-12;
        daqp: primal_tol 1e-10; quadprog: defaults).
    tracking : {"hard", "weighted"}
        ``"hard"``: thrust and both torques are equalities; ``"weighted"``:
        thrust hard, torques in the cost with ``torque_weight``.
    bound : {"box", "norm"}
        Box :math:`|H_X|, |H_Z| \\le h_{max}` or the ``n_facets``-gon
        inscribed in the circle :math:`\\|(H_X, H_Z)\\| \\le h_{max}`.
    n_facets : int
        Facets of the norm bound.
    torque_weight, propellant_weight, regularization, slack_weight : float
        Cost weights (see `build_qp`).
    solver_options : dict, optional
        Backend options over the defaults; names the backend does not
        take raise `InvalidValueError` (`adcs_common.solver_options`).
    """

    def __init__(self, unit: ThrusterSet, cycle: float, h_max: float, *,
                 solver: str = EXACT_SOLVER, tracking: str = "hard",
                 bound: str = "box", n_facets: int = 16,
                 torque_weight: float = 1e3, propellant_weight: float = 1.0,
                 regularization: float = 1e-4, slack_weight: float = 1e4,
                 solver_options: dict | None = None) -> None:
        check_instance(unit, ThrusterSet, "unit")
        self._lock = new_lock()
        t0 = time.perf_counter()
        self.unit = unit
        self.cycle = unit.check_cycle(cycle)
        self.h_max = as_finite_scalar(h_max, "h_max")
        check_positive(self.h_max, "h_max")
        solver_options = as_options(solver_options)
        self.tracking = tracking
        self.qp = build_qp(unit, cycle, h_max, tracking=tracking,
                           bound=bound, n_facets=n_facets,
                           torque_weight=torque_weight,
                           propellant_weight=propellant_weight,
                           regularization=regularization,
                           slack_weight=slack_weight)
        self.solver = solver
        self.backend = make_backend(solver, self.qp.nx, self.qp.A.shape[0],
                                    self.qp.n_eq, solver_options)
        self._exact = None
        # rows without a lower / upper bound (their stand-in ±INF stays
        # beyond INF/2 for any parameters), ±inf for the backends
        self._l_absent = infinite_bounds(self.qp.l0) == -np.inf
        self._u_absent = infinite_bounds(self.qp.u0) == np.inf
        F = unit.force_matrix()
        Mt = unit.torque_matrix()
        self._track = np.vstack([F[THRUST_AXIS], Mt[TORQUE_AXES[0]],
                                 Mt[TORQUE_AXES[1]]])
        self._torque = Mt
        self._prop = self.cycle * unit.propellant_rate()
        # every reported quantity is affine in z = (k, theta):
        # rows: achieved (3), tracking error (3), H after (3), kg (1)
        n = unit.n
        W = np.zeros((10, n + N_THETA))
        W[0:3, :n] = self._track
        W[3:6, :n] = self._track
        W[3:6, n:n + 3] = -np.eye(3)
        W[6:9, :n] = self.cycle * Mt
        W[6:9, n + 3:n + 6] = np.eye(3)
        W[6:9, n + 6:n + 9] = self.cycle * np.eye(3)
        W[9, :n] = self._prop
        self._W = W
        qp = self.qp
        self._lb, self._ub = qp.lb, qp.ub.copy()
        # residual rows r = R x + r0 + Rth theta: (l - Ax, Ax - u,
        # lb - x, x - ub), whose max is the largest violation
        eye = np.eye(qp.nx)
        self._R = np.vstack([-qp.A, qp.A, -eye, eye])
        self._Rth = np.vstack([qp.Lm, -qp.Um, np.zeros((2 * qp.nx,
                                                         N_THETA))])
        self._set_r0()
        self._steady = unit.steady_thrust
        self._scale = np.ones(unit.n)
        self._pressure = unit.pressure
        self._theta = np.zeros(N_THETA)
        self._fast = None            # built by the first duty_fast call
        #: Cycles `duty_fast` handed to `solve` (check failed or no plugin).
        self.fast_fallbacks = 0
        self.build_time = time.perf_counter() - t0

    # ------------------------------------------------------------------
    @synchronized
    def theta(self, P_T: ArrayLike, M: ArrayLike = (0.0, 0.0),
              H: ArrayLike = (0.0, 0.0, 0.0),
              tau_dist: ArrayLike = (0.0, 0.0, 0.0)) -> np.ndarray:
        """Parameter vector (P_T, M_X, M_Z, H, tau_dist), validated.

        Raises
        ------
        ShapeError, InvalidValueError
            An argument has the wrong shape or is not finite (the message
            names it).
        """
        th = self._theta
        if not _fill_theta(th, P_T, M, H, tau_dist):
            for value, name, shape in ((P_T, "P_T", ()), (M, "M", (2,)),
                                       (H, "H", (3,)),
                                       (tau_dist, "tau_dist", (3,))):
                as_finite_array(value, name, shape)
            raise ShapeError("P_T, M, H, tau_dist do not fit (9,)")
        if not np.isfinite(th).all():
            for value, name in ((P_T, "P_T"), (M, "M"), (H, "H"),
                                (tau_dist, "tau_dist")):
                as_finite_array(value, name)
        return th.copy()

    @synchronized
    def set_pressure(self, pressure: float) -> None:
        """Use the inlet pressure p_in [Pa] for the next cycles (eq. 1).

        Thrusts scale by :math:`s_i = (a_i p + b_i)/(a_i p_0 + b_i)`. The
        QP is solved in impulse units :math:`\\tilde k_i = s_i k_i` (the
        built matrices and the propellant cost stay valid), with the upper
        bounds :math:`\\tilde k_i \\le s_i`; no rebuild is needed.
        """
        p = as_finite_array(pressure, "pressure", ())
        if p < 0:
            raise InvalidValueError(
                f"pressure must be non-negative [Pa], got {float(p)}")
        u = self.unit
        scale = (u.pressure_slope * float(p) + u.thrust_offset) / self._steady
        if np.any(scale <= 0):
            dead = [u.names[i] for i in np.flatnonzero(scale <= 0)]
            raise InvalidValueError(
                f"pressure = {float(p)} Pa gives no thrust (eq. 1) for "
                f"engine(s) {dead}")
        self._scale = scale
        self._pressure = float(p)
        self._ub[:-1] = scale
        self._set_r0()
        if self._fast:
            self._fast.kmax[:] = scale

    def _set_r0(self) -> None:
        qp = self.qp
        self._r0 = np.concatenate([qp.l0, -qp.u0, qp.lb, -self._ub])

    @property
    def pressure(self) -> float:
        """Inlet pressure the allocator currently uses [Pa]."""
        return self._pressure

    @synchronized
    def solve(self, P_T: float, M: ArrayLike = (0.0, 0.0),
              H: ArrayLike = (0.0, 0.0, 0.0),
              tau_dist: ArrayLike = (0.0, 0.0, 0.0)) -> DutyAllocation:
        """Allocate one cycle (at the pressure of `set_pressure`).

        Parameters
        ----------
        P_T : float
            Required mean thrust along +Y [N] (0: reorientation/hold).
        M : array_like, shape (2,)
            Demanded mean torques (M_X, M_Z) [N·m].
        H : array_like, shape (3,)
            Wheel momentum at the start of the cycle [N·m·s].
        tau_dist : array_like, shape (3,)
            Disturbance torque estimate over the cycle [N·m].

        Returns
        -------
        DutyAllocation
        """
        th = self.theta(P_T, M, H, tau_dist)
        return self.solve_theta(th)

    @synchronized
    def solve_theta(self, th: np.ndarray) -> DutyAllocation:
        """`solve` with a ready parameter vector (9,) (no validation).

        ``th`` is not copied (the result's ``demand`` is a view of it):
        pass a fresh array, as `theta` returns.
        """
        t0 = time.perf_counter()
        x, sol, residual = self._backend_point(self.backend, th)
        extras: dict[str, Any] = {}
        if x is None and sol.status != "infeasible" and \
                self.backend.name != EXACT_SOLVER:
            # an iterative backend failed: the exact one answers, and the
            # result says so (a feasible cycle never gets zero duties)
            failed = sol
            x, sol, residual = self._backend_point(self._exact_backend(), th)
            extras = {"fallback": EXACT_SOLVER,
                      "failed_backend": self.backend.name,
                      "failure": failed.extras.get("backend_status",
                                                   failed.status)}
        solve_time = time.perf_counter() - t0
        status = sol.status
        if x is None:
            status = ("infeasible" if status == "infeasible"
                      or not self._feasible(th) else "failed")
            kt = np.zeros(self.unit.n)
            slack = 0.0
        else:
            kt = x[:-1].clip(0.0, self._ub[:-1])     # impulse units
            slack = max(float(x[-1]), 0.0)
            status = "optimal" if slack <= SLACK_TOL else "bound_relaxed"
        sol.extras.update(extras)
        return self._result(kt, th, status, slack, residual, solve_time,
                            sol)

    def _backend_point(self, backend, th: np.ndarray):
        """``(x or None, QPSolution, residual)`` of ``backend`` at ``th``.

        ``x`` is None unless the point keeps every constraint to
        `RESIDUAL_TOL` (scaled rows).
        """
        qp = self.qp
        q, l, u = qp.vectors(th)
        ub = self._ub
        if backend.name.startswith("qpsolvers:"):
            # no finite bound on the slack: ProxQP and Clarabel fail on
            # this QP with one (measured), the others do not care
            ub = ub.copy()
            ub[-1] = np.inf
        l[self._l_absent] = -np.inf
        u[self._u_absent] = np.inf
        sol = backend.solve(QP(qp.P, q, qp.A, l, u, qp.lb, ub, qp.n_eq))
        if sol.x is None or not sol.success:
            # no point, or one that failed the optimality certificate
            return None, sol, np.inf
        residual = float((self._R @ sol.x + self._Rth @ th
                          + self._r0).max())
        return (sol.x if residual <= RESIDUAL_TOL else None), sol, residual

    def _exact_backend(self):
        if self._exact is None:
            self._exact = make_backend(EXACT_SOLVER, self.qp.nx,
                                       self.qp.A.shape[0], self.qp.n_eq,
                                       None)
        return self._exact

    def casadi_function(self, plugin: str = "qrqp",
                        options: dict | None = None) -> Any:
        """Return this QP as a casadi Function for code generation.

        Returns
        -------
        casadi.Function
            ``duty_qp(theta[9], kmax[n]) -> (x[n+1], violation)`` with
            ``theta = (P_T, M_X, M_Z, H[3], tau_dist[3])`` (see `theta`),
            ``kmax`` ones at the build pressure (see `set_pressure`),
            ``x = (k, s)``; ``Function.generate`` gives self-contained C
            with ``plugin="qrqp"``. Check ``violation`` (qrqp can report
            success on a violated point).
        """
        from .casadi_functions import conic_function

        return conic_function(self.qp, plugin, options)

    @synchronized
    def duty(self, P_T: float, M: ArrayLike = (0.0, 0.0),
             H: ArrayLike = (0.0, 0.0, 0.0),
             tau_dist: ArrayLike = (0.0, 0.0, 0.0)) -> np.ndarray:
        """Duty fractions only (raises unless found; see `duty_fast`)."""
        res = self.solve(P_T, M, H, tau_dist)
        if not res.success:
            from adcs_common.exceptions import InfeasibleError
            raise InfeasibleError(
                f"duty-cycle QP: status {res.status!r} for demand "
                f"{res.demand}", problem=self.qp, result=res)
        return res.duty

    @synchronized
    def duty_fast(self, P_T: float, M: ArrayLike = (0.0, 0.0),
                  H: ArrayLike = (0.0, 0.0, 0.0),
                  tau_dist: ArrayLike = (0.0, 0.0, 0.0),
                  out: np.ndarray | None = None
                  ) -> np.ndarray:
        """Duty fractions of one cycle, fast path (same answer as `duty`).

        One `casadi.Function.buffer` trigger runs the whole allocation
        (`backends.casadi_conic_.duty_function`: the equality rows
        eliminated in closed form, CasADi's 'daqp' conic with primal_tol
        1e-10 on the rest, whatever ``solver`` the allocator was built
        with, then a KKT certificate of its point (constraint violation
        <= `RESIDUAL_TOL`, complementarity and stationarity <= 1e-9), a
        NaN check and the duties in [0, 1]), with no result object. The
        certificate is enforced: when it fails, is NaN, or an argument is
        not finite or has the wrong type, the cycle goes through `solve` (the
        allocator's backend, the full checks and statuses; counted in
        ``fast_fallbacks``), so it never returns a wrong or NaN duty
        silently. The Function is built by the first call (a few ms).

        Parameters
        ----------
        P_T, M, H, tau_dist
            As in `solve`.
        out : numpy.ndarray, shape (n,), optional
            Write the duties there (no allocation) and return it;
            otherwise a new array is returned.

        Returns
        -------
        numpy.ndarray, shape (n,)
            Duty fractions in [0, 1] (at the pressure of `set_pressure`).

        Raises
        ------
        InfeasibleError
            Status neither ``"optimal"`` nor ``"bound_relaxed"`` (as
            `duty`).
        ShapeError, InvalidValueError
            A bad argument (as `solve`).
        """
        f = self._fast
        if f is None:
            f = self._make_fast()
        if f:
            # a bad argument: solve names it
            if _fill_theta(f.theta, P_T, M, H, tau_dist):
                chk = f.check
                chk[0] = np.nan       # a failed evaluation leaves NaN
                try:
                    f.trigger()
                except RuntimeError:  # CasADi raised: chk stays NaN
                    pass
                if chk[0] <= 1.0:     # certified; False for NaN
                    if out is None:
                        return f.duty.copy()
                    out[:] = f.duty
                    return out
        self.fast_fallbacks += 1
        duty = self.duty(P_T, M, H, tau_dist)
        if out is None:
            return duty
        out[:] = duty
        return out

    def _make_fast(self):
        """Build the fast path's Function, or False without the plugin."""
        import casadi as ca

        from .casadi_functions import FAST_PLUGIN, FastDuty

        self._fast = (FastDuty(self.qp, self._ub[:-1],
                               viol_tol=RESIDUAL_TOL)
                      if ca.has_conic(FAST_PLUGIN) else False)
        return self._fast

    # ------------------------------------------------------------------
    def _result(self, kt, th, status, slack, residual, solve_time,
                sol=None):
        y = self._W @ np.concatenate((kt, th))
        # kt lies in [0, scale]: the duty kt / scale lies in [0, 1]
        duty = kt if self._pressure == self.unit.pressure else np.minimum(
            kt / self._scale, 1.0)
        return DutyAllocation(
            duty=duty, status=status,
            success=status in ("optimal", "bound_relaxed"), demand=th[:3],
            achieved=y[0:3], tracking_error=y[3:6], momentum_after=y[6:9],
            momentum_excess=slack * self.h_max, residual=residual,
            propellant=float(y[9]), solve_time=solve_time,
            solver=self.solver,
            iterations=-1 if sol is None else sol.iterations,
            extras={} if sol is None else dict(sol.extras))

    def _feasible(self, th: np.ndarray) -> bool:
        """Phase-1 LP (HiGHS via scipy): tell if the equalities are met."""
        qp = self.qp
        _, l, u = qp.vectors(th)
        eq = slice(0, qp.n_eq)
        ub = np.minimum(self._ub, 1e9)
        res = linprog(np.zeros(qp.nx), A_eq=qp.A[eq], b_eq=l[eq],
                      bounds=list(zip(qp.lb, ub)), method="highs")
        return res.status == 0


@dataclass
class MinOnTimeCarry:
    """Min on-time without losing impulse: carry the remainder.

    Per engine, the demanded duty plus the carried remainder is fired
    when it reaches half the minimum pulse, rounded up to the minimum
    pulse if shorter; what was not fired (positive or negative) is
    carried to the next cycle. The commanded duties over any run then sum
    to the demanded ones up to the final carry, which stays within
    ``±min_on_time / (2 T_T)``. For opposed pairs (same line of action),
    equal carries of both engines cancel (no force, no torque) and are
    dropped.

    Attributes
    ----------
    unit : ThrusterSet
        Provides ``min_on_time`` and ``pairs``.
    cycle : float
        Cycle length T_T [s].
    carry : numpy.ndarray, shape (n,)
        Remainder carried per engine [duty fraction].
    """

    unit: ThrusterSet
    cycle: float
    # None by default: __post_init__ stores zeros(n)
    carry: np.ndarray = field(default=None)  # type: ignore[arg-type]

    def __post_init__(self) -> None:
        """Validate the cycle and start with no carry."""
        self.cycle = self.unit.check_cycle(self.cycle)
        if self.carry is None:
            self.carry = np.zeros(self.unit.n)

    @property
    def min_duty(self) -> float:
        """Minimum pulse as a duty fraction, ``min_on_time / T_T``."""
        return self.unit.min_on_time / self.cycle

    def apply(self, duty: ArrayLike) -> np.ndarray:
        """Commanded duties for demanded ``duty`` (n,), updating the carry.

        Raises
        ------
        InvalidValueError
            ``duty`` is not finite or leaves [0, 1].
        """
        k = as_finite_array(duty, "duty", (self.unit.n,))
        if np.any(k < -1e-12) or np.any(k > 1 + 1e-12):
            raise InvalidValueError(f"duty must lie in [0, 1], got {k}")
        total = k + self.carry
        for i, j in self.unit.pairs:
            common = min(total[i], total[j])
            if common > 0:
                total[i] -= common
                total[j] -= common
        kmin = self.min_duty
        fire = total >= 0.5 * kmin
        cmd = np.where(fire, np.clip(np.maximum(total, kmin), 0.0, 1.0),
                       0.0)
        self.carry = total - cmd
        return cmd
