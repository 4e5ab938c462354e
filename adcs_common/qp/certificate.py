r"""Optimality certificate of a QP answer, with an exact polish.

A backend's point is accepted only when it is the optimum of the `QP`:
primal feasible, stationary, complementary and dual feasible, each within
a tolerance relative to the data. The point is first *polished*: the
equality-constrained QP of the active set the backend found is solved
exactly (its KKT system),

.. math::
    \begin{bmatrix} P & G_S^T \\ G_S & 0 \end{bmatrix}
    \begin{bmatrix} x \\ \lambda_S \end{bmatrix} =
    \begin{bmatrix} -q \\ b_S \end{bmatrix},

with ``G = [C; I]`` the rows and variable bounds and ``S`` the rows at a
bound. A row with a multiplier of the wrong sign leaves ``S`` and a
violated row joins it (a few primal-dual active-set steps from the
backend's guess), so an iterative solver's approximate answer becomes the
exact optimum whenever its active set is nearly right. Convex QPs only
(``P`` positive semi-definite): there the KKT conditions are sufficient.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .problem import QP

__all__ = ["Certificate", "certify", "CERTIFY_TOL"]

#: Relative tolerance of the certificate (stationarity, feasibility,
#: multiplier signs).
CERTIFY_TOL = 1e-9
#: Relative distances to a bound under which the backend's point counts
#: the row as active: the polish's guesses, loosest first (a point the
#: backend took just inside a face is tried on and off it); the last
#: starts from the equality rows alone.
_ACTIVE_TOLS = (1e-5, 1e-8, 1e-11, -np.inf)
#: Smallest scale of a value (see `_row_scale`).
_FLOOR = 1e-200
#: Primal-dual active-set steps of the polish, over one per row.
_MAX_STEPS = 12


@dataclass(frozen=True)
class Certificate:
    """The verdict on one point.

    Attributes
    ----------
    certified : bool
        The point is optimal within ``tol``.
    primal : float
        Largest row or bound violation, relative to the row's scale.
    stationarity : float
        ``|P x + q + G^T λ|_∞`` relative to the gradient's terms.
    dual : float
        Largest multiplier of the wrong sign, relative to the multipliers.
    polished : bool
        The returned point is the exact KKT solution of an active set
        (else the backend's point, unchanged).
    steps : int
        Active-set steps the polish took.
    """

    certified: bool
    primal: float
    stationarity: float
    dual: float
    polished: bool
    steps: int

    def as_dict(self) -> dict:
        """The fields as a plain dict (for ``extras``)."""
        return {"certified": self.certified, "primal": self.primal,
                "stationarity": self.stationarity, "dual": self.dual,
                "polished": self.polished, "steps": self.steps}


def _rows(qp: QP) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``G = [C; I]`` and its bounds ``gl``, ``gu``."""
    G = np.vstack([qp.C, np.eye(qp.n)])
    return G, np.concatenate([qp.l, qp.lb]), np.concatenate([qp.u, qp.ub])


def _row_scale(G, x, b):
    """Scale of each row's value: ``|G_i|_1 |x|_∞ + |b_i|``.

    Floored at 1e-200: below it a value is zero for any physical problem,
    and subnormal numbers have lost their relative precision.
    """
    return np.abs(G).sum(axis=1) * float(np.max(np.abs(x), initial=0.0)) \
        + np.abs(b) + _FLOOR


def _kkt_solve(P, q, G, S, b, n_rows):
    """Exact minimiser of the QP with rows ``S`` held at ``b``.

    The active variable bounds fix their variables; the active general
    rows (the first ``n_rows`` of G) are met by least squares on the
    free variables, which must solve them exactly (dependent rows are
    fine, inconsistent ones are not); the cost is minimised in their
    null space. Returns ``x`` or None (no solution, or the reduced
    Hessian is not positive definite).
    """
    n = P.shape[0]
    x = np.zeros(n)
    fixed = np.zeros(n, dtype=bool)
    bound = S >= n_rows
    fixed[S[bound] - n_rows] = True
    x[S[bound] - n_rows] = b[bound]
    free = ~fixed
    rows = S[~bound]
    C = G[rows][:, free]
    r = b[~bound] - G[rows][:, fixed] @ x[fixed]
    g = q[free] + P[np.ix_(free, fixed)] @ x[fixed]
    H = P[np.ix_(free, free)]
    if C.shape[0]:
        U, sv, Vt = np.linalg.svd(C)
        rank = int((sv > 1e-12 * (sv.max(initial=0.0) + 1e-300)).sum())
        xp = Vt[:rank].T @ ((U[:, :rank].T @ r) / sv[:rank])
        x[free] = xp
        scale = _row_scale(G[rows], x, b[~bound])
        if np.max(np.abs(C @ xp - r) / scale) > 1e-10:
            return None                     # inconsistent rows
        Z = Vt[rank:].T
    else:
        xp = np.zeros(int(free.sum()))
        Z = np.eye(int(free.sum()))
    if Z.shape[1]:
        Hz = Z.T @ H @ Z
        try:
            L = np.linalg.cholesky(Hz)
        except np.linalg.LinAlgError:
            return None
        y = -np.linalg.solve(L.T, np.linalg.solve(L, Z.T @ (H @ xp + g)))
        xp = xp + Z @ y
    x[free] = xp
    return x


def _multipliers(grad, G, S, sign):
    """Multipliers λ_S with ``grad + G_Sᵀ λ_S ≈ 0`` and the right signs.

    ``sign`` is +1 (upper bound: λ >= 0), -1 (lower: λ <= 0) or 0
    (equality: free) per active row. The minimum-norm solution first;
    only when dependent rows leave it with a wrong sign, bounded least
    squares over the whole family.
    """
    GS = G[S]
    lam = np.linalg.lstsq(GS.T, -grad, rcond=1e-12)[0] if len(S) else \
        np.zeros(0)
    if np.all(lam * sign >= 0.0):
        return lam
    from scipy.optimize import lsq_linear

    lo = np.where(sign > 0, 0.0, -np.inf)
    hi = np.where(sign < 0, 0.0, np.inf)
    return lsq_linear(GS.T, -grad, bounds=(lo, hi), tol=1e-14,
                      method="bvls").x


def _measure(P, q, G, gl, gu, x, lam, eq):
    """``(primal, stationarity, dual)`` of ``(x, λ)``, all relative."""
    Gx = G @ x
    row_scale = _row_scale(G, x, np.where(np.isfinite(gl), np.abs(gl), 0)
                           + np.where(np.isfinite(gu), np.abs(gu), 0))
    with np.errstate(invalid="ignore"):
        viol = np.maximum(np.nan_to_num(gl - Gx, nan=0.0, neginf=0.0),
                          np.nan_to_num(Gx - gu, nan=0.0, neginf=0.0))
    primal = float(np.max(np.maximum(viol, 0.0) / row_scale))
    grad = P @ x + q
    terms = np.abs(P) @ np.abs(x) + np.abs(q) + np.abs(G).T @ np.abs(lam)
    stat = float(np.max(np.abs(grad + G.T @ lam))) / (
        float(np.max(terms, initial=0.0)) + _FLOOR)
    # λ > 0 only on a row at its upper bound, λ < 0 only at its lower one
    lam_scale = float(np.max(np.abs(lam), initial=0.0)) + float(
        np.max(np.abs(grad), initial=0.0)) + _FLOOR
    at_upper = np.isfinite(gu) & (np.abs(gu - Gx) <= 1e-9 * row_scale)
    at_lower = np.isfinite(gl) & (np.abs(Gx - gl) <= 1e-9 * row_scale)
    wrong = np.where(eq, 0.0, np.where(
        lam > 0, np.where(at_upper, 0.0, lam),
        np.where(at_lower, 0.0, -lam)))
    return primal, stat, float(np.max(wrong, initial=0.0)) / lam_scale


def certify(qp: QP, x: np.ndarray, tol: float = CERTIFY_TOL
            ) -> tuple[np.ndarray, Certificate]:
    """Polish ``x`` on its active set and certify the result optimal.

    Parameters
    ----------
    qp : QP
        The problem (``P`` positive semi-definite).
    x : (n,) ndarray
        A backend's point.
    tol : float
        Relative tolerance of feasibility, stationarity and multiplier
        signs.

    Returns
    -------
    x : (n,) ndarray
        The polished point when the certificate holds, else ``x``.
    Certificate
        The verdict (``certified`` False: the point is not shown optimal
        and must not be reported as a success).
    """
    x = np.asarray(x, dtype=float)
    G, gl, gu = _rows(qp)
    n_eq = qp.n_eq
    eq = np.zeros(G.shape[0], dtype=bool)
    eq[:n_eq] = True
    eq |= np.isfinite(gl) & (gl == gu)
    if x.shape != (qp.n,) or not np.all(np.isfinite(x)):
        inf = float("inf")
        return x, Certificate(False, inf, inf, inf, False, 0)
    best = None
    for active_tol in _ACTIVE_TOLS:
        xs, cert = _polish(qp, G, gl, gu, eq, x, active_tol, tol)
        if cert.certified:
            return xs, cert
        if best is None or cert.steps > best.steps:
            best = cert
    if best is None or best.steps == 0:
        inf = float("inf")
        return x, Certificate(False, inf, inf, inf, False, 0)
    return x, best


def _polish(qp, G, gl, gu, eq, x, active_tol, tol):
    """Active-set steps from the rows ``x`` has within ``active_tol``."""
    inf = float("inf")
    Gx = G @ x
    size = np.where(np.isfinite(gl), np.abs(gl), 0) + np.where(
        np.isfinite(gu), np.abs(gu), 0)
    scale = _row_scale(G, x, size)
    with np.errstate(invalid="ignore"):
        lower = ~eq & np.isfinite(gl) & (Gx - gl <= active_tol * scale)
        upper = ~eq & np.isfinite(gu) & (gu - Gx <= active_tol * scale) \
            & ~lower
    cert = Certificate(False, inf, inf, inf, False, 0)
    for step in range(_MAX_STEPS + G.shape[0]):
        S = np.flatnonzero(eq | lower | upper)
        b = np.where(upper[S], gu[S], gl[S])
        xs = _kkt_solve(qp.P, qp.q, G, S, b, qp.k)
        if xs is None:
            break
        lam = np.zeros(G.shape[0])
        lam[S] = _multipliers(qp.P @ xs + qp.q, G, S,
                              np.where(eq[S], 0, np.where(upper[S], 1, -1)))
        primal, stat, dual = _measure(qp.P, qp.q, G, gl, gu, xs, lam, eq)
        if primal <= tol and stat <= tol and dual <= tol:
            return xs, Certificate(True, primal, stat, dual, True, step + 1)
        cert = Certificate(False, primal, stat, dual, False, step + 1)
        # the wrong-signed multiplier leaves, the violated row joins
        changed = False
        lam_ref = float(np.max(np.abs(lam), initial=0.0)) + 1e-300
        bad_up = upper & (lam < -tol * lam_ref)
        bad_lo = lower & (lam > tol * lam_ref)
        if bad_up.any() or bad_lo.any():
            worst = np.argmax(np.where(bad_up, -lam, 0.0)
                              + np.where(bad_lo, lam, 0.0))
            upper[worst] = lower[worst] = False
            changed = True
        Gxs = G @ xs
        row_scale = _row_scale(G, xs, size)
        with np.errstate(invalid="ignore"):
            over = ~eq & ~upper & np.isfinite(gu) & (
                Gxs - gu > tol * row_scale)
            under = ~eq & ~lower & np.isfinite(gl) & (
                gl - Gxs > tol * row_scale)
        if not changed and (over.any() or under.any()):
            viol = np.where(over, Gxs - gu, 0.0) + np.where(
                under, gl - Gxs, 0.0)
            worst = int(np.argmax(viol / row_scale))
            upper[worst], lower[worst] = bool(over[worst]), bool(
                under[worst])
            changed = True
        if not changed:
            break
    return x, cert
