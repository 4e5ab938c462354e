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
