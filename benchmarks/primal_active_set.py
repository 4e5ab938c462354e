"""A textbook primal active-set QP solver, for studies of iteration counts.

Used by `benchmarks.horizon_qps` to count what a primal method started
from the step's warm start needs. Dense numpy (a KKT solve per
iteration), so it says how many iterations, not how fast: no flight code
is built on it.
"""

from __future__ import annotations

import numpy as np


def independent(C: np.ndarray, rows: list[int], tol: float = 1e-9
                ) -> list[int]:
    """The rows of ``rows`` (in order) whose normals ``C[j]`` are linearly
    independent of those kept before them."""
    keep: list[int] = []
    Q = np.zeros((C.shape[1], 0))
    for j in rows:
        r = C[j] - Q @ (Q.T @ C[j])
        norm = np.linalg.norm(r)
        if norm > tol * max(1.0, np.linalg.norm(C[j])):
            keep.append(j)
            Q = np.column_stack([Q, r / norm])
    return keep


def solve(H: np.ndarray, g: np.ndarray, C: np.ndarray, lo: np.ndarray,
          hi: np.ndarray, x0: np.ndarray, working: dict[int, int],
          max_iter: int = 1000, tol: float = 1e-10) -> dict:
    """min ½xᵀHx + gᵀx s.t. lo ≤ Cx ≤ hi, from the feasible ``x0``.

    ``working`` maps rows active at ``x0`` to their side (−1 lower, 1
    upper); its normals must be independent (`independent`). Each
    iteration solves the KKT system of the working set; a step blocked
    by a row adds it, a zero step with a wrong-signed multiplier drops
    the most wrong one. Every iterate is feasible, so a solve stopped at
    ``max_iter`` returns a feasible point of lower cost than ``x0``.
    Returns ``x``, ``iterations``, ``optimal``, the multipliers ``lam``
    (positive at an upper bound, as DAQP's; zero unless optimal), the
    last ``working`` set and the ``path``: the point after each
    iteration (what a solve stopped there returns).
    """
    x = np.array(x0, dtype=float)
    W = dict(working)
    n = x.size
    lam = np.zeros(C.shape[0])
    norms = np.linalg.norm(C, axis=1)
    path = []
    for it in range(1, max_iter + 1):
        rows = list(W)
        Cw = C[rows]
        k = len(rows)
        K = np.block([[H, Cw.T], [Cw, np.zeros((k, k))]])
        sol = np.linalg.solve(K, np.r_[-(H @ x + g), np.zeros(k)])
        p, mult = sol[:n], sol[n:]
        if np.max(np.abs(p), initial=0.0) <= tol:
            lam = np.zeros(C.shape[0])
            lam[rows] = mult
            # wrong sign: negative at an upper bound, positive at a lower
            wrong = [-mult[i] * W[j] for i, j in enumerate(rows)]
            if not rows or max(wrong) <= tol:
                return {"x": x, "iterations": it, "optimal": True,
                        "lam": lam, "working": W, "path": path + [x]}
            del W[rows[int(np.argmax(wrong))]]
            path.append(x)
            continue
        Cp, Cx = C @ p, C @ x
        alpha, block = 1.0, None
        # rows the step moves along (relative test: a row nearly parallel
        # to the working set's would make it dependent)
        moving = np.abs(Cp) > 1e-9 * np.linalg.norm(p) * norms
        for j in np.flatnonzero(moving):
            if j in W:
                continue
            room = (hi[j] - Cx[j]) / Cp[j] if Cp[j] > 0 else \
                (lo[j] - Cx[j]) / Cp[j]
            if room < alpha:
                alpha, block = max(room, 0.0), int(j)
        x = x + alpha * p
        path.append(x)
        if block is not None:
            W[block] = 1 if Cp[block] > 0 else -1
    return {"x": x, "iterations": max_iter, "optimal": False, "lam": lam,
            "working": W, "path": path}


def phase_one(C: np.ndarray, lo: np.ndarray, hi: np.ndarray,
              y0: np.ndarray, working: dict[int, int], max_iter: int = 1000,
              tol: float = 1e-10, dep: float = 1e-6) -> dict:
    """The projection of ``y0`` onto ``lo ≤ Cy ≤ hi`` (min ½|y − y0|²),
    by the dual active set of Goldfarb & Idnani (1983) for Hessian I, as
    ``ocp/mpc/pqp/pqp.c``'s phase one takes it: from the rows of
    ``working`` (at their bound at ``y0``, independent) with multipliers
    0, the row farthest beyond its bound (distance, beyond ``tol``
    relative to 1 + |bound|) joins at its broken side while y moves
    along its part normal to the working rows; a working row whose
    multiplier would change sign leaves first (of those whose multiplier
    moves by more than 1e-9 of the largest move). Returns ``y``, the last
    ``working`` set, ``iterations`` (one per KKT solve: a row joined or
    left) and ``status``: ``"feasible"``, ``"infeasible"`` (a row
    depends on the working rows and none can leave) or ``"limit"``.
    """
    y = np.array(y0, dtype=float)
    W = dict(working)
    u = {j: 0.0 for j in W}
    norms2 = np.einsum("ij,ij->i", C, C)
    its = 0
    while True:
        Cy = C @ y
        over_hi = Cy - hi > tol * (1 + np.abs(hi))
        over_lo = lo - Cy > tol * (1 + np.abs(lo))
        over = np.where(over_hi, Cy - hi, np.where(over_lo, lo - Cy, 0.0))
        over[list(W)] = 0.0
        if not np.any(over > 0):
            return {"y": y, "working": W, "iterations": its,
                    "status": "feasible"}
        q = int(np.argmax(over / np.sqrt(np.maximum(norms2, 1e-300))))
        s = 1 if over_hi[q] else -1
        b = hi[q] if s > 0 else lo[q]
        lam = 0.0
        while True:
            if its >= max_iter:
                return {"y": y, "working": W, "iterations": its,
                        "status": "limit"}
            its += 1
            rows = list(W)
            Cw = C[rows]
            r = (np.linalg.solve(Cw @ Cw.T, Cw @ C[q]) if rows
                 else np.zeros(0))
            z = C[q] - Cw.T @ r
            d = float(z @ z)
            dependent = len(rows) == y.size or d <= dep ** 2 * norms2[q]
            block, room = None, 0.0
            moved = 1e-9 * np.max(np.abs(r), initial=0.0)
            for i, j in enumerate(rows):
                if s * r[i] * W[j] > moved:
                    t = u[j] / (s * r[i])
                    if block is None or t < room:
                        block, room = j, t
            if dependent and block is None:
                return {"y": y, "working": W, "iterations": its,
                        "status": "infeasible"}
            step = room if dependent else s * (C[q] @ y - b) / d
            if block is not None and (dependent or room < step):
                step = room
            else:
                block = None
            if not dependent:
                y = y - step * s * z
            for i, j in enumerate(rows):
                u[j] -= step * s * r[i]
            lam += step * s
            if block is None:
                W[q], u[q] = s, lam
                break
            del W[block], u[block]
