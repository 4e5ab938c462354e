"""Rest-to-rest slews as NLPs: time-optimal and minimum-energy (SPEC 4).

The NLP is built with CasADi Opti on ``N`` intervals of length ``T/N``
with piecewise-constant controls, by multiple shooting (one RK4 step per
interval, ``substeps`` stages) or direct collocation (Legendre points of
degree 3). Limits are wheel-level, through the array — ``|m_i| <= m_max_i``
and ``|H_i| <= h_max_i`` — or a per-axis body torque box. Decision
variables are scaled by the limits and the eigenaxis time.

The time-optimal problem has a stationary point at the eigenaxis slew
(SOLVER_NOTES): started exactly there, IPOPT stops at the eigenaxis time.
The default initial guess is the eigenaxis slew perturbed by a smooth
off-axis rate and torque, which lets the solver leave it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from adcs_common.exceptions import (
    InvalidValueError,
    SolverError,
    SolverNotFound,
)
from adcs_common.validation import as_finite_scalar, as_vector, check_positive
from allocation import WheelArray, min_norm_gains

from .attitude import quat_conj, quat_mul, rotation_between
from .laws import _unit_quat, eigenaxis_slew
from .models import SpacecraftModel, check_inertia, rigid_spacecraft
from .trajectory import SlewTrajectory

__all__ = [
    "NLP_SOLVERS",
    "TRANSCRIPTIONS",
    "available_nlp_solvers",
    "min_energy_slew",
    "time_optimal_slew",
]

#: Transcriptions of the slew NLP.
TRANSCRIPTIONS = ("multiple_shooting", "collocation")

_QUIET_SQP = {"record_time": True, "print_header": False,
              "print_iteration": False, "print_status": False,
              "print_time": False, "qpsol": "qpoases",
              "qpsol_options": {"printLevel": "none", "error_on_fail": False,
                                "sparse": True},
              "convexify_strategy": "regularize", "max_iter": 200}

#: Name -> (CasADi nlpsol plugin, default options) of the NLP solvers.
NLP_SOLVERS: dict[str, tuple[str, dict]] = {
    "ipopt": ("ipopt", {"print_time": False, "record_time": True,
                        "ipopt": {"print_level": 0, "sb": "yes",
                                  "max_iter": 1000, "tol": 1e-8}}),
    "sqpmethod": ("sqpmethod", _QUIET_SQP),
}


def available_nlp_solvers() -> tuple[str, ...]:
    """Names in `NLP_SOLVERS` whose CasADi plugin loads here."""
    return tuple(n for n, (plugin, _) in NLP_SOLVERS.items()
                 if ca.has_nlpsol(plugin))


def _solver_entry(name: str) -> tuple[str, dict]:
    if not isinstance(name, str) or name not in NLP_SOLVERS:
        raise SolverNotFound(
            str(name), available_nlp_solvers(),
            hint="the slew NLPs use CasADi's nlpsol plugins; "
                 "pip install casadi brings ipopt and sqpmethod")
    plugin, opts = NLP_SOLVERS[name]
    if not ca.has_nlpsol(plugin):
        raise SolverNotFound(name, available_nlp_solvers(),
                             hint=f"CasADi plugin {plugin!r} is missing")
    return plugin, opts


def _merge(base: dict, extra: dict) -> dict:
    out = dict(base)
    for k, v in extra.items():
        out[k] = (_merge(out[k], v) if isinstance(v, dict)
                  and isinstance(out.get(k), dict) else v)
    return out


@dataclass(frozen=True, eq=False)
class _Setup:
    model: SpacecraftModel
    q0: np.ndarray
    qf: np.ndarray
    h0: np.ndarray
    u_max: np.ndarray
    h_max: np.ndarray | None
    w_scale: float
    rate_max: float | None
    T_eig: float
    eig_axis: np.ndarray


def _setup(inertia, q0, qf, wheels, torque_max, h0, rate_max) -> _Setup:
    J = check_inertia(inertia)
    q0 = _unit_quat(q0, "q0")
    qf = _unit_quat(qf, "qf")
    if np.dot(q0, qf) < 0:
        qf = -qf
    model = rigid_spacecraft(J, wheels, torque_max=torque_max)
    if rate_max is not None:
        rate_max = as_finite_scalar(rate_max, "rate_max")
        check_positive(rate_max, "rate_max")
    eig = eigenaxis_slew(J, q0, qf, wheels=wheels, torque_max=torque_max,
                         rate_max=rate_max)
    if wheels is not None:
        h0 = (np.zeros(wheels.n_wheels) if h0 is None
              else as_vector(h0, wheels.n_wheels, "h0"))
        u_max = np.array(wheels.m_max)
        h_max = np.array(wheels.h_max)
        if np.any(np.abs(h0) > h_max):
            raise InvalidValueError(
                f"h0 must lie within ±h_max = {h_max}, got {h0}")
    else:
        if h0 is not None:
            raise InvalidValueError("h0 is only for a model with wheels")
        h0 = np.zeros(0)
        u_max = np.array(model.torque_max)
        h_max = None
    w_scale = max(eig.peak_rate, 1e-12) if eig.T > 0 else 1.0
    return _Setup(model, q0, qf, h0, u_max, h_max, w_scale, rate_max,
                  max(eig.T, 1e-9), eig.axis)


def _check_common(N: int, transcription: str, substeps: int) -> None:
    if not isinstance(N, (int, np.integer)) or N < 2:
        raise InvalidValueError(f"N must be an integer >= 2, got {N!r}")
    if transcription not in TRANSCRIPTIONS:
        raise InvalidValueError(
            f"transcription must be one of {TRANSCRIPTIONS}, got "
            f"{transcription!r}")
    if not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise InvalidValueError(
            f"substeps must be an integer >= 1, got {substeps!r}")


def _guess(s: _Setup, N: int, T: float, kind: str, perturbation: float,
           seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the initial guess (X (nx, N+1), U (nu, N)), physical units."""
    model = s.model
    J = model.inertia
    t = np.linspace(0.0, T, N + 1)
    tm = 0.5 * (t[:-1] + t[1:])
    e, theta = rotation_between(s.q0, s.qf)
    if kind == "eigenaxis":
        eig = eigenaxis_slew(J, s.q0, s.qf, wheels=model.wheels,
                             torque_max=model.torque_max,
                             rate_max=s.rate_max)
        scale = eig.T / T
        th, rate, _ = eig.profile(t * scale)
        rate = rate * scale
        acc = eig.profile(tm * scale)[2] * scale ** 2
    else:  # smooth cubic rest-to-rest profile over T
        sg = t / T
        th = theta * (3 * sg ** 2 - 2 * sg ** 3)
        rate = theta * (6 * sg - 6 * sg ** 2) / T
        sm = tm / T
        acc = theta * (6 - 12 * sm) / T ** 2
    rng = np.random.default_rng(seed)
    if perturbation > 0:
        # smooth off-axis rate, consistent torque: breaks the symmetry
        d = rng.normal(size=3)
        d -= (d @ e) * e
        d /= np.linalg.norm(d)
        amp = perturbation * max(np.max(np.abs(rate)), 1e-12)
        d_rate = amp * np.sin(np.pi * t / T)[:, None] * d
        d_acc = (amp * np.pi / T * np.cos(np.pi * tm / T))[:, None] * d
    else:
        d_rate = np.zeros((N + 1, 3))
        d_acc = np.zeros((N, 3))
    w = np.outer(rate, e) + d_rate
    wdot = np.outer(acc, e) + d_acc
    dq = np.column_stack([np.cos(th / 2), np.outer(np.sin(th / 2), e)])
    q = np.array([quat_mul(s.q0, d) for d in dq])
    body = (J @ wdot.T).T  # body torque needed, gyroscopic part ignored
    if model.wheels is None:
        U = np.clip(body, -s.u_max, s.u_max)
        X = np.column_stack([q, w])
    else:
        G = min_norm_gains(model.wheels)
        m = -(G @ body.T).T  # -A m = J ω̇
        U = np.clip(m, -s.u_max, s.u_max)
        h = s.h0 + np.vstack([np.zeros(model.n_wheels),
                              np.cumsum(U * (T / N), axis=0)])
        h = np.clip(h, -s.h_max, s.h_max)
        X = np.column_stack([q, w, h])
    return X.T, U.T


def _collocation_coefficients(d: int = 3):
    tau = np.append(0, ca.collocation_points(d, "legendre"))
    C = np.zeros((d + 1, d + 1))
    D = np.zeros(d + 1)
    B = np.zeros(d + 1)
    for j in range(d + 1):
        p = np.poly1d([1.0])
        for r in range(d + 1):
            if r != j:
                p *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        D[j] = p(1.0)
        dp = np.polyder(p)
        for r in range(d + 1):
            C[j, r] = dp(tau[r])
        B[j] = np.polyint(p)(1.0)
    return tau, C, D, B


def _shooting_function(f: ca.Function, nx: int, nu: int,
                       substeps: int) -> ca.Function:
    """SX Function ``step(x, u, dt) -> (xf)``: RK4 with ``substeps``."""
    x = ca.SX.sym("x", nx)
    u = ca.SX.sym("u", nu)
    dt = ca.SX.sym("dt")
    tau = ca.SX.zeros(3)
    h = dt / substeps
    xk = x
    for _ in range(substeps):
        k1 = f(xk, u, tau)
        k2 = f(xk + h / 2 * k1, u, tau)
        k3 = f(xk + h / 2 * k2, u, tau)
        k4 = f(xk + h * k3, u, tau)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("step", [x, u, dt], [xk])


def _collocation_function(f: ca.Function, nx: int, nu: int,
                          d: int) -> ca.Function:
    """SX Function ``interval(x, xc, u, dt) -> (res, xend)`` (Legendre)."""
    _, C, D, _ = _collocation_coefficients(d)
    x = ca.SX.sym("x", nx)
    xc = ca.SX.sym("xc", nx * d)
    u = ca.SX.sym("u", nu)
    dt = ca.SX.sym("dt")
    pts = [x] + [xc[j * nx:(j + 1) * nx] for j in range(d)]
    res = []
    xend = D[0] * x
    for j in range(1, d + 1):
        xp = C[0, j] * x
        for r in range(1, d + 1):
            xp = xp + C[r, j] * pts[r]
        res.append(dt * f(pts[j], u, ca.SX.zeros(3)) - xp)
        xend = xend + D[j] * pts[j]
    return ca.Function("interval", [x, xc, u, dt],
                       [ca.vertcat(*res), xend])


def _solve(s: _Setup, *, objective: str, T_fixed: float | None, N: int,
           transcription: str, solver: str, expand: bool, substeps: int,
           initial_guess: str, perturbation: float, seed: int,
           solver_options: dict | None, verify: bool) -> SlewTrajectory:
    plugin, base_opts = _solver_entry(solver)
    model = s.model
    nx, nu = model.nx, model.nu
    nw = model.n_wheels
    t_build = time.perf_counter()
    # expand=True builds the NLP in SX directly (what expanding the MX
    # graph gives, without the MX step); expand=False keeps an MX graph
    # of Function calls.
    Sym = ca.SX if expand else ca.MX
    xs = np.r_[np.ones(4), s.w_scale * np.ones(3),
               s.h_max if s.h_max is not None else np.zeros(0)]
    d = 3
    Xn = Sym.sym("X", nx, N + 1)
    Un = Sym.sym("U", nu, N)
    free_T = T_fixed is None
    Tn = Sym.sym("T", 1 if free_T else 0)
    colloc = transcription == "collocation"
    Xcn = Sym.sym("Xc", nx, d * N if colloc else 0)
    X = ca.diag(ca.DM(xs)) @ Xn
    U = ca.diag(ca.DM(s.u_max)) @ Un
    T = s.T_eig * Tn if free_T else T_fixed
    dt = T / N
    f = model.dynamics
    inv_xs = ca.DM(1.0 / xs)
    g, lbg, ubg = [], [], []

    def eq(expr):
        g.append(ca.vec(expr))
        lbg.append(np.zeros(expr.numel()))
        ubg.append(np.zeros(expr.numel()))

    if not colloc:
        F = _shooting_function(f, nx, nu, substeps).map(N)
        eq(Xn[:, 1:] - inv_xs * F(X[:, :N], U, ca.repmat(dt, 1, N)))
    else:
        F = _collocation_function(f, nx, nu, d).map(N)
        Xc = ca.diag(ca.DM(xs)) @ Xcn
        Xc_stack = ca.reshape(Xc, nx * d, N)
        res, xend = F(X[:, :N], Xc_stack, U, ca.repmat(dt, 1, N))
        eq(ca.repmat(inv_xs, d, 1) * res)
        eq(Xn[:, 1:] - inv_xs * xend)
    qN = X[:4, N]
    qe = quat_mul(ca.DM(quat_conj(s.qf)), qN)
    eq(qe[1:])
    g.append(qe[0])
    lbg.append([0.0])
    ubg.append([np.inf])
    if s.rate_max is not None:
        r = s.rate_max / s.w_scale
        g.append(ca.sum1(Xn[4:7, :] ** 2).T)
        lbg.append(np.full(N + 1, -np.inf))
        ubg.append(np.full(N + 1, r ** 2))
    # simple bounds
    x0 = np.r_[s.q0, np.zeros(3), s.h0]
    lbX = -np.inf * np.ones((nx, N + 1))
    ubX = np.inf * np.ones((nx, N + 1))
    lbX[:, 0] = ubX[:, 0] = x0 / xs
    lbX[4:7, N] = ubX[4:7, N] = 0.0
    if nw:
        lbX[7:, 1:] = -1.0
        ubX[7:, 1:] = 1.0
    active = (np.ones(nu) if model.wheels is None
              else model.wheels.active.astype(float))
    lbU = -np.repeat(active[:, None], N, axis=1)
    ubU = -lbU
    lbXc = -np.inf * np.ones((nx, Xcn.shape[1]))
    ubXc = np.inf * np.ones((nx, Xcn.shape[1]))
    if nw and colloc:
        lbXc[7:] = -1.0
        ubXc[7:] = 1.0
    lbT = np.full(Tn.shape[0], 1e-3)
    ubT = np.full(Tn.shape[0], np.inf)
    w = ca.vertcat(ca.vec(Xn), ca.vec(Un), Tn, ca.vec(Xcn))
    lbw = np.concatenate([lbX.ravel("F"), lbU.ravel("F"), lbT,
                          lbXc.ravel("F")])
    ubw = np.concatenate([ubX.ravel("F"), ubU.ravel("F"), ubT,
                          ubXc.ravel("F")])
    J_obj = Tn if free_T else ca.sumsqr(Un) / N  # ∝ Σ ∫ m² dt at fixed T
    # initial guess
    T_guess = s.T_eig if free_T else T_fixed
    Xg, Ug = _guess(s, N, T_guess, initial_guess, perturbation, seed)
    Xgn = Xg / xs[:, None]
    Xcg = np.repeat(0.5 * (Xgn[:, :-1] + Xgn[:, 1:]), d, axis=1)
    w0 = np.concatenate([Xgn.ravel("F"), (Ug / s.u_max[:, None]).ravel("F"),
                         [T_guess / s.T_eig] if free_T else [],
                         Xcg.ravel("F") if colloc else []])
    opts = _merge(base_opts, solver_options or {})
    nlp = {"x": w, "f": J_obj, "g": ca.vertcat(*g)}
    S = ca.nlpsol("slew", plugin, nlp, opts)
    build_time = time.perf_counter() - t_build
    t0 = time.perf_counter()
    try:
        sol = S(x0=w0, lbx=lbw, ubx=ubw, lbg=np.concatenate(lbg),
                ubg=np.concatenate(ubg))
    except RuntimeError as exc:
        raise SolverError(f"solver {solver!r} failed with an error: "
                          f"{str(exc).strip().splitlines()[-1]}",
                          solver=solver) from exc
    solve_time = time.perf_counter() - t0
    stats = S.stats()
    success = bool(stats.get("success", False))
    status = str(stats.get("return_status", "unknown"))
    wopt = np.asarray(sol["x"]).ravel()
    nX, nU = nx * (N + 1), nu * N
    Xv = wopt[:nX].reshape(nx, N + 1, order="F") * xs[:, None]
    Uv = wopt[nX:nX + nU].reshape(nu, N, order="F") * s.u_max[:, None]
    Tv = float(wopt[nX + nU] * s.T_eig) if free_T else float(T_fixed)
    t = np.linspace(0.0, Tv, N + 1)
    extras = {"objective": objective, "transcription": transcription,
              "solver": solver, "expand": bool(expand), "N": N,
              "build_time": build_time,
              "solver_time": float(stats.get("t_wall_total", np.nan)),
              "eigenaxis_T": s.T_eig,
              "initial_guess": ("perturbed_eigenaxis" if perturbation > 0
                                and initial_guess == "eigenaxis"
                                else initial_guess),
              "perturbation": perturbation,
              "nlp_objective": float(sol["f"])}
    traj = SlewTrajectory(
        method="time_optimal" if free_T else "min_energy",
        T=Tv, t=t, q=Xv[:4].T, w=Xv[4:7].T,
        torque=model.body_control_torque(Uv).T,
        wheel_torque=Uv.T if nw else None,
        wheel_momentum=Xv[7:].T if nw else None, qf=s.qf, status=status,
        success=success, solve_time=solve_time,
        iterations=int(stats.get("iter_count", -1)), extras=extras)
    if verify and np.isfinite(Tv) and Tv > 0:
        Xs = model.simulate(x0, t, Uv.T, options={"abstol": 1e-9,
                                                   "reltol": 1e-9})
        qe = quat_mul(quat_conj(s.qf), Xs[-1, :4] / np.linalg.norm(
            Xs[-1, :4]))
        extras["simulated_final_error"] = float(
            2 * np.arcsin(min(1.0, np.linalg.norm(qe[1:]))))
        extras["simulated_final_rate"] = float(np.linalg.norm(Xs[-1, 4:7]))
    return traj


def time_optimal_slew(inertia, q0, qf, *, torque_max=None,
                      wheels: WheelArray | None = None, N: int = 100,
                      transcription: str = "multiple_shooting",
                      solver: str = "ipopt", expand: bool = True,
                      substeps: int = 1, h0=None,
                      rate_max: float | None = None,
                      initial_guess: str = "perturbed_eigenaxis",
                      perturbation: float = 0.3, seed: int = 0,
                      solver_options: dict | None = None,
                      verify: bool = True) -> SlewTrajectory:
    """Minimum-time rest-to-rest slew from ``q0`` to ``qf`` (free T).

    .. math::
        \\min T \\;\\text{s.t.}\\; \\dot x = f(x, u),\\; q(0) = q_0,\\;
        ω(0) = ω(T) = 0,\\; \\mathrm{vec}(q_f^{*}\\otimes q(T)) = 0,\\;
        |m_i| \\le m_{max,i},\\; |H_i| \\le h_{max,i}

    (or :math:`|u_k| \\le u_{max,k}` for the torque box).

    Parameters
    ----------
    inertia : array_like (3, 3) or (3,)
        J [kg·m²].
    q0, qf : array_like (4,)
        Initial and final attitude (scalar-first, body to reference).
    torque_max : float or array_like (3,), optional
        Per-axis body torque box [N·m] (instead of ``wheels``).
    wheels : WheelArray, optional
        Wheel array: limits ``m_max`` and ``h_max`` per wheel.
    N : int
        Number of control intervals.
    transcription : {"multiple_shooting", "collocation"}
        Transcription of the dynamics.
    solver : {"ipopt", "sqpmethod"}
        NLP solver (default ``"ipopt"``). ``"sqpmethod"`` is CasADi's SQP
        with qpOASES: it converges on minimum-energy slews but stalls on
        time-optimal ones (its status then says so).
    expand : bool
        Build the NLP as an SX graph (what ``expand`` gives: faster
        evaluations) instead of an MX graph of Function calls.
    substeps : int
        RK4 stages per interval (multiple shooting).
    h0 : array_like (N_w,), optional
        Initial wheel momenta [N·m·s] (default zero); final ones are free.
    rate_max : float, optional
        Bound on |ω| [rad/s].
    initial_guess : {"perturbed_eigenaxis", "eigenaxis"}
        ``"eigenaxis"`` is the unperturbed closed form: a stationary point.
    perturbation : float
        Off-axis rate amplitude of the perturbed guess, relative to the
        eigenaxis peak rate.
    seed : int
        Seed of the perturbation direction.
    solver_options : dict, optional
        Options for the CasADi solver, merged over the defaults and
        forwarded untouched.
    verify : bool
        Simulate the optimal controls with CVODES and store the final
        attitude error and rate in ``extras`` (outside ``solve_time``).

    Returns
    -------
    SlewTrajectory
        ``success`` False and ``status`` the solver's message when the
        solver fails; the iterate is then returned for inspection.

    Raises
    ------
    SolverNotFound
        Unknown or missing solver.
    InvalidValueError, ShapeError
        Bad arguments.
    """
    if initial_guess not in ("perturbed_eigenaxis", "eigenaxis"):
        raise InvalidValueError(
            "initial_guess must be 'perturbed_eigenaxis' or 'eigenaxis', "
            f"got {initial_guess!r}")
    _solver_entry(solver)
    _check_common(N, transcription, substeps)
    perturbation = as_finite_scalar(perturbation, "perturbation")
    s = _setup(inertia, q0, qf, wheels, torque_max, h0, rate_max)
    pert = 0.0 if initial_guess == "eigenaxis" else perturbation
    return _solve(s, objective="time", T_fixed=None, N=int(N),
                  transcription=transcription, solver=solver,
                  expand=expand, substeps=int(substeps),
                  initial_guess="eigenaxis", perturbation=pert, seed=seed,
                  solver_options=solver_options, verify=verify)


def min_energy_slew(inertia, q0, qf, *, T: float, torque_max=None,
                    wheels: WheelArray | None = None, N: int = 100,
                    transcription: str = "multiple_shooting",
                    solver: str = "ipopt", expand: bool = True,
                    substeps: int = 1, h0=None,
                    rate_max: float | None = None,
                    solver_options: dict | None = None,
                    verify: bool = True) -> SlewTrajectory:
    """Minimum-energy rest-to-rest slew in a fixed time ``T``.

    .. math::
        \\min \\sum_i \\int_0^T m_i^2\\,dt

    (body torque :math:`\\int |u|^2 dt` for the torque box) under the
    constraints of `time_optimal_slew`. The initial guess is a cubic
    rest-to-rest eigenaxis profile over ``T``, allocated by the
    minimum-norm law.

    Parameters
    ----------
    T : float
        Slew time [s]; infeasible below the time-optimal one (then
        ``success`` is False).
    inertia, q0, qf, torque_max, wheels, N, transcription, solver
        As `time_optimal_slew`.
    expand, substeps, h0, rate_max, solver_options, verify
        As `time_optimal_slew`.

    Returns
    -------
    SlewTrajectory
    """
    _solver_entry(solver)
    _check_common(N, transcription, substeps)
    T = as_finite_scalar(T, "T")
    check_positive(T, "T")
    s = _setup(inertia, q0, qf, wheels, torque_max, h0, rate_max)
    return _solve(s, objective="energy", T_fixed=T, N=int(N),
                  transcription=transcription, solver=solver,
                  expand=expand, substeps=int(substeps),
                  initial_guess="cubic", perturbation=0.0, seed=0,
                  solver_options=solver_options, verify=verify)
