r"""The one QP form every allocator hands to a backend.

.. math::
    \min_x \tfrac12 x^T P x + q^T x \quad\text{s.t.}\quad
    l \le C x \le u,\qquad lb \le x \le ub

The first ``n_eq`` rows of ``C`` are equalities (``l == u``); an absent
bound is ``±inf``. Backends translate this form to their own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["QP", "primal_residual"]


@dataclass(frozen=True, eq=False)
class QP:
    """One dense QP in the form above.

    Attributes
    ----------
    P : (n, n) ndarray
        Hessian (symmetric, positive semi-definite).
    q : (n,) ndarray
    C : (k, n) ndarray
    l, u : (k,) ndarray
        Row bounds (``±inf`` where absent; equal on the first ``n_eq``).
    lb, ub : (n,) ndarray
        Variable bounds (``±inf`` where absent).
    n_eq : int
        Number of leading equality rows.
    """

    P: np.ndarray
    q: np.ndarray
    C: np.ndarray
    l: np.ndarray  # noqa: E741 (the usual name of the lower row bound)
    u: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    n_eq: int

    @property
    def n(self) -> int:
        """Number of variables."""
        return self.P.shape[0]

    @property
    def k(self) -> int:
        """Number of constraint rows."""
        return self.C.shape[0]


def primal_residual(qp: QP, x: np.ndarray) -> float:
    """Largest violation of any row or variable bound by ``x`` (≥ 0).

    This is what *residual* means everywhere in the toolbox: the largest
    amount by which a point breaks a constraint, in the constraint's
    units (``inf`` for a non-finite point).
    """
    x = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(x)):
        return float("inf")
    Cx = qp.C @ x
    with np.errstate(invalid="ignore"):
        parts = [qp.l - Cx, Cx - qp.u, qp.lb - x, x - qp.ub, [0.0]]
    return float(max(np.max(np.nan_to_num(p, nan=0.0, neginf=0.0))
                     for p in parts))
