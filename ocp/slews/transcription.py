"""Transcriptions of the slew dynamics and the NLP variable layout."""

from __future__ import annotations

from dataclasses import dataclass
import casadi as ca
import numpy as np
from adcs_common.quaternion import (
    quat_rate,
)


#: Transcriptions of the slew NLP.
TRANSCRIPTIONS = ("multiple_shooting", "collocation")


def collocation_coefficients(d: int = 3):
    """Legendre collocation matrices (C, D, B) of degree ``d``."""
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


def param_sizes(nx: int, nu: int, nw: int,
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
SLEW_PARAMETERS = ("wscale", "Tref", "qf", "x0", "keep")


def split_parameters(v, sizes: dict[str, int]) -> dict:
    """Slices of ``v`` named as in `param_sizes`."""
    out, i = {}, 0
    for k, n in sizes.items():
        out[k] = v[i:i + n]
        i += n
    return out


def state_scale(d: dict):
    """Scale of the state (q, ω, H_w): ``x = xs ⊙ x_n``."""
    one = d["wscale"] * 0 + 1  # 1 of the right type
    return ca.vertcat(one, one, one, one, d["wscale"], d["wscale"],
                      d["wscale"], d["hmax"])


def rigid_dynamics(x, u, d: dict, nw: int):
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


def shooting_function(nx: int, nu: int, nw: int, substeps: int,
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
    xs = state_scale(d)
    u = d["umax"] * un
    h = dt / substeps
    xk = xs * xn
    for _ in range(substeps):
        k1 = rigid_dynamics(xk, u, d, nw)
        k2 = rigid_dynamics(xk + h / 2 * k1, u, d, nw)
        k3 = rigid_dynamics(xk + h / 2 * k2, u, d, nw)
        k4 = rigid_dynamics(xk + h * k3, u, d, nw)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("step", [xn, un, dt, p], [xk / xs])


def collocation_function(nx: int, nu: int, nw: int, deg: int,
                         data) -> ca.Function:
    """SX ``interval(x_n, xc_n, u_n, dt, p) -> (res, x_n end)``.

    Legendre collocation of degree ``deg``, scaled as
    `shooting_function`; ``res`` (nx deg) are the scaled residuals.
    """
    _, C, D, _ = collocation_coefficients(deg)
    xn = ca.SX.sym("xn", nx)
    xcn = ca.SX.sym("xcn", nx * deg)
    un = ca.SX.sym("un", nu)
    dt = ca.SX.sym("dt")
    d, p = data
    xs = state_scale(d)
    u = d["umax"] * un
    pts = [xn] + [xcn[j * nx:(j + 1) * nx] for j in range(deg)]
    res = []
    xend = D[0] * xn
    for j in range(1, deg + 1):
        xp = C[0, j] * xn
        for r in range(1, deg + 1):
            xp = xp + C[r, j] * pts[r]
        xdot = rigid_dynamics(xs * pts[j], u, d, nw) / xs
        res.append(dt * xdot - xp)
        xend = xend + D[j] * pts[j]
    return ca.Function("interval", [xn, xcn, un, dt, p],
                       [ca.vertcat(*res), xend])


@dataclass(frozen=True)
class Layout:
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


def layout(nx: int, nu: int, N: int, free_T: bool, nc: int,
           stagewise: bool) -> Layout:
    """Block layout (X, U, T, Xc) or stage-wise (x_k, T_k, u_k, xc_k)."""
    if not stagewise:
        c = np.cumsum([0, nx * (N + 1), nu * N, int(free_T)])
        iX = np.arange(c[0], c[1]).reshape(nx, N + 1, order="F")
        iU = np.arange(c[1], c[2]).reshape(nu, N, order="F")
        iT = np.full(N + 1 if free_T else 0, c[2])
        iXc = np.arange(c[3], c[3] + nx * nc * N).reshape(
            nx, nc * N, order="F")
        return Layout(iX, iU, iT, iXc, int(c[3] + nx * nc * N))
    nt = int(free_T)
    stage = nx + nt + nu + nx * nc
    base = stage * np.arange(N + 1)
    iX = base[None, :] + np.arange(nx)[:, None]
    iT = base + nx if free_T else np.zeros(0, dtype=int)
    iU = base[None, :N] + nx + nt + np.arange(nu)[:, None]
    iXc = (base[None, :N, None] + nx + nt + nu
           + np.arange(nx * nc).reshape(nc, nx).T[:, None, :])
    iXc = iXc.transpose(0, 2, 1).reshape(nx, nc * N, order="F")
    return Layout(iX, iU, iT, iXc, int(stage * N + nx + nt))


def pick(w, idx: np.ndarray):
    """Symbolic entries ``w[idx]`` with the shape of ``idx``."""
    if idx.size == 0:
        return type(w)(*idx.shape) if idx.ndim == 2 else type(w)(0, 1)
    flat = w[idx.ravel("F").tolist()]
    return ca.reshape(flat, *idx.shape) if idx.ndim == 2 else flat


class Constraints:
    """Accumulates constraint rows ``lbg <= g <= ubg``."""

    def __init__(self) -> None:
        self.g: list = []
        self.lb: list[np.ndarray] = []
        self.ub: list[np.ndarray] = []

    def add(self, expr, lb, ub) -> None:
        """Append rows ``lb <= expr <= ub``."""
        expr = ca.vec(expr)
        n = expr.numel()
        self.g.append(expr)
        for out, v in ((self.lb, lb), (self.ub, ub)):
            v = np.asarray(v, float).ravel("F")  # the order of ca.vec
            out.append(np.broadcast_to(v, n).copy())

    def eq(self, expr, value=0.0) -> None:
        """Append equality rows ``expr == value``."""
        self.add(expr, value, value)

    def arrays(self):
        """(g, lbg, ubg, equality flags)."""
        lb = np.concatenate(self.lb) if self.lb else np.zeros(0)
        ub = np.concatenate(self.ub) if self.ub else np.zeros(0)
        return ca.vertcat(*self.g), lb, ub, (lb == ub).tolist()


@dataclass(frozen=True)
class MultipleShooting:
    """Multiple shooting: one RK4 step (``substeps`` stages) per interval."""

    substeps: int = 1
    name = "multiple_shooting"
    #: collocation states per interval (none)
    degree = 0

    def defects(self, dims: tuple[int, int, int], N: int, Xn, Xcn, Un, dt,
                p, data) -> list:
        """Continuity rows ``x_{k+1} - step(x_k, u_k)`` (all equal to 0)."""
        F = shooting_function(*dims, self.substeps, data).map(N)
        return [Xn[:, 1:] - F(Xn[:, :N], Un, dt, p)]


@dataclass(frozen=True)
class Collocation:
    """Direct collocation, Legendre points of degree ``degree``."""

    degree: int = 3
    name = "collocation"

    def defects(self, dims: tuple[int, int, int], N: int, Xn, Xcn, Un, dt,
                p, data) -> list:
        """Continuity and collocation residual rows (all equal to 0)."""
        nx = dims[0]
        F = collocation_function(*dims, self.degree, data).map(N)
        res, xend = F(Xn[:, :N], ca.reshape(Xcn, nx * self.degree, N), Un,
                      dt, p)
        return [Xn[:, 1:] - xend, res]


def transcription_named(name: str, substeps: int = 1):
    """Return the transcription object of a `TRANSCRIPTIONS` name."""
    if name == "collocation":
        return Collocation()
    return MultipleShooting(substeps)
