"""Bounded QP wheel allocator: build once, allocate every control step."""

from __future__ import annotations

import time
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError, SolverError
from adcs_common.threads import new_lock, synchronized
from adcs_common.qp import QP, Backend, QPSolution, make_backend
from adcs_common.validation import (
    as_options,
    as_finite_array,
    as_finite_scalar,
    as_vector,
    check_positive,
)

from ..arrays import WheelArray
from ..electrical import WheelMotor
from .batch import BatchKernel, allocate_rows
from .fast import FastWheelQP
from .result import BatchAllocation, WheelAllocation
from .solvers import available_solvers
from .problem import (
    facet_normals,
    flat_max_scale,
    max_scale,
    pin_to_face,
    set_normals,
    torque_bounds,
)

SATURATION_MODES = ("scale", "least_squares")
#: The exact backend: the default, and the one a failed iterative backend
#: hands its problem to (the result's ``extras["fallback"]`` says so).
EXACT_SOLVER = "daqp"
_LS_REGULARISATION = 1e-9
_EPIGRAPH_REGULARISATION = 1e-9
#: How a saturated target on the boundary of the attainable set is solved,
#: each step only if the backend failed the previous one: exactly on a
#: facet the feasible set of A m = α M is a face of the box, where
#: quadprog fails on about half of the demands and interior-point or ADMM
#: solvers (osqp, clarabel, proxqp) on a few per cent. ("margin", r) pulls
#: the target inside by the relative margin r; ("pin", 0) fixes the wheels
#: the facet determines (`pin_to_face`) and solves for the others exactly.
_BOUNDARY_STEPS = (("margin", 1e-9), ("pin", 0.0), ("margin", 1e-6))
#: Step lengths dt whose fast-path Function `allocate_fast` keeps (each
#: costs a few ms to build: the fast path is for a fixed control step).
_FAST_CACHE = 4


def _step_length(dt, h) -> float | None:
    """Validate ``dt`` [s] (positive, needs the wheel momenta ``h``)."""
    if dt is None:
        return None
    dt = as_finite_scalar(dt, "dt")
    if dt <= 0:
        raise InvalidValueError(f"dt must be positive, got {dt}")
    if h is None:
        raise InvalidValueError(
            "dt bounds the momentum after the step and needs "
            "wheel_momentum")
    return dt


class QPAllocator:
    r"""Bounded, weighted wheel-torque allocation by quadratic programming.

    Safe to share between threads: each call holds the allocator's lock
    (its backend and fast-path buffers are per object), so a shared
    allocator answers as from one thread; the lock costs under 0.1 µs.

    Each call solves

    .. math::
        \min_m \sum V_i m_i^2 + w_n \lVert m - m_d\rVert^2 + w_p P_e(m)
        \quad\text{s.t.}\quad A m = M,\;|m_i| \le m_{max,i},\;
        |h_i + m_i\,dt| \le h_{max,i},\; m_{failed} = 0

    ([1]'s weighted criterion with the wheels' limits). The
    null-space term drives wheel momenta towards ``momentum_target`` with
    ``m_d = -k (h - h_target)``; since A m = M is hard it acts only in the
    null space of A. The power term ``P_e`` is `WheelMotor`'s electrical
    power (winding loss plus mechanical power with partial regeneration),
    modelled exactly with N epigraph variables.

    A demand outside the attainable set is never an error and never NaN:
    with ``saturation="scale"`` (default) the result is the best
    direction-preserving torque (largest α <= 1 with A m = α M, α from the
    facets of the attainable zonotope); with ``"least_squares"`` it is the
    attainable torque closest to M. Either way ``status == "saturated"``.
    If the bounds exclude every point along M (a wheel over its momentum
    limit must brake), ``"scale"`` falls back to least squares.

    Parameters
    ----------
    array : WheelArray
        The wheels (failed wheels held at zero).
    weights : array_like (N,), optional
        Positive weights V_i (default ones; none when ``motor`` is given).
    solver : str
        QP backend, default ``"daqp"`` (DAQP called directly: an exact
        active-set method, a dependency of the toolbox); see
        `available_solvers`. With the default and 3–4 working wheels
        (no null-space term, power cost or least squares) the QP is
        answered by its exact closed form (``result.solver == "closed
        form"``, equal to DAQP to rounding, about 20 µs a call instead of
        50). When another backend fails on a demand, DAQP
        answers it and the result's ``extras`` say so (``"fallback"``,
        ``"failed_backend"``, ``"failure"``).
    saturation : {"scale", "least_squares"}
        Behaviour outside the attainable set.
    momentum_target : array_like (N,), optional
        Wheel momenta to drive towards [N·m·s] (null-space management).
    momentum_gain : float
        k [1/s] of the null-space term.
    momentum_weight : float
        w_n of the null-space term [1/(N·m)²].
    motor : WheelMotor, optional
        Adds the electrical power [W] to the cost (power-optimal).
    power_weight : float
        w_p [1/(W)] multiplying the power.
    solver_options : dict, optional
        Backend options; names it does not take raise `InvalidValueError`
        (`adcs_common.solver_options`).
    check_tol : float
        Relative tolerance of the checks applied to every solver answer.
    """

    def __init__(self, array: WheelArray, weights: ArrayLike | None = None,
                 solver: str = EXACT_SOLVER,
                 *, saturation: str = "scale",
                 momentum_target: ArrayLike | None = None,
                 momentum_gain: float = 0.1, momentum_weight: float = 1.0,
                 motor: WheelMotor | None = None, power_weight: float = 1.0,
                 solver_options: dict[str, Any] | None = None,
                 check_tol: float = 1e-6) -> None:
        self._lock = new_lock()
        if not isinstance(array, WheelArray):
            raise InvalidValueError(
                f"array must be a WheelArray, got {type(array).__name__}")
        array.require_full_rank()
        n = array.n_wheels
        self.array = array
        if weights is None:
            w = np.zeros(n) if motor is not None else np.ones(n)
        else:
            w = as_vector(weights, n, "weights")
            check_positive(w, "weights")
        self.weights = w
        if saturation not in SATURATION_MODES:
            raise InvalidValueError(
                f"saturation must be one of {SATURATION_MODES}, got "
                f"{saturation!r}")
        self.saturation = saturation
        self.momentum_target = None if momentum_target is None else \
            as_vector(momentum_target, n, "momentum_target")
        self.momentum_gain = as_finite_scalar(momentum_gain, "momentum_gain")
        self.momentum_weight = as_finite_scalar(momentum_weight,
                                                "momentum_weight")
        if self.momentum_gain < 0 or self.momentum_weight < 0:
            raise InvalidValueError(
                "momentum_gain and momentum_weight must be non-negative")
        if motor is not None and not isinstance(motor, WheelMotor):
            raise InvalidValueError(
                f"motor must be a WheelMotor, got {type(motor).__name__}")
        self.motor = motor
        self.power_weight = as_finite_scalar(power_weight, "power_weight")
        if self.power_weight < 0:
            raise InvalidValueError("power_weight must be non-negative")
        self.check_tol = as_finite_scalar(check_tol, "check_tol")
        if not 0.0 < self.check_tol < 1.0:
            raise InvalidValueError(
                f"check_tol must lie in (0, 1) (relative), got {check_tol!r}")
        self.solver = solver
        self.solver_options = as_options(solver_options)
        self._axes = array.working_axes
        self._active = array.active
        self._normals = facet_normals(self._axes[:, array.active])
        self._abs_na = np.abs(self._normals @ self._axes)
        self._static_cost: tuple[np.ndarray, np.ndarray] | None = None
        self._m_scale = float(np.max(array.m_max))
        self._nvar = 2 * n if motor is not None else n
        self._nrow = 3 + (2 * n if motor is not None else 0)
        self._backend = self._make_backend(self._nrow, 3)
        self._ls_backend: Backend | None = None
        self._ls_exact: Backend | None = None
        self._exact: Backend | None = None
        #: momentum bound of each working wheel (inf: failed, free)
        self._h_cap = np.where(array.active, array.h_max, np.inf)
        self._fast: dict[float | None, FastWheelQP | None] = {}
        self._batch: BatchKernel | None | Literal[False] = False
        #: Calls `allocate_fast` handed to `allocate` (see there).
        self.fast_fallbacks = 0
        #: Scale α reached by the last `allocate_fast` call.
        self.fast_alpha = float("nan")

    @property
    def fast_step_lengths(self) -> tuple:
        """Step lengths dt [s] whose `allocate_fast` Function is kept."""
        return tuple(self._fast)

    # ------------------------------------------------------------- helpers
    def _make_backend(self, k: int, n_eq: int) -> Backend:
        return make_backend(self.solver, self._nvar, k, n_eq,
                            self.solver_options, available_solvers())

    def _cost(self, h: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        depends_on_h = self.momentum_target is not None
        if self._static_cost is not None and (h is None or not depends_on_h):
            return self._static_cost
        n = self.array.n_wheels
        P = np.zeros((self._nvar, self._nvar))
        q = np.zeros(self._nvar)
        P[:n, :n] += 2.0 * np.diag(self.weights)
        if self.momentum_target is not None and h is not None:
            m_des = -self.momentum_gain * (h - self.momentum_target)
            P[:n, :n] += 2.0 * self.momentum_weight * np.eye(n)
            q[:n] -= 2.0 * self.momentum_weight * m_des
        if self.motor is not None:
            c = self.power_weight * self.motor.copper_coefficient()
            P[:n, :n] += 2.0 * c * np.eye(n)
            P[n:, n:] = _EPIGRAPH_REGULARISATION * np.eye(n)
            q[n:] = self.power_weight
        if h is None or not depends_on_h:
            self._static_cost = (P, q)
        return P, q

    def _power_rows(self, h: np.ndarray | None
                    ) -> tuple[np.ndarray, np.ndarray]:
        assert self.motor is not None   # power rows only with a motor
        n = self.array.n_wheels
        speed = np.zeros(n) if h is None else self.motor.speed(h)
        eta = self.motor.regen_efficiency
        eye = np.eye(n)
        rows = np.vstack([np.hstack([np.diag(speed), -eye]),
                          np.hstack([np.diag(eta * speed), -eye])])
        return rows, np.zeros(2 * n)

    def _data(self, P, q, C_eq, b_eq, lo, hi, h) -> QP:
        n = self.array.n_wheels
        lb = np.concatenate([lo, np.full(self._nvar - n, -np.inf)])
        ub = np.concatenate([hi, np.full(self._nvar - n, np.inf)])
        C = np.zeros((len(b_eq), self._nvar))
        C[:, :n] = C_eq
        l_rows, u_rows = b_eq, b_eq
        if self.motor is not None:
            rows, rhs = self._power_rows(h)
            C = np.vstack([C, rows])
            l_rows = np.concatenate([l_rows, np.full(len(rhs), -np.inf)])
            u_rows = np.concatenate([u_rows, rhs])
        return QP(P, q, C, l_rows, u_rows, lb, ub, len(b_eq))

    def _solve(self, backend: Backend, data: QP) -> QPSolution:
        res = backend.solve(data)
        if not res.success:
            raise SolverError(
                f"{backend.name} failed on the allocation QP "
                f"(status {res.status!r})", solver=backend.name, result=res)
        return res

    def _solve_steps(self, backend: Backend, steps, anchor, boundary,
                     normals, P, q, lo, hi, h):
        """Solve the QP of each boundary step in turn until one checks."""
        for step, margin in steps:
            target = anchor + (boundary - anchor) * (1.0 - margin)
            lo_s, hi_s = (lo, hi) if step == "margin" else pin_to_face(
                normals, self._axes, lo, hi, target)
            data = self._data(P, q, self._axes, target, lo_s, hi_s, h)
            try:
                res = self._solve(backend, data)
                m = self._check(res.x, target, lo_s, hi_s, backend.name)
                return res, m, target, lo_s, hi_s
            except SolverError:
                if (step, margin) == steps[-1]:
                    raise
        raise AssertionError("unreachable: steps is never empty")

    def _exact_backend(self) -> Backend | None:
        """DAQP for this QP (None when DAQP is the backend already)."""
        if self._backend.name == EXACT_SOLVER:
            return None
        if self._exact is None:
            self._exact = make_backend(EXACT_SOLVER, self._nvar, self._nrow,
                                       3, {}, available_solvers())
        return self._exact

    def _project(self, M, lo, hi, h) -> np.ndarray:
        """Attainable torque closest to M (least-squares fallback)."""
        n = self.array.n_wheels
        A = self._axes
        P, q = self._cost(h)
        scale = _LS_REGULARISATION / max(np.max(np.diag(P)[:n]), 1e-300)
        P = scale * P
        q = scale * q
        P[:n, :n] += 2.0 * A.T @ A
        q[:n] -= 2.0 * A.T @ M
        if self._ls_backend is None:
            self._ls_backend = self._make_backend(self._nrow - 3, 0)
        data = self._data(P, q, np.zeros((0, n)), np.zeros(0), lo, hi, h)
        try:
            res = self._solve(self._ls_backend, data)
        except SolverError:
            if self._backend.name == EXACT_SOLVER:
                raise
            # an iterative backend's projection failed its certificate:
            # the exact one projects (the result's extras say which)
            if self._ls_exact is None:
                self._ls_exact = make_backend(
                    EXACT_SOLVER, self._nvar, self._nrow - 3, 0, {},
                    available_solvers())
            res = self._solve(self._ls_exact, data)
        assert res.x is not None     # _solve returns successes only
        return A @ np.clip(res.x[:n], lo, hi)

    def _check(self, x, target, lo, hi, backend: str) -> np.ndarray:
        n = self.array.n_wheels
        m = x[:n]
        scale = max(self._m_scale, float(np.abs(target).max()))
        tol = self.check_tol * scale
        bound_err = float(np.maximum(lo - m, m - hi).max())
        eq_err = float(np.abs(self._axes @ m - target).max())
        if bound_err > tol or eq_err > tol:
            raise SolverError(
                f"{backend} returned a point that fails the checks: bound "
                f"violation {bound_err:.3g}, |A m - M| {eq_err:.3g} "
                f"(tolerance {tol:.3g})", solver=backend, result=x)
        return np.clip(m, lo, hi)

    # ---------------------------------------------------------------- API
    @synchronized
    def allocate_fast(self, torque: ArrayLike,
                      wheel_momentum: ArrayLike | None = None,
                      dt: float | None = None, *,
                      out: np.ndarray | None = None) -> np.ndarray:
        """Motor torques of one demand, fast path (same law as `allocate`).

        One `casadi.Function.buffer` trigger of `conic_allocator_function`
        (built on first use for each ``dt``, the last 4 kept: meant for a
        fixed control step; the weighted QP in closed form
        for 3–4 working wheels, the minimum-norm point or daqp for more;
        saturation by the largest attainable scale α), about 2 µs of
        solver instead of `allocate`'s ~200 µs of Python around one. Its
        answer passes the checks `allocate` applies to every backend
        (bounds and ``A m = α M`` within ``check_tol``) or the call goes
        through `allocate` (counted in ``fast_fallbacks``), as do
        allocators with a null-space momentum term, a power cost or
        ``saturation="least_squares"``, and bad input (`allocate` names
        it: a scalar or wrong-length demand, NaN or inf in the torque or
        momentum). A working wheel beyond its momentum bound (it must
        brake; where `allocate` may take its least-squares fallback) sends
        the call through `allocate` too. So it accepts exactly what
        `allocate` accepts, answers the same, and never returns a NaN or a
        bound-breaking torque.

        Parameters
        ----------
        torque, wheel_momentum, dt
            As `allocate` (``dt`` needs ``wheel_momentum``).
        out : numpy.ndarray, shape (N,), optional
            Write the torques there and return it.

        Returns
        -------
        numpy.ndarray, shape (N,)
            Motor torques m [N·m]; `fast_alpha` holds the scale reached
            (1 unless saturated).
        """
        fast = self._fast[dt] if dt in self._fast else self._make_fast(
            dt, wheel_momentum)
        if fast is not None and (dt is None) == (wheel_momentum is None) \
                and fast.load(torque, wheel_momentum, self._h_cap):
            fast.check[0] = np.nan
            try:
                fast.trigger()
            except RuntimeError:          # the conic raised: NaN
                pass
            if fast.check[0] <= fast.tol:     # False for NaN
                self.fast_alpha = float(fast.alpha[0])
                if out is None:
                    return fast.m.copy()
                out[:] = fast.m
                return out
        self.fast_fallbacks += 1
        res = self.allocate(torque, wheel_momentum, dt)
        self.fast_alpha = res.alpha
        if out is None:
            return res.torques
        out[:] = res.torques
        return out

    def _make_fast(self, dt: float | None, wheel_momentum: ArrayLike | None
                   ) -> FastWheelQP | None:
        """Build (or refuse, None) the fast path for ``dt``."""
        fast = None
        eligible = (self.momentum_target is None and self.motor is None
                    and self.saturation == "scale")
        try:
            dt_ok = dt is None or (as_finite_scalar(dt, "dt") > 0
                                   and wheel_momentum is not None)
        except InvalidValueError:
            dt_ok = False
        if eligible and dt_ok:
            fast = FastWheelQP(self.array, self.weights, dt,
                                self.check_tol * self._m_scale
                                * self.array.n_wheels)
        if dt_ok:                    # a bad dt is not cached
            while len(self._fast) >= _FAST_CACHE:   # the oldest dt goes
                self._fast.pop(next(iter(self._fast)))
            self._fast[dt] = fast
        return fast

    @synchronized
    def allocate(self, torque: ArrayLike,
                 wheel_momentum: ArrayLike | None = None,
                 dt: float | None = None) -> WheelAllocation:
        """Allocate one demanded array torque.

        Parameters
        ----------
        torque : array_like (3,)
            Demanded array torque M [N·m] (body frame).
        wheel_momentum : array_like (N,), optional
            Current wheel momenta h [N·m·s] (for the momentum bound, the
            null-space term and the wheel speeds of the power cost).
        dt : float, optional
            Step length [s]; with ``wheel_momentum`` it bounds the
            momentum after the step.

        Returns
        -------
        WheelAllocation

        Raises
        ------
        ShapeError, InvalidValueError
            Bad arguments (NaN/inf, wrong shape, non-positive dt).
        SolverError
            The backend failed or returned a point that fails the checks.
        """
        t0 = time.perf_counter()
        n = self.array.n_wheels
        M = as_finite_array(torque, "torque", (3,))
        h = None if wheel_momentum is None else as_vector(
            wheel_momentum, n, "wheel_momentum")
        dt = _step_length(dt, h)
        lo, hi, _ = torque_bounds(self.array, h, dt, self._active)
        closed = self._closed_form(M, h, dt, lo, hi, t0)
        if closed is not None:
            return closed
        normals = set_normals(self.array, lo, hi, self._normals, self._active)
        # a flat set (the free wheels span less than 3-D) is approached
        # from its centre, which lies in its plane
        anchor = np.zeros(3) if normals is not None else \
            self._axes @ ((lo + hi) / 2.0)
        alpha = flat_max_scale(self._axes, lo, hi, M) if normals is None \
            else max_scale(normals, self._axes, lo, hi, M,
                           self._abs_na if normals is self._normals else None)
        if alpha is not None and alpha >= 1.0:
            mode, status = "exact", "optimal"
            boundary = M
        elif alpha is not None and self.saturation == "scale":
            mode, status = "scale", "saturated"
            boundary = alpha * M
        else:
            mode, status = "least_squares", "saturated"
            boundary = self._project(M, lo, hi, h)
            anchor = self._axes @ ((lo + hi) / 2.0)
        P, q = self._cost(h)
        steps = (("margin", 0.0),) if mode == "exact" else tuple(
            st for st in _BOUNDARY_STEPS
            if st[0] == "margin" or normals is not None)
        extras: dict[str, Any] = {}
        try:
            res, m, target, lo_s, hi_s = self._solve_steps(
                self._backend, steps, anchor, boundary, normals, P, q, lo,
                hi, h)
        except SolverError as exc:
            exact = self._exact_backend()
            if exact is None:
                raise
            # an iterative backend failed where the exact one may not:
            # answer, and say so
            res, m, target, lo_s, hi_s = self._solve_steps(
                exact, steps, anchor, boundary, normals, P, q, lo, hi, h)
            extras = {"fallback": exact.name,
                      "failed_backend": self._backend.name,
                      "failure": str(exc)}
        if mode != "exact":
            nm = float(M @ M)
            alpha = max(float(target @ M) / nm, 0.0) if nm > 0 else 0.0
        achieved = self._axes @ m
        after = None if dt is None else h + m * dt
        assert alpha is not None     # exact mode: alpha >= 1
        return WheelAllocation(
            torques=m, achieved=achieved, status=status,
            shortfall=M - achieved, alpha=float(alpha), mode=mode,
            solve_time=time.perf_counter() - t0,
            solver=self._backend.name, iterations=res.iterations,
            momentum_after=after,
            residual=float(max(np.max(np.maximum(lo_s - m, m - hi_s)),
                               np.max(np.abs(self._axes @ m - target)),
                               0.0)),
            extras={**res.extras, **extras})

    @synchronized
    def allocate_batch(self, torques: ArrayLike,
                       wheel_momentum: ArrayLike | None = None,
                       dt: float | None = None) -> BatchAllocation:
        """Allocate K demands at once (the same law as `allocate`).

        With the default exact backend, at most four working wheels,
        ``saturation="scale"`` and no momentum management or power cost
        the QP's exact closed form is
        evaluated for all rows in one numpy pass (`batch.BatchKernel`;
        over 10⁶ allocations per second, see ``benchmarks/allocation.py``)
        and checked like every answer of `allocate`; other rows (a wheel
        past its momentum bound, a row failing the check) and other
        allocators (another backend by name: its own answers) go through
        `allocate` one at a time. Row k equals
        ``allocate(torques[k], wheel_momentum[k], dt)`` to rounding.

        Parameters
        ----------
        torques : array_like (K, 3)
            Demanded array torques [N·m], one per row.
        wheel_momentum : array_like (K, N), optional
            Wheel momenta of each row [N·m·s].
        dt : float, optional
            Step length [s]; with ``wheel_momentum`` it bounds the
            momentum after the step.

        Returns
        -------
        BatchAllocation

        Raises
        ------
        ShapeError, InvalidValueError
            Bad arguments (NaN/inf, wrong shape, non-positive dt).
        SolverError
            A row handed to `allocate` failed there.
        """
        t0 = time.perf_counter()
        n = self.array.n_wheels
        M = as_finite_array(torques, "torques", (None, 3))
        h = None if wheel_momentum is None else as_finite_array(
            wheel_momentum, "wheel_momentum", (M.shape[0], n))
        dt = _step_length(dt, h)
        return allocate_rows(self, self._batch_kernel(), M, h, dt, t0)

    def _batch_kernel(self) -> BatchKernel | None:
        """Return the vectorised exact form (None where it does not apply)."""
        if self._batch is False:
            eligible = (self.momentum_target is None and self.motor is None
                        and self.saturation == "scale"
                        and self._backend.name == EXACT_SOLVER
                        and int(self._active.sum()) <= 4)
            self._batch = BatchKernel(self.array, self.weights) \
                if eligible else None
        return self._batch

    def _closed_form(self, M, h, dt, lo, hi, t0) -> WheelAllocation | None:
        """Answer of the exact closed form, checked; None if it does not apply.

        The default backend on 3–4 working wheels (`_batch_kernel`'s
        conditions): the QP's closed form through the `allocate_fast`
        Function, then the same check as every backend answer.
        """
        if self._batch_kernel() is None:
            return None
        fast = self._fast[dt] if dt in self._fast else self._make_fast(dt, h)
        h_in = None if dt is None else h
        if fast is None or not fast.load(M, h_in, self._h_cap):
            return None
        fast.trigger()
        alpha = float(fast.alpha[0])
        target = alpha * M
        if not fast.check[0] <= fast.tol:          # False for NaN
            return None
        try:
            m = self._check(fast.m.copy(), target, lo, hi, "closed form")
        except SolverError:
            return None
        achieved = self._axes @ m
        exact = alpha >= 1.0
        return WheelAllocation(
            torques=m, achieved=achieved,
            status="optimal" if exact else "saturated",
            shortfall=M - achieved, alpha=alpha,
            mode="exact" if exact else "scale",
            solve_time=time.perf_counter() - t0, solver="closed form",
            iterations=0, momentum_after=None if dt is None else h + m * dt,
            residual=float(max(np.max(np.maximum(lo - m, m - hi)),
                               np.max(np.abs(achieved - target)), 0.0)),
            extras={"method": "closed form (3-4 working wheels)"})
