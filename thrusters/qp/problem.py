"""The duty-cycle QP in canonical, parameter-affine form."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_scalar, check_positive

from ..laws import THRUST_AXIS, TORQUE_AXES
from ..unit import ThrusterSet

#: Number of parameters theta = (P_T, M_X, M_Z, H[3], tau_dist[3]).
N_THETA = 9
#: Finite stand-in for an absent bound (OSQP treats >= 1e30 as infinite).
INF = 1e30
#: Upper bound on the slack (scaled momentum excess), finite so that every
#: backend accepts it.
SLACK_MAX = 1e6


@dataclass(frozen=True, eq=False)
class DutyCycleQP:
    """Canonical data of the duty-cycle QP, affine in the parameters.

    Variables :math:`x = (k_1..k_n, s)`: duty fractions and one slack
    :math:`s \\ge 0` on the momentum bound. With parameters
    :math:`\\theta = (P_T, M_X, M_Z, H, \\tau_{dist})`:

    .. math::
        \\min_x\\ \\tfrac12 x^T P x + q(\\theta)^T x \\quad
        \\text{s.t.}\\quad l(\\theta) \\le A x \\le u(\\theta),\\quad
        lb \\le x \\le ub

    with ``q = q0 + Q @ theta``, ``l = l0 + Lm @ theta``,
    ``u = u0 + Um @ theta``. Rows of ``A``: first ``n_eq`` equality rows
    (``l == u``: tracked quantities), then one-sided momentum rows. All
    rows are scaled to O(1) (thrust by the group capacity, torques by the
    largest arm torque, momentum by the bound).

    Attributes
    ----------
    P, A : numpy.ndarray
        Hessian (n+1, n+1) and constraint matrix (m, n+1).
    q0, l0, u0 : numpy.ndarray
        Constant parts.
    Q, Lm, Um : numpy.ndarray
        Parameter maps, shapes (n+1, 9), (m, 9), (m, 9).
    lb, ub : numpy.ndarray, shape (n+1,)
        Variable bounds (k in [0, 1], s in [0, SLACK_MAX]).
    n_eq : int
        Number of equality rows.
    upper_rows, lower_rows : numpy.ndarray of bool, shape (m,)
        Which rows carry a finite upper / lower bound.
    """

    P: np.ndarray
    q0: np.ndarray
    Q: np.ndarray
    A: np.ndarray
    l0: np.ndarray
    Lm: np.ndarray
    u0: np.ndarray
    Um: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    n_eq: int
    upper_rows: np.ndarray
    lower_rows: np.ndarray
    if TYPE_CHECKING:   # set in __post_init__, not dataclass fields
        _v0: np.ndarray = field(init=False)
        _V: np.ndarray = field(init=False)
        _cuts: tuple[int, int] = field(init=False)

    @property
    def nx(self) -> int:
        """Number of variables (duties and slack)."""
        return self.P.shape[0]

    def __post_init__(self) -> None:
        """Stack q, l, u's affine maps (one product per cycle)."""
        # one stacked affine map for q, l, u (one product per cycle)
        object.__setattr__(self, "_v0", np.concatenate(
            [self.q0, self.l0, self.u0]))
        object.__setattr__(self, "_V", np.vstack([self.Q, self.Lm,
                                                  self.Um]))
        object.__setattr__(self, "_cuts", (self.nx,
                                           self.nx + self.A.shape[0]))

    def vectors(self, theta: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q, l, u)`` at parameters ``theta`` (9,)."""
        v = self._v0 + self._V @ theta
        a, b = self._cuts
        return v[:a], v[a:b], v[b:]


def facet_normals(n_facets: int) -> np.ndarray:
    """Outward normals (n_facets, 2) of a regular polygon in the XZ plane."""
    ang = 2 * np.pi * (np.arange(n_facets) + 0.5) / n_facets
    return np.column_stack([np.cos(ang), np.sin(ang)])


def _check_arguments(unit, cycle, h_max, tracking, bound, n_facets,
                     *weights) -> tuple[float, float]:
    """Check `build_qp`'s arguments; return the cycle and h_max [s, N·m·s]."""
    if tracking not in ("hard", "weighted"):
        raise InvalidValueError(
            f"tracking must be 'hard' or 'weighted', got {tracking!r}")
    if bound not in ("box", "norm"):
        raise InvalidValueError(
            f"bound must be 'box' or 'norm', got {bound!r}")
    T = unit.check_cycle(cycle)
    hm = as_finite_scalar(h_max, "h_max")
    if not 1e-12 <= hm <= 1e6:
        raise InvalidValueError(
            f"h_max must lie in [1e-12, 1e6] N·m·s, got {h_max!r}")
    names = ("torque_weight", "propellant_weight", "regularization",
             "slack_weight")
    for name, val in zip(names, weights):
        check_positive(as_finite_scalar(val, name), name)
    if bound == "norm" and (int(n_facets) != n_facets or n_facets < 3):
        raise InvalidValueError(
            f"n_facets must be an integer >= 3, got {n_facets!r}")
    return T, hm


def build_qp(unit: ThrusterSet, cycle: float, h_max: float,
             tracking: str = "hard", bound: str = "box",
             n_facets: int = 16, torque_weight: float = 1e3,
             propellant_weight: float = 1.0,
             regularization: float = 1e-4,
             slack_weight: float = 1e4) -> DutyCycleQP:
    """Build the canonical duty-cycle QP of a thruster set (theory §2).

    Cost: propellant per cycle :math:`\\sum_i k_i T_T P_i/(I_{sp} g_0)`
    (scaled to a maximum coefficient of ``propellant_weight``), a small
    ``regularization`` :math:`\\tfrac\\epsilon2\\|k\\|^2` (unique
    solutions), the slack penalty ``slack_weight * s + s²/2`` (an exact
    penalty while the bound's multiplier stays below ``slack_weight``:
    with the default weights the bound is met whenever it can be, as the
    property tests check on random demands) and, with
    ``tracking="weighted"``, :math:`\\tfrac w2\\|(M_{thr}k - M)/M_{ref}\\|^2`.

    Constraints: thrust along +Y equal to P_T (always hard: it is the
    mission's Δv and, at P_T = 0, eq. 10's zero net thrust); with
    ``tracking="hard"`` also :math:`M_X, M_Z`; the wheel momentum after
    the cycle :math:`H^+ = H + T_T(M_{thr}k + \\tau_{dist})` inside the box
    :math:`|H^+_X|, |H^+_Z| \\le h_{max} + s` or (``bound="norm"``) inside
    the regular ``n_facets``-gon inscribed in the circle of radius
    ``h_max`` (conservative: the polygon lies inside the circle), relaxed
    by the same slack.

    Returns
    -------
    DutyCycleQP
    """
    T, hm = _check_arguments(unit, cycle, h_max, tracking, bound, n_facets,
                             torque_weight, propellant_weight,
                             regularization, slack_weight)
    n = unit.n
    nx = n + 1
    F = unit.force_matrix()[THRUST_AXIS]                # (n,) [N]
    Mt = unit.torque_matrix()[list(TORQUE_AXES)]        # (2, n) [N·m]
    f_ref = float(np.max(np.abs(F))) * 3.0              # group capacity
    m_ref = float(np.max(np.abs(Mt)))
    if m_ref == 0.0:
        raise InvalidValueError(
            "unit: the thrusters make no torque about X or Z")

    # cost --------------------------------------------------------------
    prop = T * unit.propellant_rate()                   # [kg] per cycle
    P = np.zeros((nx, nx))
    P[:n, :n] = regularization * np.eye(n)
    P[n, n] = 1.0
    q0 = np.zeros(nx)
    q0[:n] = propellant_weight * prop / np.max(prop)
    q0[n] = slack_weight
    Q = np.zeros((nx, N_THETA))

    rows_A, rows_l0, rows_u0, rows_L, rows_U = [], [], [], [], []

    def add(a, lo, up, Lrow, Urow):
        rows_A.append(a)
        rows_l0.append(lo)
        rows_u0.append(up)
        rows_L.append(Lrow)
        rows_U.append(Urow)

    # tracking rows (equalities) ------------------------------------------
    e = np.eye(N_THETA)
    add(np.append(F / f_ref, 0.0), 0.0, 0.0, e[0] / f_ref, e[0] / f_ref)
    if tracking == "hard":
        for j in range(2):
            add(np.append(Mt[j] / m_ref, 0.0), 0.0, 0.0,
                e[1 + j] / m_ref, e[1 + j] / m_ref)
    else:
        Ms = Mt / m_ref
        P[:n, :n] += torque_weight * Ms.T @ Ms
        Q[:n, 1:3] = -torque_weight * Ms.T / m_ref
    n_eq = len(rows_A)

    # momentum rows: (T Mt k + H + T tau)/h_max -+ s <= / >= +-bound -----
    h_idx = [3 + TORQUE_AXES[0], 3 + TORQUE_AXES[1]]
    t_idx = [6 + TORQUE_AXES[0], 6 + TORQUE_AXES[1]]
    if bound == "box":
        normals = np.array([[1.0, 0.0], [0.0, 1.0]])
        limit = 1.0
        two_sided = True
    else:
        normals = facet_normals(int(n_facets))
        limit = float(np.cos(np.pi / n_facets))
        two_sided = False
    for nrm in normals:
        a_k = T * (nrm @ Mt) / hm
        shift = np.zeros(N_THETA)                       # n·(H + T tau)
        shift[h_idx] = nrm / hm
        shift[t_idx] = T * nrm / hm
        add(np.append(a_k, -1.0), -INF, limit, np.zeros(N_THETA), -shift)
        if two_sided:
            add(np.append(a_k, 1.0), -limit, INF, -shift,
                np.zeros(N_THETA))
    A = np.array(rows_A)
    l0 = np.array(rows_l0)
    u0 = np.array(rows_u0)
    lb = np.zeros(nx)
    ub = np.ones(nx)
    ub[n] = SLACK_MAX
    return DutyCycleQP(
        P=P, q0=q0, Q=Q, A=A, l0=l0, Lm=np.array(rows_L), u0=u0,
        Um=np.array(rows_U), lb=lb, ub=ub, n_eq=n_eq,
        upper_rows=u0 < INF / 2, lower_rows=l0 > -INF / 2)
