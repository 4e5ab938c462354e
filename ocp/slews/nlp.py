"""Rest-to-rest slews as NLPs: time-optimal and minimum-energy (SPEC 4).

The NLP is built with CasADi ``nlpsol`` on ``N`` intervals of length
``T/N`` with piecewise-constant controls, by multiple shooting (one RK4
step per interval, ``substeps`` stages) or direct collocation (Legendre
points of degree 3). Limits are wheel-level, through the array —
``|m_i| <= m_max_i`` and ``|H_i| <= h_max_i`` — or a per-axis body torque
box. Decision variables are scaled by the limits and the eigenaxis time.

The time-optimal problem has a stationary point at the eigenaxis slew
(SOLVER_NOTES): started exactly there, IPOPT stops at the eigenaxis time.
The perturbed guess is the eigenaxis slew plus a smooth off-axis rate and
torque, which lets the solver leave it; the default with IPOPT solves
that first on about N/5 intervals and refines (``initial_guess``).

Built solvers are kept per problem shape (`_CACHE`): the target, initial
state and scales are NLP parameters, so another slew of the same
spacecraft reuses the solver. ``jit=True`` compiles the NLP (all data as
parameters) to a C library cached on disk. ``solver="fatrop"`` uses a
stage-wise layout with the final time as a state of every stage.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from adcs_common.exceptions import (
    InvalidValueError,
    SolverError,
    SolverNotFound,
)
from adcs_common.validation import as_finite_scalar, as_vector, check_positive
from allocation import WheelArray, min_norm_gains

from ocp.spacecraft.definition import Spacecraft, spacecraft_parts

from adcs_common.quaternion import (
    quat_conj,
    quat_mul,
    quat_rate,
    quat_to_dcm,
    rotation_between,
)
from ocp.guidance import _unit_quat, eigenaxis_slew
from ocp.models.rigid import (
    SpacecraftModel,
    _effective_torque_matrix,
    check_inertia,
    rigid_spacecraft,
)
from ocp.models.trajectory import SlewTrajectory

__all__ = [
    "KeepOut",
    "NLP_SOLVERS",
    "TRANSCRIPTIONS",
    "available_nlp_solvers",
    "clear_solver_cache",
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
    # the code-generatable conic of the MPC; about 25x faster per SQP
    # iteration than qpOASES here
    "sqpmethod:qrqp": ("sqpmethod", {
        **{k: v for k, v in _QUIET_SQP.items() if k != "qpsol_options"},
        "qpsol": "qrqp", "max_iter": 300,
        "qpsol_options": {"print_iter": False, "print_header": False,
                          "print_info": False, "error_on_fail": False}}),
    "fatrop": ("fatrop", {"print_time": False, "record_time": True,
                          "structure_detection": "auto",
                          "fatrop": {"print_level": 0, "max_iter": 1000,
                                     "tol": 1e-8}}),
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


def _with_user(base: dict, user: dict | None) -> dict:
    """Merge the user's solver options over ``base``.

    A ``qpsol`` other than the default drops the default's
    ``qpsol_options`` (sqpmethod's qpOASES settings mean nothing to
    qrqp or osqp and would fail its setup).
    """
    user = user or {}
    if "qpsol" in user and user["qpsol"] != base.get("qpsol"):
        base = {k: v for k, v in base.items() if k != "qpsol_options"}
    return _merge(base, user)


@dataclass(frozen=True)
class KeepOut:
    """A keep-out cone: a body axis must stay away from a fixed direction.

    The boresight ``b`` (body frame, e.g. a star tracker's or a
    telescope's) keeps an angle of at least ``half_angle`` from the
    direction ``s`` (reference frame, e.g. the Sun):
    :math:`s^T R(q)\\, b \\le \\cos(\\text{half\\_angle})`, with R(q)
    body to reference. The slews impose it at every node of the grid
    (between nodes the motion is smooth; ``extras["keep_out_margin"]``
    reports the smallest angular margin on the simulated trajectory).

    Attributes
    ----------
    boresight : tuple of 3 float
        Body axis (normalised here).
    direction : tuple of 3 float
        Reference-frame direction to avoid (normalised here).
    half_angle : float
        Cone half-angle [rad], in (0, π).
    """

    boresight: tuple
    direction: tuple
    half_angle: float

    def __post_init__(self) -> None:
        """Normalise the axes and check the angle."""
        for name in ("boresight", "direction"):
            v = as_vector(getattr(self, name), 3, name)
            n = np.linalg.norm(v)
            if n < 1e-12:
                raise InvalidValueError(f"{name} must be a non-zero vector")
            object.__setattr__(self, name, tuple(v / n))
        a = as_finite_scalar(self.half_angle, "half_angle")
        if not 0.0 < a < np.pi:
            raise InvalidValueError(
                f"half_angle must lie in (0, π) rad, got {a}")
        object.__setattr__(self, "half_angle", a)

    def margin(self, q) -> np.ndarray:
        """Angle of the boresight from the direction minus the half-angle.

        ``q`` (4,) or (K, 4) scalar-first; returns radians, (K,) or a
        float; negative inside the cone.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        b, d = np.array(self.boresight), np.array(self.direction)
        c = np.array([d @ quat_to_dcm(qk / np.linalg.norm(qk)) @ b
                      for qk in q])
        out = np.arccos(np.clip(c, -1.0, 1.0)) - self.half_angle
        return out if out.size > 1 else float(out[0])


def _keep_outs(keep_out, q0, qf) -> tuple[KeepOut, ...]:
    """Check the cones; the end attitudes must lie outside them."""
    if keep_out is None:
        return ()
    if isinstance(keep_out, KeepOut):
        keep_out = (keep_out,)
    out = tuple(keep_out)
    for i, k in enumerate(out):
        if not isinstance(k, KeepOut):
            raise InvalidValueError(
                f"keep_out[{i}] must be a KeepOut, got {type(k).__name__}")
        for name, q in (("q0", q0), ("qf", qf)):
            if k.margin(q) < 0:
                raise InvalidValueError(
                    f"{name} lies inside keep_out[{i}] (boresight "
                    f"{np.rad2deg(k.margin(q) + k.half_angle):.2f}° from the "
                    f"direction, cone {np.rad2deg(k.half_angle):.2f}°)")
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
    keep_out: tuple = ()


def _setup(inertia, q0, qf, wheels, torque_max, h0, rate_max,
           keep_out=None) -> _Setup:
    if isinstance(inertia, Spacecraft) and rate_max is None:
        rate_max = inertia.rate_max
    inertia, wheels, _ = spacecraft_parts(inertia, wheels)
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
                  max(eig.T, 1e-9), eig.axis, _keep_outs(keep_out, q0, qf))


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


def _param_sizes(nx: int, nu: int, nw: int,
                 nk: int = 0) -> dict[str, int]:
    """Entries of the slew-data vector (order and lengths).

    ``J``, ``Jinv`` (9, column-major) [kg·m², 1/(kg·m²)], ``A`` (3 N_w)
    wheel axes, ``sfac`` (N_w) torque factors, ``umax`` (nu) control
    scale [N·m], ``hmax`` (N_w) momentum scale [N·m·s], ``wscale`` rate
    scale [rad/s], ``Tref`` time scale [s] (eigenaxis time, or T when
    fixed), ``qf`` (4) target attitude, ``x0`` (nx) scaled initial state,
    ``keep`` (7 nk) the keep-out cones (boresight, direction, cos of the
    half-angle, column by column).
    """
    return {"J": 9, "Jinv": 9, "A": 3 * nw, "sfac": nw, "umax": nu,
            "hmax": nw, "wscale": 1, "Tref": 1, "qf": 4, "x0": nx,
            "keep": 7 * nk}


#: Entries of the slew data that stay symbolic (NLP parameters ``p``)
#: when the other ones are folded into the graph as constants.
_SLEW_PARAMETERS = ("wscale", "Tref", "qf", "x0", "keep")


def _split(v, sizes: dict[str, int]) -> dict:
    """Slices of ``v`` named as in `_param_sizes`."""
    out, i = {}, 0
    for k, n in sizes.items():
        out[k] = v[i:i + n]
        i += n
    return out


def _state_scale(d: dict):
    """Scale of the state (q, ω, H_w): ``x = xs ⊙ x_n``."""
    one = d["wscale"] * 0 + 1  # 1 of the right type
    return ca.vertcat(one, one, one, one, d["wscale"], d["wscale"],
                      d["wscale"], d["hmax"])


def _rigid_dynamics(x, u, d: dict, nw: int):
    """ẋ of `ocp.models.rigid.rigid_spacecraft` (no external torque).

    The same equations with J, J⁻¹, A and the torque factors taken from
    ``d`` (symbols or constants): ``J ω̇ = -ω × (J ω + A H_w) - A m``,
    ``Ḣ_w = m = sfac ⊙ u`` (torque box: ``J ω̇ = -ω × J ω + u``).
    """
    J = ca.reshape(d["J"], 3, 3)
    Jinv = ca.reshape(d["Jinv"], 3, 3)
    q, w = x[:4], x[4:7]
    H = J @ w
    if nw:
        A = ca.reshape(d["A"], 3, nw)
        m = d["sfac"] * u
        H = H + A @ x[7:]
        torque = -A @ m
    else:
        torque = u
    wdot = Jinv @ (-ca.cross(w, H) + torque)
    return ca.vertcat(quat_rate(q, w), wdot, m) if nw else ca.vertcat(
        quat_rate(q, w), wdot)


def _shooting_function(nx: int, nu: int, nw: int, substeps: int,
                       data) -> ca.Function:
    """SX ``step(x_n, u_n, dt, p) -> (x_n+)``: RK4, ``substeps`` stages.

    States and controls are scaled (``x = xs ⊙ x_n``, ``u = umax ⊙
    u_n``); ``data`` is the slew-data vector with symbols where it holds
    NLP parameters, and ``p`` those symbols.
    """
    xn = ca.SX.sym("xn", nx)
    un = ca.SX.sym("un", nu)
    dt = ca.SX.sym("dt")
    d, p = data
    xs = _state_scale(d)
    u = d["umax"] * un
    h = dt / substeps
    xk = xs * xn
    for _ in range(substeps):
        k1 = _rigid_dynamics(xk, u, d, nw)
        k2 = _rigid_dynamics(xk + h / 2 * k1, u, d, nw)
        k3 = _rigid_dynamics(xk + h / 2 * k2, u, d, nw)
        k4 = _rigid_dynamics(xk + h * k3, u, d, nw)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("step", [xn, un, dt, p], [xk / xs])


def _collocation_function(nx: int, nu: int, nw: int, deg: int,
                          data) -> ca.Function:
    """SX ``interval(x_n, xc_n, u_n, dt, p) -> (res, x_n end)``.

    Legendre collocation of degree ``deg``, scaled as
    `_shooting_function`; ``res`` (nx deg) are the scaled residuals.
    """
    _, C, D, _ = _collocation_coefficients(deg)
    xn = ca.SX.sym("xn", nx)
    xcn = ca.SX.sym("xcn", nx * deg)
    un = ca.SX.sym("un", nu)
    dt = ca.SX.sym("dt")
    d, p = data
    xs = _state_scale(d)
    u = d["umax"] * un
    pts = [xn] + [xcn[j * nx:(j + 1) * nx] for j in range(deg)]
    res = []
    xend = D[0] * xn
    for j in range(1, deg + 1):
        xp = C[0, j] * xn
        for r in range(1, deg + 1):
            xp = xp + C[r, j] * pts[r]
        xdot = _rigid_dynamics(xs * pts[j], u, d, nw) / xs
        res.append(dt * xdot - xp)
        xend = xend + D[j] * pts[j]
    return ca.Function("interval", [xn, xcn, un, dt, p],
                       [ca.vertcat(*res), xend])


@dataclass(frozen=True)
class _Layout:
    """Positions of the scaled decision variables in the NLP vector ``w``.

    ``iX`` (nx, N+1) and ``iU`` (nu, N) index the states and controls,
    ``iT`` (N+1,) the scaled final time seen by each stage (one shared
    variable, or a copy per stage for fatrop; empty at fixed T) and
    ``iXc`` (nx, d N) the collocation states.
    """

    iX: np.ndarray
    iU: np.ndarray
    iT: np.ndarray
    iXc: np.ndarray
    n: int


def _layout(nx: int, nu: int, N: int, free_T: bool, nc: int,
            stagewise: bool) -> _Layout:
    """Block layout (X, U, T, Xc) or stage-wise (x_k, T_k, u_k, xc_k)."""
    if not stagewise:
        c = np.cumsum([0, nx * (N + 1), nu * N, int(free_T)])
        iX = np.arange(c[0], c[1]).reshape(nx, N + 1, order="F")
        iU = np.arange(c[1], c[2]).reshape(nu, N, order="F")
        iT = np.full(N + 1 if free_T else 0, c[2])
        iXc = np.arange(c[3], c[3] + nx * nc * N).reshape(
            nx, nc * N, order="F")
        return _Layout(iX, iU, iT, iXc, int(c[3] + nx * nc * N))
    nt = int(free_T)
    stage = nx + nt + nu + nx * nc
    base = stage * np.arange(N + 1)
    iX = base[None, :] + np.arange(nx)[:, None]
    iT = base + nx if free_T else np.zeros(0, dtype=int)
    iU = base[None, :N] + nx + nt + np.arange(nu)[:, None]
    iXc = (base[None, :N, None] + nx + nt + nu
           + np.arange(nx * nc).reshape(nc, nx).T[:, None, :])
    iXc = iXc.transpose(0, 2, 1).reshape(nx, nc * N, order="F")
    return _Layout(iX, iU, iT, iXc, int(stage * N + nx + nt))


def _pick(w, idx: np.ndarray):
    """Symbolic entries ``w[idx]`` with the shape of ``idx``."""
    if idx.size == 0:
        return type(w)(*idx.shape) if idx.ndim == 2 else type(w)(0, 1)
    flat = w[idx.ravel("F").tolist()]
    return ca.reshape(flat, *idx.shape) if idx.ndim == 2 else flat


class _Constraints:
    """Accumulates constraint rows ``lbg <= g <= ubg``."""

    def __init__(self) -> None:
        self.g: list = []
        self.lb: list[np.ndarray] = []
        self.ub: list[np.ndarray] = []

    def add(self, expr, lb, ub) -> None:
        expr = ca.vec(expr)
        n = expr.numel()
        self.g.append(expr)
        for out, v in ((self.lb, lb), (self.ub, ub)):
            v = np.asarray(v, float).ravel("F")  # the order of ca.vec
            out.append(np.broadcast_to(v, n).copy())

    def eq(self, expr, value=0.0) -> None:
        self.add(expr, value, value)

    def arrays(self):
        """(g, lbg, ubg, equality flags)."""
        lb = np.concatenate(self.lb) if self.lb else np.zeros(0)
        ub = np.concatenate(self.ub) if self.ub else np.zeros(0)
        return ca.vertcat(*self.g), lb, ub, (lb == ub).tolist()


@dataclass(frozen=True, eq=False)
class _Built:
    """A slew NLP solver and the numeric pieces of its inputs.

    ``lbg``, ``ubg`` are the constraint bounds, with ``rate_rows`` the
    rows of the ``|ω|² <= rate_max²`` bound (set per solve).
    """

    solver: ca.Function
    lay: _Layout
    lbg: np.ndarray
    ubg: np.ndarray
    rate_rows: np.ndarray
    build_time: float


#: Built solvers, keyed by problem structure (and folded data).
_CACHE: dict[tuple, _Built] = {}
_CACHE_SIZE = 16


def clear_solver_cache() -> None:
    """Forget every built slew solver (the next solve builds afresh)."""
    _CACHE.clear()


def _slew_data(s: _Setup, T_ref: float, x0: np.ndarray) -> np.ndarray:
    """Numeric slew-data vector (layout of `_param_sizes`)."""
    model = s.model
    if model.wheels is None:
        A, sfac, hmax = np.zeros((3, 0)), np.zeros(0), np.zeros(0)
    else:
        A, sfac = _effective_torque_matrix(model.wheels)
        hmax = s.h_max
    J = model.inertia
    xs = np.r_[np.ones(4), np.full(3, s.w_scale), hmax]
    keep = [np.r_[k.boresight, k.direction, np.cos(k.half_angle)]
            for k in s.keep_out]
    return np.concatenate([J.ravel("F"), np.linalg.inv(J).ravel("F"),
                           A.ravel("F"), sfac, s.u_max, hmax, [s.w_scale],
                           [T_ref], s.qf, x0 / xs, *keep])


def _data_symbols(Sym, sizes: dict[str, int], values: np.ndarray,
                  symbolic: tuple[str, ...]):
    """Return (dict of entries, p) of the slew data.

    The ``symbolic`` entries are symbols, stacked in ``p``; the others
    are the constants of ``values``.
    """
    num = _split(values, sizes)
    d, syms = {}, []
    for k, n in sizes.items():
        if k in symbolic:
            d[k] = Sym.sym(k, n)
            syms.append(d[k])
        else:
            d[k] = ca.DM(num[k])
    return d, ca.vertcat(*syms) if syms else Sym(0, 1)


def _options_key(opts: dict):
    """Hashable form of solver options, None if they hold objects."""
    try:
        return json.dumps(opts, sort_keys=True)
    except TypeError:
        return None


def _build(s: _Setup, *, plugin: str, opts: dict, N: int, free_T: bool,
           colloc: bool, substeps: int, expand: bool,
           symbolic: tuple[str, ...], values: np.ndarray,
           jit: dict | None) -> _Built:
    """Build the NLP solver (parameters ``p``: the `symbolic` entries)."""
    t_build = time.perf_counter()
    model = s.model
    nx, nu, nw = model.nx, model.nu, model.n_wheels
    # fatrop needs the stage-wise layout, the final time as a state
    # (T_{k+1} = T_k) and fixed values as constraint rows
    ocp_form = plugin == "fatrop"
    # expand=True builds the NLP in SX directly (what expanding the MX
    # graph gives, without the MX step); expand=False keeps an MX graph
    # of mapped Function calls (what the JIT compiles: loops, not one
    # flat expression).
    Sym = ca.SX if expand and jit is None else ca.MX
    nk = len(s.keep_out)
    sizes = _param_sizes(nx, nu, nw, nk)
    deg = 3
    lay = _layout(nx, nu, N, free_T, deg if colloc else 0, ocp_form)
    w = Sym.sym("w", lay.n)
    d, p = _data_symbols(Sym, sizes, values, symbolic)
    inner = _data_symbols(ca.SX, sizes, values, symbolic)
    Xn, Un, Xcn = _pick(w, lay.iX), _pick(w, lay.iU), _pick(w, lay.iXc)
    Tk = _pick(w, lay.iT) if free_T else None  # (N+1,) scaled
    dt = (d["Tref"] / N * Tk[:N].T if free_T
          else ca.repmat(d["Tref"] / N, 1, N))
    rate = ca.sum1(Xn[4:7, :] ** 2) if s.rate_max is not None else None
    # keep-out cones: s_j^T R(q_k) b_j - cos(half-angle_j) <= 0 per node
    cones = None
    if nk:
        kd = ca.reshape(d["keep"], 7, nk)
        cones = ca.horzcat(*[
            ca.vertcat(*[kd[3:6, j].T @ quat_to_dcm(Xn[:4, k]) @ kd[:3, j]
                         - kd[6, j] for j in range(nk)])
            for k in range(N + 1)])
    # rows stage by stage (fatrop's structure detection reads them so)
    rows, lo, hi = [], [], []
    if not colloc:
        F = _shooting_function(nx, nu, nw, substeps, inner).map(N)
        rows.append(Xn[:, 1:] - F(Xn[:, :N], Un, dt, p))
        lo.append(0.0), hi.append(0.0)
    else:
        F = _collocation_function(nx, nu, nw, deg, inner).map(N)
        res, xend = F(Xn[:, :N], ca.reshape(Xcn, nx * deg, N), Un, dt, p)
        rows += [Xn[:, 1:] - xend, res]
        lo += [0.0, 0.0]
        hi += [0.0, 0.0]
    if free_T and ocp_form:
        rows.append(Tk[1:].T - Tk[:N].T), lo.append(0.0), hi.append(0.0)
    if rate is not None:
        rows.append(rate[:N]), lo.append(-np.inf), hi.append(np.nan)
    if cones is not None:
        rows.append(cones[:, :N]), lo.append(-np.inf), hi.append(0.0)
    con = _Constraints()
    if ocp_form:
        con.eq(Xn[:, 0] - d["x0"])
    con.add(ca.vertcat(*rows),
            np.concatenate([np.full((r.shape[0], N), a)
                            for r, a in zip(rows, lo)]),
            np.concatenate([np.full((r.shape[0], N), b)
                            for r, b in zip(rows, hi)]))
    if rate is not None:
        con.add(rate[N], -np.inf, np.nan)
    if cones is not None:
        con.add(cones[:, N], -np.inf, 0.0)
    if ocp_form:
        con.eq(Xn[4:7, N])
    qe = quat_mul(quat_conj(d["qf"]), Xn[:4, N])  # xs = 1 on q
    con.eq(qe[1:])
    con.add(qe[0], 0.0, np.inf)
    g, lbg, ubg, equality = con.arrays()
    J_obj = Tk[0] if free_T else ca.sumsqr(Un) / N  # ∝ Σ ∫ m² dt
    opts = dict(opts)
    if ocp_form:
        opts["equality"] = equality
    nlp = {"x": w, "p": p, "f": J_obj, "g": g}
    S = (ca.nlpsol("slew", plugin, nlp, opts) if jit is None
         else _compiled_nlpsol(plugin, nlp, opts, jit))
    return _Built(S, lay, lbg, ubg, np.flatnonzero(np.isnan(ubg)),
                  time.perf_counter() - t_build)


def _compiled_nlpsol(plugin: str, nlp: dict, opts: dict,
                     jit: dict) -> ca.Function:
    """Return an nlpsol over a C library of the NLP, cached on disk.

    The library is compiled once per generated code (its SHA-256 names
    it) with ``jit["compiler"]`` and ``jit["flags"]`` into
    ``jit["cache_dir"]``.
    """
    S0 = ca.nlpsol("slew", plugin, nlp, opts)
    cache = Path(jit["cache_dir"]).expanduser()
    cache.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=cache) as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)  # generate_dependencies writes to the cwd
        try:
            S0.generate_dependencies("slew_nlp.c")
        finally:
            os.chdir(cwd)
        src = Path(tmp, "slew_nlp.c")
        cmd = [jit["compiler"], *jit["flags"], "-shared", "-fPIC"]
        key = hashlib.sha256(src.read_bytes() + " ".join(
            cmd + [ca.__version__]).encode()).hexdigest()[:20]
        lib = cache / f"slew_{key}.so"
        if not lib.exists():
            out = Path(tmp, "lib.so")
            run = subprocess.run([*cmd, "-o", str(out), str(src), "-lm"],
                                 capture_output=True, text=True)
            if run.returncode != 0:
                raise SolverError("compiling the slew NLP failed: "
                                  + run.stderr.strip()[-500:],
                                  solver=plugin)
            os.replace(out, lib)  # atomic: concurrent builds are safe
    return ca.nlpsol("slew", plugin, str(lib), opts)


def _jit_settings(jit) -> dict | None:
    """None (no JIT) or the compiler, flags and cache directory."""
    if jit is False or jit is None:
        return None
    cfg = {"compiler": os.environ.get("CC") or shutil.which("gcc")
           or shutil.which("cc") or shutil.which("clang"),
           "flags": ["-O1"],
           "cache_dir": os.environ.get("ADCS_CACHE_DIR",
                                       "~/.cache/adcs_toolbox/slews")}
    if isinstance(jit, dict):
        unknown = set(jit) - set(cfg)
        if unknown:
            raise InvalidValueError(
                f"jit takes the keys {sorted(cfg)}, got {sorted(unknown)}")
        cfg.update(jit)
    elif jit is not True:
        raise InvalidValueError(f"jit must be a bool or a dict, got {jit!r}")
    if not cfg["compiler"]:
        raise InvalidValueError("jit needs a C compiler (gcc, cc or clang "
                                "on PATH, or $CC)")
    cfg["flags"] = list(cfg["flags"])
    return cfg


@dataclass(frozen=True, eq=False)
class _Prepared:
    """A built solver with the numeric inputs of one slew."""

    built: _Built
    cached: bool
    p: np.ndarray
    lbw: np.ndarray
    ubw: np.ndarray
    ubg: np.ndarray
    xs: np.ndarray


def _prepare(s: _Setup, *, solver: str, N: int, T_fixed: float | None,
             transcription: str, expand: bool, substeps: int,
             opts: dict, jit_cfg: dict | None) -> _Prepared:
    """Fetch (or build) the solver and set the numeric inputs."""
    plugin, _ = _solver_entry(solver)
    model = s.model
    nx, nw = model.nx, model.n_wheels
    colloc = transcription == "collocation"
    free_T = T_fixed is None
    T_ref = s.T_eig if free_T else float(T_fixed)
    x0 = np.r_[s.q0, np.zeros(3), s.h0]
    xs = np.r_[np.ones(4), s.w_scale * np.ones(3),
               s.h_max if s.h_max is not None else np.zeros(0)]
    values = _slew_data(s, T_ref, x0)
    sizes = _param_sizes(nx, model.nu, nw, len(s.keep_out))
    # compiled: every entry is a parameter (one library per shape);
    # otherwise the spacecraft data are folded into the SX graph
    symbolic = tuple(sizes) if jit_cfg else _SLEW_PARAMETERS
    folded = np.concatenate([np.zeros(0)] + [
        v for k, v in _split(values, sizes).items() if k not in symbolic])
    okey = _options_key(opts)
    key = (solver, transcription, N, nx, model.nu, nw, substeps, free_T,
           s.rate_max is not None, len(s.keep_out), bool(expand),
           _options_key(jit_cfg),
           okey, folded.tobytes())
    built = _CACHE.get(key) if okey is not None else None
    cached = built is not None
    if built is None:
        built = _build(s, plugin=plugin, opts=opts, N=N, free_T=free_T,
                       colloc=colloc, substeps=substeps, expand=expand,
                       symbolic=symbolic, values=values, jit=jit_cfg)
        if okey is not None:
            while len(_CACHE) >= _CACHE_SIZE:
                _CACHE.pop(next(iter(_CACHE)))
            _CACHE[key] = built
    p = np.concatenate([v for k, v in _split(values, sizes).items()
                        if k in symbolic])
    ubg = built.ubg.copy()
    if s.rate_max is not None:
        ubg[built.rate_rows] = (s.rate_max / s.w_scale) ** 2
    lbw, ubw = _bounds(s, built.lay, N, xs, x0, colloc,
                       fix=plugin != "fatrop")
    return _Prepared(built, cached, p, lbw, ubw, ubg, xs)


def _run(prep: _Prepared, solver: str,
         w0: np.ndarray) -> tuple[dict, dict, float]:
    """Solve; return (solution as arrays, stats, wall time [s])."""
    S = prep.built.solver
    args = dict(x0=w0, p=prep.p, lbx=prep.lbw, ubx=prep.ubw,
                lbg=prep.built.lbg, ubg=prep.ubg)
    t0 = time.perf_counter()
    try:
        sol = S(**args)
    except RuntimeError as exc:
        raise SolverError(f"solver {solver!r} failed with an error: "
                          f"{str(exc).strip().splitlines()[-1]}",
                          solver=solver) from exc
    solve_time = time.perf_counter() - t0
    sol = {k: np.asarray(v).ravel() for k, v in sol.items()}
    return sol, S.stats(), solve_time


#: Options of the refined solve (``initial_guess="coarse"``): its guess
#: is feasible and near the optimum, so a small barrier parameter and
#: iterates kept close to the (active) bounds. Measured on the benchmark
#: slews; IPOPT's warm start with the interpolated multipliers was no
#: better.
WARM_START_OPTIONS: dict[str, dict] = {
    "ipopt": {"ipopt": {"mu_init": 1e-5, "bound_push": 1e-8,
                        "bound_frac": 1e-8}},
    "fatrop": {"fatrop": {"mu_init": 1e-5}},
}

#: Options of the coarse solve that seeds ``initial_guess="coarse"``
#: (a rough optimum is enough).
COARSE_OPTIONS: dict[str, dict] = {
    "ipopt": {"ipopt": {"tol": 1e-4}},
    "fatrop": {"fatrop": {"tol": 1e-4}},
}


def _coarse_N(N: int) -> int | None:
    """Intervals of the coarse solve for ``initial_guess="coarse"``.

    The divisor of N nearest N/5 within [N/8, N/3] (its piecewise-
    constant controls are then exactly representable on N intervals),
    else round(N/5); None when that is under 6 intervals (then the
    perturbed eigenaxis guess is used directly).
    """
    divs = [n for n in range(max(1, N // 8), N // 3 + 1)
            if N % n == 0 and 8 * n >= N]
    Nc = (min(divs, key=lambda n: abs(5 * n - N)) if divs
          else int(round(N / 5)))
    return Nc if Nc >= 6 else None


def _refined_start(s: _Setup, coarse: _Prepared, sol: dict,
                   fine: _Prepared, N: int, T_fixed: float | None,
                   substeps: int) -> np.ndarray:
    """Scaled guess w0 on N intervals from a coarse solution.

    Controls are held over the fine grid and the states simulated by the
    RK4 of the NLP, so the guess satisfies the continuity rows.
    """
    lc, lf = coarse.built.lay, fine.built.lay
    Nc = lc.iU.shape[1]
    j = np.minimum((np.arange(N) * Nc) // N, Nc - 1)  # coarse interval
    Un = sol["x"][lc.iU][:, j]
    T = (float(sol["x"][lc.iT[0]] * s.T_eig) if T_fixed is None
         else T_fixed)
    U = Un * s.u_max[:, None]
    X = np.empty((s.model.nx, N + 1))
    X[:, 0] = np.r_[s.q0, np.zeros(3), s.h0]
    step = s.model.rk4_step(substeps)  # the shooting step of the NLP
    for k in range(N):
        X[:, k + 1] = np.asarray(step(X[:, k], U[:, k], np.zeros(3),
                                      T / N)).ravel()
    w0 = np.zeros(lf.n)
    w0[lf.iX] = X / fine.xs[:, None]
    w0[lf.iU] = Un
    if lf.iXc.size:  # collocation states: interval midpoints
        d = lf.iXc.shape[1] // N
        mid = 0.5 * (w0[lf.iX][:, :-1] + w0[lf.iX][:, 1:])
        w0[lf.iXc] = np.repeat(mid, d, axis=1)
    if lf.iT.size:
        w0[lf.iT] = sol["x"][lc.iT[0]]
    return w0


def _guess_label(initial_guess: str, Nc: int | None,
                 perturbation: float) -> str:
    """Name of the start actually used, for ``extras["initial_guess"]``."""
    if Nc is not None:
        return "coarse"
    if initial_guess in ("eigenaxis", "coarse"):
        return "perturbed_eigenaxis" if perturbation > 0 else "eigenaxis"
    return initial_guess


def _solve(s: _Setup, *, objective: str, T_fixed: float | None, N: int,
           transcription: str, solver: str, expand: bool, substeps: int,
           initial_guess: str, perturbation: float, seed: int,
           solver_options: dict | None, verify: bool,
           jit=False) -> SlewTrajectory:
    plugin, base_opts = _solver_entry(solver)
    model = s.model
    nw = model.n_wheels
    colloc = transcription == "collocation"
    if plugin == "fatrop" and colloc:
        # its structure detection rejects the collocation rows
        raise InvalidValueError(
            "solver 'fatrop' takes transcription='multiple_shooting' only")
    jit_cfg = _jit_settings(jit)
    free_T = T_fixed is None
    T_ref = s.T_eig if free_T else float(T_fixed)
    opts = _with_user(base_opts, solver_options)
    common = dict(solver=solver, T_fixed=T_fixed, transcription=transcription,
                  expand=expand, substeps=substeps, jit_cfg=jit_cfg)
    coarse_info: dict = {}
    builds: list[_Prepared] = []
    Nc = _coarse_N(N) if initial_guess == "coarse" else None
    sol = None
    if Nc is not None:
        cprep = _prepare(s, N=Nc, opts=_merge(
            opts, COARSE_OPTIONS.get(plugin, {})), **common)
        w0c = _initial_point(s, cprep.built.lay, Nc, cprep.xs, T_ref,
                             free_T, colloc, 3,
                             "eigenaxis" if free_T else "cubic",
                             perturbation, seed)
        csol, cstats, ctime = _run(cprep, solver, w0c)
        builds.append(cprep)
        coarse_info = {"coarse_N": Nc,
                       "coarse_iterations": int(cstats.get("iter_count", -1)),
                       "coarse_solve_time": ctime,
                       "coarse_status": _status(cstats)}
        if cstats.get("success", False):
            warm = _with_user(_merge(base_opts,
                                     WARM_START_OPTIONS.get(plugin, {})),
                              solver_options)
            prep = _prepare(s, N=N, opts=warm, **common)
            w0 = _refined_start(s, cprep, csol, prep, N, T_fixed, substeps)
            sol, stats, solve_time = _run(prep, solver, w0)
        else:  # start again from the perturbed guess (time included)
            Nc = None
    if sol is None:
        kind = "eigenaxis" if initial_guess == "coarse" else initial_guess
        prep = _prepare(s, N=N, opts=opts, **common)
        w0 = _initial_point(s, prep.built.lay, N, prep.xs, T_ref, free_T,
                            colloc, 3, kind, perturbation, seed)
        sol, stats, solve_time = _run(prep, solver, w0)
    builds.append(prep)
    solve_time += coarse_info.get("coarse_solve_time", 0.0)
    lay, xs = prep.built.lay, prep.xs
    cached = all(b.cached for b in builds)
    build_time = sum(b.built.build_time for b in builds if not b.cached)
    x0 = np.r_[s.q0, np.zeros(3), s.h0]
    wopt = sol["x"]
    Xv = wopt[lay.iX] * xs[:, None]
    Uv = wopt[lay.iU] * s.u_max[:, None]
    Tv = float(wopt[lay.iT[0]] * s.T_eig) if free_T else float(T_fixed)
    t = np.linspace(0.0, Tv, N + 1)
    extras = {"objective": objective, "transcription": transcription,
              "solver": solver, "expand": bool(expand), "N": N,
              "jit": jit_cfg is not None, "cached": cached,
              "build_time": build_time,
              "solver_time": float(stats.get("t_wall_total", np.nan)),
              "eigenaxis_T": s.T_eig,
              "initial_guess": _guess_label(initial_guess, Nc,
                                            perturbation),
              "perturbation": perturbation,
              "nlp_objective": float(sol["f"][0]), **coarse_info}
    traj = SlewTrajectory(
        method="time_optimal" if free_T else "min_energy",
        T=Tv, t=t, q=Xv[:4].T, w=Xv[4:7].T,
        torque=model.body_control_torque(Uv).T,
        wheel_torque=Uv.T if nw else None,
        wheel_momentum=Xv[7:].T if nw else None, qf=s.qf,
        status=_status(stats), success=bool(stats.get("success", False)),
        solve_time=solve_time,
        iterations=int(stats.get("iter_count", -1)), extras=extras)
    if s.keep_out:
        extras["keep_out_node_margin"] = float(min(
            np.min(k.margin(traj.q)) for k in s.keep_out))
    if verify and np.isfinite(Tv) and Tv > 0:
        _verify(model, x0, t, Uv, s.qf, extras, s.keep_out)
    return traj


def _status(stats: dict) -> str:
    """Return the solver's status message (fatrop's code is an int)."""
    status = stats.get("return_status", "unknown")
    if isinstance(status, str):
        return status
    return f"{stats.get('unified_return_status', 'unknown')} ({status})"


def _bounds(s: _Setup, lay: _Layout, N: int, xs: np.ndarray,
            x0: np.ndarray, colloc: bool, fix: bool):
    """(lbw, ubw) of the scaled variables; ``fix``: x(0), ω(T) by bounds."""
    nx = lay.iX.shape[0]
    nw = s.model.n_wheels
    lbw = np.full(lay.n, -np.inf)
    ubw = np.full(lay.n, np.inf)
    lbX = np.full((nx, N + 1), -np.inf)
    ubX = np.full((nx, N + 1), np.inf)
    if nw:
        lbX[7:, 1:], ubX[7:, 1:] = -1.0, 1.0
    if fix:
        lbX[:, 0] = ubX[:, 0] = x0 / xs
        lbX[4:7, N] = ubX[4:7, N] = 0.0
    lbw[lay.iX], ubw[lay.iX] = lbX, ubX
    active = (np.ones(s.model.nu) if s.model.wheels is None
              else s.model.wheels.active.astype(float))
    lbw[lay.iU] = -active[:, None]
    ubw[lay.iU] = active[:, None]
    if nw and colloc:
        lbw[lay.iXc[7:]], ubw[lay.iXc[7:]] = -1.0, 1.0
    lbw[lay.iT] = 1e-3
    return lbw, ubw


def _initial_point(s: _Setup, lay: _Layout, N: int, xs: np.ndarray,
                   T_guess: float, free_T: bool, colloc: bool, d: int,
                   kind: str, perturbation: float, seed: int) -> np.ndarray:
    """Scaled initial guess ``w0`` (lay.n,)."""
    Xg, Ug = _guess(s, N, T_guess, kind, perturbation, seed)
    Xgn = Xg / xs[:, None]
    w0 = np.zeros(lay.n)
    w0[lay.iX] = Xgn
    w0[lay.iU] = Ug / s.u_max[:, None]
    if free_T:
        w0[lay.iT] = T_guess / s.T_eig
    if colloc:
        w0[lay.iXc] = np.repeat(0.5 * (Xgn[:, :-1] + Xgn[:, 1:]), d, axis=1)
    return w0


def _verify(model: SpacecraftModel, x0: np.ndarray, t: np.ndarray,
            Uv: np.ndarray, qf: np.ndarray, extras: dict,
            keep_out: tuple = ()) -> None:
    """Simulate the controls with CVODES; store final error and rate.

    With keep-out cones the grid is refined 8 times (controls held) and
    the smallest angular margin on it is stored too [rad].
    """
    opts = {"abstol": 1e-9, "reltol": 1e-9}
    if keep_out:
        sub = 8
        tf = np.linspace(t[0], t[-1], sub * (len(t) - 1) + 1)
        Xf = model.simulate(x0, tf, np.repeat(Uv.T, sub, axis=0),
                            options=opts)
        extras["keep_out_margin"] = float(min(
            np.min(k.margin(Xf[:, :4])) for k in keep_out))
        Xs = Xf[::sub]
    else:
        Xs = model.simulate(x0, t, Uv.T, options=opts)
    qe = quat_mul(quat_conj(qf), Xs[-1, :4] / np.linalg.norm(Xs[-1, :4]))
    extras["simulated_final_error"] = float(
        2 * np.arcsin(min(1.0, np.linalg.norm(qe[1:]))))
    extras["simulated_final_rate"] = float(np.linalg.norm(Xs[-1, 4:7]))


def time_optimal_slew(inertia, q0, qf, *, torque_max=None,
                      wheels: WheelArray | None = None, N: int = 100,
                      transcription: str = "multiple_shooting",
                      solver: str = "ipopt", expand: bool = True,
                      substeps: int = 1, h0=None,
                      rate_max: float | None = None,
                      initial_guess: str | None = None,
                      perturbation: float = 0.3, seed: int = 0,
                      solver_options: dict | None = None,
                      verify: bool = True,
                      jit: bool | dict = False,
                      keep_out=None) -> SlewTrajectory:
    """Minimum-time rest-to-rest slew from ``q0`` to ``qf`` (free T).

    .. math::
        \\min T \\;\\text{s.t.}\\; \\dot x = f(x, u),\\; q(0) = q_0,\\;
        ω(0) = ω(T) = 0,\\; \\mathrm{vec}(q_f^{*}\\otimes q(T)) = 0,\\;
        |m_i| \\le m_{max,i},\\; |H_i| \\le h_{max,i}

    (or :math:`|u_k| \\le u_{max,k}` for the torque box).

    Parameters
    ----------
    inertia : array_like (3, 3) or (3,), or ocp.spacecraft.Spacecraft
        J [kg·m²], or a `Spacecraft` (its wheels, and its ``rate_max``
        unless given here).
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
    solver : {"ipopt", "fatrop", "sqpmethod", "sqpmethod:qrqp"}
        NLP solver (default ``"ipopt"``). ``"fatrop"`` (where CasADi has
        it; multiple shooting only) exploits the stage structure.
        ``"sqpmethod"`` is CasADi's SQP with qpOASES, ``"sqpmethod:qrqp"``
        the same with qrqp (code-generatable, much faster per iteration):
        both converge on minimum-energy slews, slowly (about 100
        iterations), and stall on time-optimal ones (the status then says
        so; set ``solver_options={"max_iter": ...}`` to bound the time).
    expand : bool
        Build the NLP as an SX graph (what ``expand`` gives: faster
        evaluations) instead of an MX graph of Function calls.
    substeps : int
        RK4 stages per interval (multiple shooting).
    h0 : array_like (N_w,), optional
        Initial wheel momenta [N·m·s] (default zero); final ones are free.
    rate_max : float, optional
        Bound on |ω| [rad/s].
    initial_guess : {None, "coarse", "perturbed_eigenaxis", "eigenaxis"}
        None (default): ``"coarse"`` with IPOPT, ``"perturbed_eigenaxis"``
        with the other solvers (fatrop's coarse solve of the
        Bilimoria–Wie slew ends in another local optimum, T = 3.285).
        ``"perturbed_eigenaxis"``: the eigenaxis slew with a smooth
        off-axis perturbation. ``"coarse"``: that guess solved
        first on about N/5 intervals (a divisor of N where one fits;
        tolerance 1e-4, `COARSE_OPTIONS`), its controls held on the N
        intervals and its states re-simulated, then the N-interval NLP
        solved from there (`WARM_START_OPTIONS`); ``solve_time`` includes
        both solves and ``extras`` holds the coarse figures. Below 30
        intervals it is ``"perturbed_eigenaxis"``. ``"eigenaxis"`` is the
        unperturbed closed form: a stationary point.
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
    jit : bool or dict
        Opt-in: compile the NLP's functions to C (MX graph of mapped
        interval Functions, ``expand`` ignored) with all problem data as
        NLP parameters, so one library serves every slew of the same
        shape (N, wheels or torque box, transcription, solver, options).
        The library is cached on disk, named by the SHA-256 of its code:
        the compile (≈ 8–16 s per library at -O1 on the benchmark slews;
        the coarse start needs two) happens once per machine, later
        processes load it in ≈ 1 s. It is not thread-safe (it changes
        the working directory while generating the code). A dict
        sets ``compiler`` (default $CC, gcc, cc or clang), ``flags``
        (default ``["-O1"]``) and ``cache_dir`` (default
        $ADCS_CACHE_DIR or ``~/.cache/adcs_toolbox/slews``).
    keep_out : KeepOut or sequence of KeepOut, optional
        Cones a body axis must stay out of (e.g. a star tracker away from
        the Sun), imposed at every node; ``extras`` then holds
        ``keep_out_node_margin`` and, with ``verify``,
        ``keep_out_margin`` (smallest margin on the simulated trajectory
        at 8 points per interval) [rad]. ``q0`` and ``qf`` must lie
        outside every cone.

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
    if initial_guess is None:
        initial_guess = ("coarse" if solver == "ipopt"
                         else "perturbed_eigenaxis")
    if initial_guess not in ("perturbed_eigenaxis", "eigenaxis", "coarse"):
        raise InvalidValueError(
            "initial_guess must be 'perturbed_eigenaxis', 'eigenaxis' or "
            f"'coarse', got {initial_guess!r}")
    _solver_entry(solver)
    _check_common(N, transcription, substeps)
    perturbation = as_finite_scalar(perturbation, "perturbation")
    s = _setup(inertia, q0, qf, wheels, torque_max, h0, rate_max, keep_out)
    pert = 0.0 if initial_guess == "eigenaxis" else perturbation
    return _solve(s, objective="time", T_fixed=None, N=int(N),
                  transcription=transcription, solver=solver,
                  expand=expand, substeps=int(substeps),
                  initial_guess=("coarse" if initial_guess == "coarse"
                                 else "eigenaxis"),
                  perturbation=pert, seed=seed,
                  solver_options=solver_options, verify=verify, jit=jit)


def min_energy_slew(inertia, q0, qf, *, T: float, torque_max=None,
                    wheels: WheelArray | None = None, N: int = 100,
                    transcription: str = "multiple_shooting",
                    solver: str = "ipopt", expand: bool = True,
                    substeps: int = 1, h0=None,
                    rate_max: float | None = None,
                    solver_options: dict | None = None,
                    verify: bool = True,
                    jit: bool | dict = False,
                    keep_out=None) -> SlewTrajectory:
    """Minimum-energy rest-to-rest slew in a fixed time ``T``.

    .. math::
        \\min \\sum_i \\int_0^T m_i^2\\,dt

    (body torque :math:`\\int |u|^2 dt` for the torque box) under the
    constraints of `time_optimal_slew`. The initial guess is a cubic
    rest-to-rest eigenaxis profile over ``T``, allocated by the
    minimum-norm law (with keep-out cones, perturbed off the eigenaxis
    plane as in `time_optimal_slew`).

    Parameters
    ----------
    T : float
        Slew time [s]; infeasible below the time-optimal one (then
        ``success`` is False).
    inertia, q0, qf, torque_max, wheels, N, transcription, solver
        As `time_optimal_slew`.
    expand, substeps, h0, rate_max, solver_options, verify, jit, keep_out
        As `time_optimal_slew`.

    Returns
    -------
    SlewTrajectory
    """
    _solver_entry(solver)
    _check_common(N, transcription, substeps)
    T = as_finite_scalar(T, "T")
    check_positive(T, "T")
    s = _setup(inertia, q0, qf, wheels, torque_max, h0, rate_max, keep_out)
    # a cone on the eigenaxis path makes the planar guess a stationary
    # point (escaping to either side is symmetric): perturb it off-plane
    return _solve(s, objective="energy", T_fixed=T, N=int(N),
                  transcription=transcription, solver=solver,
                  expand=expand, substeps=int(substeps),
                  initial_guess="cubic",
                  perturbation=0.3 if s.keep_out else 0.0, seed=0,
                  solver_options=solver_options, verify=verify, jit=jit)
